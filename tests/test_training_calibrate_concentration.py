"""Per-joint concentration calibration: the buffer scales F after the head, old checkpoints
load uncalibrated, fine-tunes start uncalibrated, and the fit finds a known over-confidence."""

from __future__ import annotations

import math

import pytest
import torch

from hkpd.distributions import KinematicMatrixFisher
from hkpd.kinematic_tree import BODY_PARENTS
from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import (
    CALIBRATION_KEY,
    load_initial_weights,
    load_network,
    save_checkpoint,
)
from hkpd.training.calibrate_concentration import (
    choose_scale_indices,
    coverage_by_scale,
    main,
)

TINY = {"backbone_base_width": 8, "head_hidden": 32, "joint_hidden": (16,), "image_size": 32}


def _network() -> DistributionNetwork:
    torch.manual_seed(0)
    return DistributionNetwork(NetworkConfig(**TINY)).eval()


def test_the_calibration_scales_each_joints_F_after_the_head_and_keeps_the_modes() -> None:
    network = _network()
    proxies = torch.rand(3, 18, 32, 32, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        before = network(proxies)
        scales = torch.linspace(-1.0, 1.0, 23)
        getattr(network, CALIBRATION_KEY).copy_(scales)
        after = network(proxies)
    torch.testing.assert_close(after.F, before.F * scales.exp()[:, None, None])
    torch.testing.assert_close(after.pose_distribution().mode, before.pose_distribution().mode)
    for name in ("shape_mean", "global_orient", "camera"):
        torch.testing.assert_close(getattr(after, name), getattr(before, name), rtol=0, atol=0)


def test_checkpoints_keep_the_calibration_old_ones_load_without_it(tmp_path) -> None:
    network = _network()
    with torch.no_grad():
        getattr(network, CALIBRATION_KEY).fill_(0.5)
    path = save_checkpoint(tmp_path / "cal.pt", network, network.config.to_dict(), 1, {}, 16)
    reloaded, _ = load_network(path)
    torch.testing.assert_close(getattr(reloaded, CALIBRATION_KEY), torch.full((23,), 0.5))

    # A checkpoint written before the buffer existed: no key, loads as uncalibrated.
    payload = torch.load(path, weights_only=True)
    del payload["model"][CALIBRATION_KEY]
    payload.pop("checksum")
    torch.save(payload, tmp_path / "old.pt")
    old, _ = load_network(tmp_path / "old.pt")
    assert not getattr(old, CALIBRATION_KEY).any()

    # A fine-tune trains the raw distributions: the calibration is not carried over.
    fresh = DistributionNetwork(NetworkConfig(**TINY))
    load_initial_weights(fresh, path, "cpu")
    assert not getattr(fresh, CALIBRATION_KEY).any()
    torch.testing.assert_close(fresh.head.trunk[0].weight, network.head.trunk[0].weight)


def test_the_fit_undoes_a_known_over_confidence() -> None:
    generator = torch.Generator().manual_seed(3)
    count = 400
    # True distributions with per-joint concentrations 5-200; the truth is drawn from them.
    concentration = torch.logspace(math.log10(5.0), math.log10(200.0), 23, dtype=torch.float64)
    rotations = KinematicMatrixFisher(
        torch.eye(3, dtype=torch.float64).expand(count, 23, 3, 3) * 50.0, BODY_PARENTS
    ).sample(1, generator=generator)[0]
    honest = rotations * concentration[:, None, None]
    truth = KinematicMatrixFisher(honest, BODY_PARENTS).sample(1, generator=generator)[0]
    # The "network" is 4x too sure on the first ten joints, 2x too unsure on the others.
    factor = torch.where(torch.arange(23) < 10, 4.0, 0.5).to(torch.float64)
    predicted = honest * factor[:, None, None]
    grid = torch.arange(-6, 7) * 0.5
    coverage = coverage_by_scale(predicted, truth, grid)
    assert coverage.shape == (13, 2, 23)
    at_one = coverage[6]
    assert (at_one[0, :10] < 0.3).all() and (at_one[0, 10:] > 0.6).all()
    chosen = grid[choose_scale_indices(coverage, grid)]
    assert (chosen[:10] - (-2.0)).abs().max() <= 0.5  # t near 1/4
    assert (chosen[10:] - 1.0).abs().max() <= 0.5  # t near 2
    # Coverage rises with a smaller scale (wider distributions) for every joint.
    assert (coverage[0, 0] >= coverage[-1, 0]).all()


def test_the_command_writes_a_calibrated_copy_and_never_overwrites(tmp_path, capsys) -> None:
    network = _network()
    source = save_checkpoint(tmp_path / "in.pt", network, network.config.to_dict(), 2, {}, 32)
    out = tmp_path / "out.pt"
    figure = tmp_path / "figures" / "calibration.png"
    assert main([str(source), str(out), "--examples", "6", "--figure", str(figure)]) == 0
    printed = capsys.readouterr().out
    assert figure.is_file() and figure.stat().st_size > 10_000
    assert "| left_hip |" in printed and "all joints after" in printed
    calibrated, payload = load_network(out)
    assert payload["step"] == 2
    scales = getattr(calibrated, CALIBRATION_KEY)
    assert scales.shape == (23,) and torch.isfinite(scales).all()
    proxies = torch.rand(2, 18, 32, 32)
    with torch.no_grad():
        expected = network(proxies).F * scales.exp()[:, None, None]
        torch.testing.assert_close(calibrated(proxies).F, expected)
    with pytest.raises(SystemExit):
        main([str(source), str(out)])
    assert main([str(tmp_path / "missing.pt"), str(tmp_path / "x.pt")]) == 2


def test_the_shipped_weights_are_calibrated_within_the_search_grid() -> None:
    """The evidence default (``EvidenceConfig.prior_weight``) was tuned for calibrated weights:
    shipping uncalibrated ones (all factors 1) must not pass unnoticed."""
    from pathlib import Path

    shipped = Path(__file__).resolve().parents[1] / "assets" / "models" / "hkpd_hierarchical.pt"
    network, _ = load_network(shipped)
    log_scales = getattr(network, CALIBRATION_KEY)
    assert log_scales.shape == (23,)
    assert torch.isfinite(log_scales).all()
    assert (log_scales != 0).sum() >= 10, "the shipped weights carry no concentration calibration"
    assert log_scales.abs().max() <= 5 * math.log(2) + 1e-4
