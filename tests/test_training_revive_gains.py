"""Reviving stuck concentration gains: only stuck joints change, every output stays, and the
gain learns again."""

from __future__ import annotations

import pytest
import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import load_network, save_checkpoint
from hkpd.network.output_decoding import MAX_LOG_GAIN
from hkpd.training.revive_gains import log_gains, main, revive_stuck_gains

TINY = {"backbone_base_width": 8, "head_hidden": 32, "joint_hidden": (16,), "image_size": 32}


def _network_with_stuck_joints(*joints: str) -> DistributionNetwork:
    torch.manual_seed(0)
    network = DistributionNetwork(NetworkConfig(concentration_gain=True, **TINY)).eval()
    head = network.head
    with torch.no_grad():
        for streams in head.level_streams:  # some input dependence everywhere
            streams.log_gain.weight.normal_(0.0, 0.3)
        for level, streams in zip(head.levels, head.level_streams, strict=True):
            for row, joint in enumerate(level):
                if BODY_JOINT_NAMES[joint] in joints:
                    streams.log_gain.bias[row] = -250.0
    return network


def test_only_stuck_joints_are_revived_and_every_output_stays() -> None:
    network = _network_with_stuck_joints("right_collar", "left_elbow")
    proxies = torch.rand(6, 18, 32, 32, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        before = network(proxies)
    gains_before = log_gains(network, proxies)
    ranges = revive_stuck_gains(network, proxies)
    assert {entry.joint for entry in ranges if entry.revived} == {"right_collar", "left_elbow"}
    assert len(ranges) == 23
    with torch.no_grad():
        after = network(proxies)
    torch.testing.assert_close(after.F, before.F, rtol=0, atol=0)
    gains_after = log_gains(network, proxies)
    revived = [BODY_JOINT_NAMES.index(name) for name in ("right_collar", "left_elbow")]
    assert torch.all(gains_after[:, revived] == -MAX_LOG_GAIN)
    others = [joint for joint in range(23) if joint not in revived]
    torch.testing.assert_close(gains_after[:, others], gains_before[:, others])

    # the revived gain's layer gets gradients again: a loss on F moves it
    network.train()
    network(proxies).F[:, revived].square().sum().backward()
    gain_rows = [
        streams.log_gain.weight.grad[row]
        for level, streams in zip(network.head.levels, network.head.level_streams, strict=True)
        for row, joint in enumerate(level)
        if joint in revived
    ]
    assert all(float(row.abs().sum()) > 0 for row in gain_rows)


def test_the_command_reports_writes_and_never_overwrites(tmp_path, capsys) -> None:
    network = _network_with_stuck_joints("left_hand")
    source = save_checkpoint(tmp_path / "in.pt", network, network.config.to_dict(), 3, {}, 48)
    out = tmp_path / "out.pt"
    assert main([str(source), str(out), "--examples", "4"]) == 0
    printed = capsys.readouterr().out
    assert "| left_hand |" in printed and "revived left_hand" in printed
    reloaded, payload = load_network(out)
    assert payload["step"] == 3
    proxies = torch.rand(2, 18, 32, 32)
    with torch.no_grad():
        torch.testing.assert_close(reloaded.eval()(proxies).F, network(proxies).F)
    with pytest.raises(SystemExit):
        main([str(source), str(out)])
    assert main([str(tmp_path / "missing.pt"), str(tmp_path / "x.pt")]) == 2
    healthy = save_checkpoint(
        tmp_path / "healthy.pt", _network_with_stuck_joints(), network.config.to_dict(), 0, {}, 0
    )
    assert main([str(healthy), str(tmp_path / "y.pt"), "--examples", "4"]) == 0
    assert "nothing written" in capsys.readouterr().out and not (tmp_path / "y.pt").exists()
    plain = DistributionNetwork(NetworkConfig(**TINY))
    no_gain = save_checkpoint(tmp_path / "plain.pt", plain, plain.config.to_dict(), 0, {}, 0)
    assert main([str(no_gain), str(tmp_path / "z.pt"), "--examples", "2"]) == 2
