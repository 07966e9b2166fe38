"""Half-precision weights (issue 51): stored as float16 (the calibration in float32), loaded back
as float32 exactly, so a network computes what it computed with its weights rounded to float16;
float32 checkpoints load as they are."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch

from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import (
    CALIBRATION_KEY,
    FULL_PRECISION_KEYS,
    load_network,
    read_checkpoint,
    save_checkpoint,
)
from hkpd.training.export import export_weights

SMALL = NetworkConfig(backbone_base_width=8, image_size=32)


@pytest.fixture(scope="module")
def trained_like() -> DistributionNetwork:
    """A small network with non-trivial batch-norm statistics and a calibration on the grid of
    ``log(2) / 4`` steps, in eval mode."""
    torch.manual_seed(0)
    network = DistributionNetwork(SMALL)
    network.train()
    with torch.no_grad():
        for _ in range(3):
            network(torch.rand(8, 18, 32, 32) * 2.0)
        getattr(network, CALIBRATION_KEY).copy_(
            torch.arange(-11, 12).double().mul(math.log(2) / 4).float()[:23]
        )
    return network.eval()


@pytest.fixture(scope="module")
def proxies() -> torch.Tensor:
    return torch.rand(4, 18, 32, 32, generator=torch.Generator().manual_seed(1))


def outputs(network: torch.nn.Module, proxies: torch.Tensor) -> tuple[torch.Tensor, ...]:
    with torch.no_grad():
        return network(proxies).tensors()


def save(network: torch.nn.Module, path: Path, half: bool) -> Path:
    return save_checkpoint(path, network, SMALL.to_dict(), 10, {}, 160, half_precision=half)


def test_half_weights_are_float16_on_disk_and_float32_when_loaded(trained_like, tmp_path):
    full = save(trained_like, tmp_path / "full.pt", half=False)
    half = save(trained_like, tmp_path / "half.pt", half=True)
    stored = read_checkpoint(half)["model"]
    for key, value in stored.items():
        if value.is_floating_point():
            wanted = torch.float32 if key in FULL_PRECISION_KEYS else torch.float16
            assert value.dtype == wanted, key
    assert half.stat().st_size < 0.6 * full.stat().st_size
    network, _ = load_network(half)
    original = trained_like.state_dict()
    for key, value in network.state_dict().items():
        if value.is_floating_point():
            assert value.dtype == torch.float32, key
            rounded = original[key] if key in FULL_PRECISION_KEYS else original[key].half().float()
            assert torch.equal(value, rounded), key
        else:
            assert torch.equal(value, original[key]), key


def test_loaded_half_weights_compute_what_the_rounded_network_computes(
    trained_like, proxies, tmp_path
):
    """Bit for bit against the float32 network with its weights rounded to float16 (the
    loading adds nothing); against the unrounded network, within float16's rounding of the
    weights (relative 2^-11 each)."""
    network, _ = load_network(save(trained_like, tmp_path / "half.pt", half=True))
    rounded = DistributionNetwork(SMALL).eval()
    rounded.load_state_dict(
        {
            key: value.half().float()
            if value.is_floating_point() and key != CALIBRATION_KEY
            else value
            for key, value in trained_like.state_dict().items()
        }
    )
    for loaded, expected, unrounded in zip(
        outputs(network, proxies),
        outputs(rounded, proxies),
        outputs(trained_like, proxies),
        strict=True,
    ):
        assert torch.equal(loaded, expected)
        scale = float(unrounded.abs().max())
        assert float((loaded - unrounded).abs().max()) <= 5e-3 * scale


def test_float32_checkpoints_still_load_exactly(trained_like, proxies, tmp_path) -> None:
    network, _ = load_network(save(trained_like, tmp_path / "full.pt", half=False))
    assert all(v.dtype != torch.float16 for v in network.state_dict().values())
    for loaded, original in zip(
        outputs(network, proxies), outputs(trained_like, proxies), strict=True
    ):
        assert torch.equal(loaded, original)


def test_export_keeps_the_calibration_and_the_training_record(trained_like, tmp_path) -> None:
    source = save_checkpoint(
        tmp_path / "run.pt", trained_like, SMALL.to_dict(), 1234, {"seed": 3}, 9876,
        evidence_config={"prior_weight": 0.25},
    )  # fmt: skip
    payload = read_checkpoint(export_weights(source, tmp_path / "shipped.pt"))
    assert (payload["step"], payload["samples_seen"]) == (1234, 9876)
    assert payload["train_config"] == {"seed": 3}
    assert payload["evidence_config"] == {"prior_weight": 0.25}
    assert torch.equal(payload["model"][CALIBRATION_KEY], getattr(trained_like, CALIBRATION_KEY))


def test_the_shipped_weights_are_stored_in_float16() -> None:
    """The model card's "13.3 MB of float16 weights": the file is float16 but for the
    calibration, and about 2 bytes per parameter."""
    shipped = Path(__file__).parents[1] / "assets" / "models" / "hkpd_hierarchical.pt"
    if not shipped.is_file():
        pytest.skip("the shipped weights are not in this checkout")
    state = read_checkpoint(shipped)["model"]
    floats = {key: value for key, value in state.items() if value.is_floating_point()}
    assert {v.dtype for k, v in floats.items() if k not in FULL_PRECISION_KEYS} == {torch.float16}
    parameters = sum(value.numel() for value in floats.values())
    assert shipped.stat().st_size < 2.1 * parameters
