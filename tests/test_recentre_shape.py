"""Recentring a drifted shape head: the mean offset goes, every pose output stays."""

from __future__ import annotations

import pytest
import torch

from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import load_network, save_checkpoint
from hkpd.training.recentre_shape import main, recentre_shape_mean


@pytest.mark.parametrize("pose_head", ["hierarchical", "independent"])
def test_the_offset_goes_and_the_pose_outputs_stay(pose_head) -> None:
    torch.manual_seed(0)
    config = NetworkConfig(backbone_base_width=8, image_size=32, pose_head=pose_head)
    network = DistributionNetwork(config).eval()
    drift = torch.linspace(-3.0, 7.0, config.num_betas)
    with torch.no_grad():
        network.head.globals_out.bias[: config.num_betas] += drift
    proxies = torch.rand(12, 18, 32, 32, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        before = network(proxies)
    offset = recentre_shape_mean(network, proxies)
    with torch.no_grad():
        after = network(proxies)
    assert after.shape_mean.mean(0).abs().max() < 1e-5
    torch.testing.assert_close(after.shape_mean, before.shape_mean - offset)
    torch.testing.assert_close(offset, before.shape_mean.mean(0))
    assert offset[-1] > 5.0  # the drift was found
    for name in ("F", "shape_std", "global_orient", "camera"):
        torch.testing.assert_close(getattr(after, name), getattr(before, name))


def test_the_command_writes_loadable_weights_and_never_overwrites(tmp_path, capsys) -> None:
    torch.manual_seed(0)
    config = NetworkConfig(backbone_base_width=8, image_size=32)
    source = save_checkpoint(
        tmp_path / "in.pt", DistributionNetwork(config), config.to_dict(), 5, {}, 80
    )
    out = tmp_path / "out.pt"
    assert main([str(source), str(out), "--examples", "3"]) == 0
    assert "removed the shape-mean offset" in capsys.readouterr().out
    network, payload = load_network(out)
    assert payload["step"] == 5 and network.config.image_size == 32
    with pytest.raises(SystemExit):
        main([str(source), str(out), "--examples", "3"])  # out exists: refused
    assert "exists" in capsys.readouterr().err
