"""The optional per-joint concentration gain: decoding, its zero start, and starting a run with
it from weights trained without it."""

from __future__ import annotations

import pytest
import torch

from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import load_initial_weights, load_network, save_checkpoint
from hkpd.network.output_decoding import MAX_LOG_GAIN, decode_pose

TINY = {"backbone_base_width": 8, "head_hidden": 32, "joint_hidden": (16,), "image_size": 64}


def test_gain_scales_every_singular_value_and_keeps_the_mode() -> None:
    raw = torch.randn(4, 23, 9)
    log_gain = torch.randn(4, 23, 1)
    plain = decode_pose(raw, 1.0)
    scaled = decode_pose(raw, 1.0, log_gain)
    torch.testing.assert_close(scaled, plain * log_gain.exp()[..., None])
    torch.testing.assert_close(
        torch.linalg.svdvals(scaled), torch.linalg.svdvals(plain) * log_gain.exp()
    )
    torch.testing.assert_close(decode_pose(raw, 1.0, torch.zeros(4, 23)), plain)
    huge = decode_pose(raw, 1.0, torch.full((4, 23), 100.0))
    torch.testing.assert_close(huge, plain * torch.tensor(MAX_LOG_GAIN).exp())


@pytest.mark.parametrize("head", ["independent", "hierarchical"])
def test_gain_starts_as_a_no_op_and_then_learns(head: str) -> None:
    torch.manual_seed(0)
    without = DistributionNetwork(NetworkConfig(pose_head=head, **TINY)).eval()
    gained = DistributionNetwork(NetworkConfig(pose_head=head, concentration_gain=True, **TINY))
    missing, unexpected = gained.load_state_dict(without.state_dict(), strict=False)
    assert missing and all("log_gain" in key for key in missing) and not unexpected
    gained.eval()
    proxy = torch.rand(2, 18, 64, 64)
    torch.testing.assert_close(gained(proxy).F, without(proxy).F)

    # The gain gets gradients: lowering every concentration is one step away.
    gained.train()
    optimizer = torch.optim.SGD([p for k, p in gained.named_parameters() if "log_gain" in k], 1.0)
    gained(proxy).F.square().sum().backward()
    optimizer.step()
    gained.eval()
    assert float(gained(proxy).F.norm()) < float(without(proxy).F.norm())


def test_initial_weights_without_gain_load_into_a_network_with_it(tmp_path) -> None:
    torch.manual_seed(1)
    trained = DistributionNetwork(NetworkConfig(**TINY)).eval()
    path = tmp_path / "trained.pt"
    save_checkpoint(path, trained, trained.config.to_dict(), 0, {}, 0)
    gained = DistributionNetwork(NetworkConfig(concentration_gain=True, **TINY))
    load_initial_weights(gained, path, "cpu")
    proxy = torch.rand(1, 18, 64, 64)
    torch.testing.assert_close(gained.eval()(proxy).F, trained(proxy).F)
    reloaded, _ = load_network(path)
    assert reloaded.config.concentration_gain is False

    other = DistributionNetwork(NetworkConfig(**{**TINY, "backbone_base_width": 16}))
    with pytest.raises(ValueError, match="architecture"):
        load_initial_weights(other, path, "cpu")


def test_a_gain_beyond_its_bound_gets_back_but_is_not_pushed_further_out() -> None:
    from hkpd.network.output_decoding import bounded_log_gain

    value = torch.tensor([-300.0, -300.0, 0.5, 300.0, 300.0], requires_grad=True)
    bounded = bounded_log_gain(value)
    torch.testing.assert_close(
        bounded.detach(),
        torch.tensor([-1.0, -1.0, 0.5, 1.0, 1.0])
        * torch.tensor([MAX_LOG_GAIN, MAX_LOG_GAIN, 1.0, MAX_LOG_GAIN, MAX_LOG_GAIN]),
    )
    # upstream gradients: -1 asks a descent step to raise the value, +1 to lower it
    bounded.backward(torch.tensor([-1.0, 1.0, 1.0, 1.0, -1.0]))
    # below the range only raising passes; inside everything; above only lowering
    torch.testing.assert_close(value.grad, torch.tensor([-1.0, 0.0, 1.0, 1.0, 0.0]))


def test_a_stuck_gain_learns_again_through_decode_pose() -> None:
    raw = torch.randn(2, 1, 9)
    log_gain = torch.full((2, 1, 1), -200.0, requires_grad=True)
    # a loss that wants more concentration reaches the stuck gain (a plain clamp gave 0)
    (-decode_pose(raw, 1.0, log_gain).square().sum()).backward()
    assert float(log_gain.grad.abs().min()) > 0.0
