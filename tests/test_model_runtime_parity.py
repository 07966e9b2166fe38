"""hkpd's graph-model runtime reproduces TF.js (``@tensorflow/tfjs`` 4.22.0, pure-JS CPU
backend under node) on every shipped model: each recorded output within 1e-5 (max abs).

The fixtures (tests/data/tfjs_parity/*.npz, written by tests/record_tfjs_parity.py) hold the
input image and TF.js's outputs; large outputs are stored as a sample of positions (random and
largest values) plus the whole output's mean and mean |value|. Measured when recorded (float32,
one thread): faceres 4.0e-6 (global_pooling/Mean), nanodet 6.9e-6 (Identity_4),
movenet-thunder 1.2e-6. These are float32 summation order only: TF.js's own convolutions are
1.5e-5 away from exactly rounded ones on nanodet's box logits (values up to 6.5), and torch's
native (non-oneDNN) kernels land 1.8e-5 from TF.js there, so the 1e-5 margin depends on the
kernels torch picks. With TF.js's rounding emulated (tests/tfjs_accumulation.py) every output
matches within 1e-7 on any machine: the second test, which checks every other op's semantics
to the last bits.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from hkpd.model_runtime.shipped import HUMAN_MODELS, load_human_model

sys.path.insert(0, str(Path(__file__).parent))
from tfjs_accumulation import tfjs_rounding
from tfjs_parity_inputs import model_inputs

FIXTURES = Path(__file__).parent / "data" / "tfjs_parity"
TOLERANCE = 1e-5
EMULATED_TOLERANCE = 1e-7


@pytest.fixture(scope="module", params=HUMAN_MODELS)
def recorded(request) -> tuple[str, dict[str, torch.Tensor], np.lib.npyio.NpzFile]:
    """``(model name, hkpd's outputs, the fixture)``, each model run once."""
    name = request.param
    fixture = np.load(FIXTURES / f"{name}.npz")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as recorded (the accumulation order may depend on threads)
    try:
        model = load_human_model(name)
        names = [str(output) for output in fixture["output_names"]]
        outputs = model.run(model_inputs(name, fixture["image"]), names)
    finally:
        torch.set_num_threads(threads)
    return name, outputs, fixture


def test_every_output_of_the_signature_is_recorded(recorded) -> None:
    name, _outputs, fixture = recorded
    assert sorted(str(n) for n in fixture["output_names"]) == sorted(
        load_human_model(name).output_names
    )


def _largest_difference(outputs: dict[str, torch.Tensor], fixture) -> tuple[str, float]:
    """``(output, max |hkpd - tfjs|)`` of the output that differs most (recorded elements)."""
    worst = ("", 0.0)
    for index, output in enumerate(str(n) for n in fixture["output_names"]):
        flat = outputs[output].double().numpy().reshape(-1)
        if f"out{index}_indices" in fixture:
            flat = flat[fixture[f"out{index}_indices"]]
        error = float(np.abs(flat - fixture[f"out{index}_values"].astype(np.float64)).max())
        worst = max(worst, (output, error), key=lambda pair: pair[1])
    return worst


def test_outputs_match_tfjs_within_1e_5(recorded) -> None:
    name, outputs, fixture = recorded
    output, error = _largest_difference(outputs, fixture)
    assert error <= TOLERANCE, f"{name} {output}: max |hkpd - tfjs| = {error:.3g}"
    for index, output in enumerate(str(n) for n in fixture["output_names"]):
        ours = outputs[output].double().numpy()
        assert list(ours.shape) == fixture[f"out{index}_shape"].tolist(), (name, output)
        assert abs(ours.mean() - fixture[f"out{index}_mean"]) <= TOLERANCE, (name, output)
        assert abs(np.abs(ours).mean() - fixture[f"out{index}_mean_abs"]) <= TOLERANCE


def test_the_fixtures_are_not_degenerate(recorded) -> None:
    """The recorded inputs make the models say something (not all zeros or constant)."""
    name, _outputs, fixture = recorded
    for index in range(len(fixture["output_names"])):
        values = fixture[f"out{index}_values"]
        assert np.isfinite(values).all() and values.std() > 1e-3, (name, index)


def test_faceres_batches_and_reads_the_shipped_photos_face_as_male() -> None:
    """faceres runs a batch of two (the face and its mirror image) in one call; both read male
    (the man of assets/photos/warrior_lunge.jpg), and mirroring changes little."""
    fixture = np.load(FIXTURES / "faceres.npz")
    outputs = load_human_model("faceres").run(model_inputs("faceres", fixture["image"]))
    p_male = outputs["gender_pred/Sigmoid"][:, 0]
    assert p_male.shape == (2,)
    assert (p_male > 0.8).all(), p_male
    assert abs(float(p_male[0] - p_male[1])) < 0.1


@pytest.mark.slow
@pytest.mark.parametrize("name", HUMAN_MODELS)
def test_with_tfjs_rounding_every_output_matches_to_the_last_bits(name) -> None:
    """With TF.js's float32 summation order and LeakyRelu rounding (tests/tfjs_accumulation.py;
    ~10 s a model), every other op's arithmetic is TF.js's: measured faceres 1.1e-8,
    nanodet 3.0e-8, movenet-thunder 6.0e-8 (a last bit of a sigmoid or softmax)."""
    fixture = np.load(FIXTURES / f"{name}.npz")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with pytest.MonkeyPatch.context() as patch:
            tfjs_rounding(patch)
            model = load_human_model(name)
            names = [str(output) for output in fixture["output_names"]]
            outputs = model.run(model_inputs(name, fixture["image"]), names)
    finally:
        torch.set_num_threads(threads)
    output, error = _largest_difference(outputs, fixture)
    assert error <= EMULATED_TOLERANCE, f"{name} {output}: max |hkpd - tfjs| = {error:.3g}"
