"""Averaging checkpoints of one run: exact means, one architecture, nothing overwritten."""

from __future__ import annotations

import pytest
import torch

from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import load_network, save_checkpoint
from hkpd.training.average_weights import average_checkpoints, average_state_dicts, main

SMALL = NetworkConfig(backbone_base_width=8, image_size=32)


def _checkpoint(path, seed: int, step: int, config: NetworkConfig = SMALL):
    torch.manual_seed(seed)
    network = DistributionNetwork(config)
    return save_checkpoint(path, network, config.to_dict(), step, {"seed": seed}, 16 * step)


def test_float_tensors_are_averaged_and_counters_come_from_the_last() -> None:
    first = {"w": torch.tensor([1.0, 2.0]), "count": torch.tensor(3)}
    second = {"w": torch.tensor([3.0, 6.0]), "count": torch.tensor(7)}
    averaged = average_state_dicts([first, second])
    torch.testing.assert_close(averaged["w"], torch.tensor([2.0, 4.0]))
    assert averaged["count"].item() == 7
    with pytest.raises(ValueError, match="shapes"):
        average_state_dicts([first, {"w": torch.zeros(3), "count": torch.tensor(1)}])
    with pytest.raises(ValueError, match="other tensors"):
        average_state_dicts([first, {"w": torch.zeros(2)}])
    with pytest.raises(ValueError, match="at least one"):
        average_state_dicts([])


def test_the_average_of_three_checkpoints_is_their_mean(tmp_path) -> None:
    paths = [_checkpoint(tmp_path / f"s{i}.pt", seed=i, step=100 * (i + 1)) for i in range(3)]
    out = average_checkpoints(paths, tmp_path / "mean.pt")
    averaged, payload = load_network(out)
    assert payload["step"] == 300 and payload["samples_seen"] == 4800
    assert "optimizer" not in payload
    states = [load_network(path)[0].state_dict() for path in paths]
    for key, value in averaged.state_dict().items():
        if value.is_floating_point():
            expected = (states[0][key] + states[1][key] + states[2][key]) / 3
            torch.testing.assert_close(value, expected)
    proxies = torch.rand(2, 18, 32, 32)
    with torch.no_grad():
        assert torch.isfinite(averaged(proxies).F).all()


def test_other_architectures_and_overwrites_are_refused(tmp_path, capsys) -> None:
    first = _checkpoint(tmp_path / "a.pt", seed=0, step=1)
    wider = _checkpoint(
        tmp_path / "b.pt", 1, 2, NetworkConfig(backbone_base_width=16, image_size=32)
    )
    with pytest.raises(ValueError, match="only checkpoints of one run"):
        average_checkpoints([first, wider], tmp_path / "mean.pt")
    with pytest.raises(ValueError, match="one of the inputs"):
        average_checkpoints([first, first], first)
    assert main([str(first), str(first), "--out", str(tmp_path / "same.pt")]) == 0
    assert "mean of 2 checkpoints" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main([str(first), "--out", str(tmp_path / "same.pt")])
    assert "exists" in capsys.readouterr().err
    assert main([str(tmp_path / "missing.pt"), "--out", str(tmp_path / "x.pt")]) == 2
    assert not (tmp_path / "x.pt").exists()
