"""Hostile checkpoints are refused on load, quickly and in one line naming the file: a
network_config out of the documented limits or not matching the stored tensors (checked before
any network is built), and non-finite or absurdly large weights (with a valid checksum)."""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from hkpd.evaluation.cli import main as eval_main
from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import (
    MAX_WEIGHT_MAGNITUDE,
    CheckpointError,
    load_network,
    model_checksum,
    read_checkpoint,
    save_checkpoint,
)
from hkpd.network.config import NetworkConfig
from hkpd.prediction import cli as predict_cli
from hkpd.prediction.predictor import Predictor

HOSTILE_CONFIGS = [
    ({"backbone_base_width": 8192}, "backbone_base_width"),
    ({"backbone_blocks": [2000000]}, "backbone_blocks"),
    ({"image_size": 60000}, "image_size"),
    ({"head_hidden": 10**9}, "head_hidden"),
    ({"joint_hidden": [256] * 10_000}, "joint_hidden"),
    ({"num_betas": 10**7}, "num_betas"),
    ({"backbone_blocks": [2] * 40}, "backbone_blocks"),
    ({"backbone_base_width": "64"}, "backbone_base_width"),
    ({"backbone_base_width": 4.5}, "backbone_base_width"),
    ({"backbone_base_width": True}, "backbone_base_width"),
    ({"backbone_blocks": "2222"}, "backbone_blocks"),
    ({"backbone_blocks": None}, "backbone_blocks"),
    ({"initial_shape_std": math.nan}, "initial_shape_std"),
    ({"concentration_gain": "yes"}, "concentration_gain"),
]


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory) -> Path:
    config = NetworkConfig(backbone_base_width=4, image_size=32)
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("model") / "tiny.pt"
    return save_checkpoint(path, DistributionNetwork(config), config.to_dict(), 0, {}, 0)


@pytest.fixture
def no_network_is_built(monkeypatch) -> None:
    """Any DistributionNetwork construction fails the test (and so never allocates)."""

    def refuse(self, config=None) -> None:
        raise AssertionError(f"a network was built from {config}")

    monkeypatch.setattr(DistributionNetwork, "__init__", refuse)


def _rewritten(source: Path, target: Path, config=None, weights=None) -> Path:
    """``source`` with its config entries and/or weights replaced, with a valid checksum."""
    payload = torch.load(source, weights_only=True)
    payload["network_config"].update(config or {})
    if weights is not None:
        weights(payload["model"])
        payload["checksum"] = model_checksum(payload["model"])
    torch.save(payload, target)
    return target


def _assert_one_line(error: BaseException, path: Path, *words: str) -> None:
    message = str(error)
    assert "\n" not in message and str(path) in message, message
    for word in words:
        assert word in message, message


@pytest.mark.parametrize(("entries", "field"), HOSTILE_CONFIGS)
def test_a_hostile_config_is_refused_before_any_network_is_built(
    tmp_path, tiny_checkpoint, no_network_is_built, entries, field
) -> None:
    hostile = _rewritten(tiny_checkpoint, tmp_path / "hostile.pt", entries)
    start = time.perf_counter()
    with pytest.raises(CheckpointError) as caught:
        load_network(hostile)
    assert time.perf_counter() - start < 1.0
    _assert_one_line(caught.value, hostile, field)
    with pytest.raises(CheckpointError, match=field):
        read_checkpoint(hostile)


@pytest.mark.parametrize(
    ("entries", "words"),
    [
        ({"backbone_base_width": 8}, ["backbone.stem.0.weight", "(8, 18, 7, 7)", "(4, 18, 7, 7)"]),
        ({"backbone_blocks": [3, 2, 2, 2]}, ["backbone_blocks", "[2, 2, 2, 2]"]),
        ({"backbone_blocks": [2, 2, 2]}, ["backbone_blocks", "[2, 2, 2, 2]"]),
        ({"head_hidden": 64}, ["does not match", "head."]),
        ({"num_betas": 16}, ["does not match"]),
        ({"pose_head": "independent"}, ["does not match"]),
    ],
)
def test_a_config_that_does_not_fit_the_stored_tensors_is_refused(
    tmp_path, tiny_checkpoint, entries, words
) -> None:
    built = []
    original = DistributionNetwork.__init__

    def watch(self, config=None) -> None:
        original(self, config)
        built.append(next(iter(self.state_dict().values())).device.type)

    DistributionNetwork.__init__ = watch
    try:
        mismatched = _rewritten(tiny_checkpoint, tmp_path / "mismatch.pt", entries)
        with pytest.raises(CheckpointError) as caught:
            load_network(mismatched)
    finally:
        DistributionNetwork.__init__ = original
    _assert_one_line(caught.value, mismatched, *words)
    assert all(device == "meta" for device in built), built  # nothing real was allocated


def _poison(name: str, value: float):
    def edit(state: dict[str, torch.Tensor]) -> None:
        state[name] = state[name].contiguous().clone()
        state[name].view(-1)[3] = value

    return edit


def _scale_all(factor: float):
    def edit(state: dict[str, torch.Tensor]) -> None:
        for key, tensor in state.items():
            if tensor.is_floating_point():
                state[key] = tensor * factor

    return edit


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (_poison("head.first_layer.weight", math.nan), ["head.first_layer.weight", "NaN"]),
        (_poison("backbone.stem.0.weight", math.inf), ["backbone.stem.0.weight", "inf"]),
        (_poison("backbone.stem.1.running_var", -math.inf), ["running_var", "inf"]),
        (_scale_all(1e4), ["larger than"]),
        (_poison("head.first_layer.bias", 2 * MAX_WEIGHT_MAGNITUDE), ["head.first_layer.bias"]),
    ],
)
def test_non_finite_or_diverged_weights_are_refused_on_load(
    tmp_path, tiny_checkpoint, edit, words
) -> None:
    assert "head.first_layer.weight" in read_checkpoint(tiny_checkpoint)["model"]
    broken = _rewritten(tiny_checkpoint, tmp_path / "diverged.pt", weights=edit)
    with pytest.raises(CheckpointError) as caught:
        read_checkpoint(broken)
    _assert_one_line(caught.value, broken, *words)


def test_ordinary_weights_and_large_step_counters_still_load(tmp_path, tiny_checkpoint) -> None:
    def big_counters(state: dict[str, torch.Tensor]) -> None:
        for key in state:
            if key.endswith("num_batches_tracked"):
                state[key] = torch.tensor(10**12)

    fine = _rewritten(tiny_checkpoint, tmp_path / "fine.pt", weights=big_counters)
    network, _ = load_network(fine)
    assert network.config == NetworkConfig(backbone_base_width=4, image_size=32)


def test_the_shipped_weights_are_far_inside_the_magnitude_bound() -> None:
    shipped = Path(__file__).parents[1] / "assets" / "models" / "hkpd_hierarchical.pt"
    if not shipped.is_file():
        pytest.skip("the shipped weights are not in this checkout")
    state = read_checkpoint(shipped)["model"]
    largest = max(float(v.float().abs().max()) for v in state.values() if v.is_floating_point())
    assert largest * 100 < MAX_WEIGHT_MAGNITUDE


@pytest.fixture
def hostile(tmp_path, tiny_checkpoint) -> Path:
    return _rewritten(tiny_checkpoint, tmp_path / "hostile.pt", {"backbone_base_width": 8192})


def test_the_api_gets_the_one_line(hostile, no_network_is_built) -> None:
    with pytest.raises(CheckpointError) as caught:
        Predictor.from_pretrained(hostile, device="cpu")
    _assert_one_line(caught.value, hostile, "backbone_base_width", "8192")


def test_hkpd_predict_prints_one_line_and_exits_2(
    tmp_path, capsys, hostile, no_network_is_built
) -> None:
    photo = tmp_path / "photo.png"
    Image.fromarray(np.zeros((64, 64, 3), np.uint8)).save(photo)
    code = predict_cli.main([str(photo), "--out", str(tmp_path / "out"), "--model", str(hostile)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    (line,) = [line for line in err.splitlines() if line.strip()]
    assert "cannot load the model" in line and str(hostile) in line and "8192" in line


def test_hkpd_eval_prints_one_line_and_exits_2(capsys, hostile, no_network_is_built) -> None:
    assert eval_main([str(hostile), "--count", "2"]) == 2
    err = capsys.readouterr().err
    (line,) = [line for line in err.splitlines() if line.strip()]
    assert line.startswith("hkpd-eval: error:") and str(hostile) in line and "8192" in line


def test_the_explorer_exits_with_one_line(hostile, no_network_is_built) -> None:
    explorer_cli = pytest.importorskip("hkpd.explorer.cli")
    arguments = argparse.Namespace(provider=None, model=str(hostile), device="cpu")
    with pytest.raises(SystemExit) as caught:
        explorer_cli._build_provider(arguments)
    message = str(caught.value.code)
    assert "\n" not in message and str(hostile) in message and "backbone_base_width" in message
