"""hkpd-eval --shape: the shape metrics, the detector-like mask noise, the silhouette IoU and
shape.json on a tiny run."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from hkpd.body import BodyModel
from hkpd.body.measurements import MEASUREMENT_NAMES
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.cli import main as eval_main
from hkpd.evaluation.coco_silhouettes import (
    PersonSilhouettes,
    coco_record,
    crop_mask_in_photo,
    mask_iou,
    mode_silhouette,
    with_average_shape,
)
from hkpd.evaluation.shape_eval import MaskedExample, evaluate_shape_batches, rendered_test_set
from hkpd.evaluation.shape_metrics import body_height, r_squared, shape_scores, z_squared
from hkpd.evaluation.test_set import network_and_generator
from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import save_checkpoint
from hkpd.network.config import NetworkConfig
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.posterior import BodyPosterior
from hkpd.synthesis.mask_noise import NO_MASK_NOISE, MaskNoise, detector_like_masks

SHAPE_KEYS = {"r2", "pve_t_mm", "pve_t_sc_mm", "mean_body_pve_t_sc_mm", "height_error_mm", "z2"}


# --- the metrics -------------------------------------------------------------------------------


def test_r_squared_is_one_when_exact_zero_for_a_constant_and_matches_its_formula() -> None:
    generator = torch.Generator().manual_seed(0)
    true = torch.randn(400, 3, generator=generator, dtype=torch.float64)
    assert torch.allclose(r_squared(true.clone(), true), torch.ones(3, dtype=torch.float64))
    constant = torch.full_like(true, 0.7)
    assert torch.allclose(r_squared(constant, true), torch.zeros(3, dtype=torch.float64))
    # Half the truth plus independent noise of variance v: R² = 1 - (0.25 + v) / 1 in the limit.
    noise = torch.randn(400, 3, generator=generator, dtype=torch.float64) * 0.5
    predicted = 0.5 * true + noise
    expected = 1 - (predicted - true).var(0, unbiased=False) / true.var(0, unbiased=False)
    assert torch.allclose(r_squared(predicted, true), expected)
    assert (r_squared(predicted, true) - 0.5).abs().max() < 0.15
    with pytest.raises(ValueError, match="at least 2"):
        r_squared(true[:1], true[:1])


def test_z_squared_is_the_error_in_units_of_the_std() -> None:
    true = torch.zeros(5, 2, dtype=torch.float64)
    std = torch.tensor([[0.5, 2.0]], dtype=torch.float64).expand(5, 2)
    mean = torch.tensor([[1.0, 1.0]], dtype=torch.float64).expand(5, 2)
    assert torch.allclose(
        z_squared(mean, std, true), torch.tensor([4.0, 0.25], dtype=torch.float64)
    )


def test_shape_scores_of_the_truth_are_zero_and_the_mean_body_is_not() -> None:
    body = BodyModel().double()
    true = torch.randn(6, 10, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    scores = shape_scores(body, true.clone(), torch.ones_like(true), true)
    assert scores.r2 == pytest.approx([1.0] * 10)
    assert scores.pve_t_mm == pytest.approx(0.0, abs=1e-9)
    assert scores.pve_t_sc_mm == pytest.approx(0.0, abs=1e-6)
    assert scores.height_error_mm == pytest.approx(0.0, abs=1e-9)
    assert scores.mean_body_pve_t_sc_mm > 3.0
    average = shape_scores(body, torch.zeros_like(true), torch.ones_like(true), true)
    assert average.pve_t_sc_mm == pytest.approx(scores.mean_body_pve_t_sc_mm)
    assert average.height_error_mm == pytest.approx(scores.mean_body_height_error_mm)
    assert scores.mean_body_height_error_mm > 10.0
    # β₀ is mostly height: +1 in β₀ changes the T-pose's height by several centimetres.
    taller = body_height(body.tpose(torch.eye(10, dtype=torch.float64)[:1]))
    assert abs(float(taller - body_height(body.tpose(torch.zeros(1, 10).double())))) > 0.03


# --- the mask noise ----------------------------------------------------------------------------


def _disc(size: int = 128, radius: float = 30.0) -> torch.Tensor:
    rows = torch.arange(size, dtype=torch.float32)
    inside = (rows[:, None] - size / 2) ** 2 + (rows[None] - size / 2) ** 2 <= radius**2
    return inside[None]


def _quiet(**changes: float) -> MaskNoise:
    values = {
        "dilation_px": 0.0, "dilation_jitter_px": 0.0, "boundary_noise_px": 0.0,
        "thin_part_miss_rate": 0.0, "blob_rate": 0.0, "edge_softness_px": 0.0,
    } | changes  # fmt: skip
    return MaskNoise(**values)


def _area(probability: torch.Tensor) -> float:
    return float((probability >= 0.5).sum())


def test_exact_noise_keeps_the_silhouette_and_dilation_grows_it_by_the_offset() -> None:
    disc, everywhere = _disc(), torch.ones(1, 128, 128, dtype=torch.bool)
    generator = torch.Generator().manual_seed(0)
    exact = detector_like_masks(disc, everywhere, NO_MASK_NOISE, generator)
    assert mask_iou(exact[0].numpy() >= 0.5, disc[0].numpy()) > 0.98
    # 4 px at a 256 crop is 2 px at 128: the radius grows from 30 to about 32.
    grown = detector_like_masks(disc, everywhere, _quiet(dilation_px=4.0), generator)
    assert _area(grown) == pytest.approx(math.pi * 32.0**2, rel=0.04)
    shrunk = detector_like_masks(disc, everywhere, _quiet(dilation_px=-4.0), generator)
    assert _area(shrunk) == pytest.approx(math.pi * 28.0**2, rel=0.04)


def test_unknown_pixels_are_left_as_they_were() -> None:
    disc = _disc()
    known = torch.ones_like(disc)
    known[:, 40:90, 40:70] = False  # an occluder box over half the disc
    noise = MaskNoise(dilation_px=6.0, boundary_noise_px=3.0, blob_rate=3.0)
    probability = detector_like_masks(disc, known, noise, torch.Generator().manual_seed(3))
    box = ~known
    assert torch.equal(probability[box], disc[box].float())
    assert not torch.equal(probability[known] >= 0.5, disc[known])  # outside it, noise acts


def test_thin_parts_go_missing_blobs_appear_and_edges_are_soft() -> None:
    shape = _disc(radius=20.0).clone()
    shape[0, 10:118, 100:102] = True  # a 2-pixel-wide stick (a finger, a thin strap)
    everywhere = torch.ones_like(shape)
    generator = torch.Generator().manual_seed(0)
    opened = detector_like_masks(
        shape, everywhere, _quiet(thin_part_miss_rate=1.0, boundary_sigma_px=1.0), generator
    )
    assert float(opened[0, 10:118, 100:102].max()) == 0.0 and _area(opened) > 0.9 * math.pi * 400
    blobs = detector_like_masks(shape, everywhere, _quiet(blob_rate=20.0), generator)
    assert _area(blobs) > _area(shape.float()) + 100
    soft = detector_like_masks(shape, everywhere, _quiet(edge_softness_px=2.0), generator)
    assert bool(((soft > 0.05) & (soft < 0.95)).any()) and float(soft.min()) >= 0.0
    with pytest.raises(ValueError, match="blob_radius_px"):
        MaskNoise(blob_radius_px=(5.0, 1.0))


def test_mask_noise_is_reproducible_with_its_seed() -> None:
    disc, everywhere = _disc(), torch.ones(1, 128, 128, dtype=torch.bool)
    first = detector_like_masks(disc, everywhere, MaskNoise(), torch.Generator().manual_seed(5))
    again = detector_like_masks(disc, everywhere, MaskNoise(), torch.Generator().manual_seed(5))
    other = detector_like_masks(disc, everywhere, MaskNoise(), torch.Generator().manual_seed(6))
    assert torch.equal(first, again) and not torch.equal(first, other)


# --- silhouette IoU on photos ------------------------------------------------------------------


def test_iou_of_rectangles_and_the_crop_mapped_into_the_photo() -> None:
    first, second = np.zeros((20, 30), bool), np.zeros((20, 30), bool)
    first[0:10, 0:10], second[0:10, 5:15] = True, True
    assert mask_iou(first, second) == pytest.approx(50 / 150)
    assert math.isnan(mask_iou(np.zeros((2, 2), bool), np.zeros((2, 2), bool)))
    # A 64-px crop of the photo box x 100..164, y 20..84 at half resolution (32 px).
    crop = CropTransform(centre=(132.0, 52.0), side=64.0, size=32)
    square = np.zeros((32, 32), bool)
    square[8:24, 4:12] = True  # crop pixels -> photo x 108..124, y 36..68
    photo = crop_mask_in_photo(square, crop, (200, 100))
    expected = np.zeros((100, 200), bool)
    expected[36:68, 108:124] = True
    assert photo.shape == (100, 200) and mask_iou(photo, expected) > 0.9


def _standing_posterior(crop: CropTransform) -> BodyPosterior:
    body = BodyModel()
    distribution = BodyDistribution(
        F=torch.eye(3).expand(23, 3, 3) * 50.0,
        shape_mean=torch.tensor([2.0] + [0.0] * 9),
        shape_std=torch.ones(10),
        global_orient=torch.diag(torch.tensor([1.0, -1.0, -1.0])),  # upright, facing the camera
        camera=torch.tensor([0.7, 0.1, 0.05]),
    )
    return BodyPosterior(distribution, crop, torch.zeros(17, 2), torch.ones(17), body)


def test_the_mode_silhouette_lies_where_its_vertices_project() -> None:
    crop = CropTransform(centre=(128.0, 128.0), side=256.0, size=128)
    posterior = _standing_posterior(crop)
    silhouette = mode_silhouette(posterior)
    assert silhouette.shape == (128, 128)
    vertices = posterior.mode().vertices
    pixels = ndc_to_pixels(weak_perspective_project(vertices, posterior.camera[None]), 128)[0]
    rows = np.nonzero(silhouette.any(1))[0]
    assert rows.min() == pytest.approx(float(pixels[:, 1].min()), abs=1.5)
    assert rows.max() == pytest.approx(float(pixels[:, 1].max()), abs=1.5)
    columns = np.nonzero(silhouette.any(0))[0]
    assert columns.min() == pytest.approx(float(pixels[:, 0].min()), abs=1.5)
    assert columns.max() == pytest.approx(float(pixels[:, 0].max()), abs=1.5)
    # The average shape (β₀ = 0 instead of 2: shorter) covers fewer pixels, same camera.
    average = with_average_shape(posterior)
    assert (
        torch.equal(average.camera, posterior.camera) and float(average.shape_mean.abs().sum()) == 0
    )
    assert mode_silhouette(average).sum() < silhouette.sum()
    # Mapped into the 256-px photo, the silhouette matches itself upsampled.
    photo = crop_mask_in_photo(silhouette, crop, (256, 256))
    upsampled = np.kron(silhouette, np.ones((2, 2), bool))
    assert mask_iou(photo, upsampled) > 0.95


def test_coco_record_summarises_per_split_and_all() -> None:
    network = [PersonSilhouettes("val2017", 0.6, 0.5, None),
               PersonSilhouettes("train2017", 0.8, 0.7, None)]  # fmt: skip
    record = coco_record({"network": network})
    assert set(record) == {"val2017", "train2017", "all"}
    assert record["all"]["network"]["mode_iou"] == pytest.approx(0.7)
    assert record["val2017"]["network"] == {"mode_iou": 0.6, "average_shape_iou": 0.5, "people": 1}
    assert record["all"]["detector_iou"] is None
    with_detector = coco_record({"network": [PersonSilhouettes("val2017", 0.6, 0.5, 0.9)]})
    assert with_detector["val2017"]["detector_iou"] == pytest.approx(0.9)


# --- hkpd-eval --shape -------------------------------------------------------------------------


def _tiny_checkpoint(folder):
    """An untrained 64-px network's checkpoint in ``folder``."""
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    torch.manual_seed(0)
    return save_checkpoint(
        folder / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )


def test_eval_shape_writes_shape_json_beside_the_report(tmp_path, capsys) -> None:
    checkpoint = _tiny_checkpoint(tmp_path)
    report = tmp_path / "report.md"
    arguments = [str(checkpoint), "--count", "4", "--samples", "2", "--out", str(report)]
    assert eval_main([*arguments, "--shape", "--evidence"]) == 0
    record = json.loads((tmp_path / "shape.json").read_text())
    assert {"network", "evidence", "settings"} <= set(record) and "coco" not in record
    for name in ("network", "evidence"):
        assert set(record[name]) >= SHAPE_KEYS
        assert len(record[name]["r2"]) == 10 and len(record[name]["z2"]) == 10
        assert record[name]["examples"] == 4
        assert all(value > 0 for value in record[name]["z2"])
        assert record[name]["mean_body_pve_t_sc_mm"] > 0
    assert record["settings"]["mask_noise"]["dilation_px"] == MaskNoise().dilation_px
    # Issue 49: the sex-labelled bodies' automatic sex, measurements and stated values.
    assert 0.0 <= record["sex"]["accuracy"] <= 1.0 and 0.0 <= record["sex"]["ece"] <= 0.5
    assert record["sex"]["examples"] == 4
    assert set(record["measurements"]) == set(MEASUREMENT_NAMES)
    assert all(set(v) == {"mae", "z2"} and v["z2"] > 0 for v in record["measurements"].values())
    stated = record["stated"]
    assert stated["sex"]["pve_t_sc_mm"] > 0 and stated["sex+height+mass"]["pve_t_sc_mm"] > 0
    assert stated["sex+height+mass"]["height_error_mm"] < 15  # the stated height is honoured
    text = report.read_text()
    assert "Shape read on the synthetic test set" in text and "mean R² β₁…β₉" in text
    assert "Sex, measurements and stated values" in text
    assert eval_main([*arguments[:-2], "--shape"]) == 2
    assert "give --out" in capsys.readouterr().err
    assert eval_main([str(checkpoint), str(checkpoint), "--shape", "--out", str(report)]) == 2


class _ShapePull:
    """A toy evidence term: "shape coefficient 1 is 3 ± 0.05" (an over-sure silhouette)."""

    name = "shape_pull"
    residual_shape = (1, 1)
    robust_scale = None
    needs_vertices = False
    surface_vertices = None

    def residuals(self, posed):
        return ((posed.betas[..., 1] - 3.0) / 0.05)[..., None, None]


def test_extra_terms_for_gets_each_examples_mask_and_its_terms_reach_the_fit(tmp_path) -> None:
    checkpoint = _tiny_checkpoint(tmp_path)
    network, generator = network_and_generator(checkpoint, None, "cpu")
    seen: list[MaskedExample] = []

    def pull(example: MaskedExample) -> list:
        seen.append(example)
        return [_ShapePull()]

    batches = list(rendered_test_set(generator, 4))
    plain = evaluate_shape_batches(network.eval(), batches, generator.body, evidence=True)
    pulled = evaluate_shape_batches(
        network.eval(), batches, generator.body, evidence=True, extra_terms_for=pull
    )
    assert len(seen) == 4 and all(e.probability.shape == (64, 64) for e in seen)
    assert all(e.known.dtype == torch.bool and e.crop_size == 64 for e in seen)
    assert all(
        float(e.probability.min()) >= 0.0 and float(e.probability.max()) <= 1.0 for e in seen
    )
    assert all(bool(e.silhouette.any()) for e in seen)  # the body is in every crop
    # The network's posterior does not see the terms; the evidence posterior is pulled to 3.
    assert pulled["network"].z2 == plain["network"].z2
    assert pulled["evidence"].z2[1] > 10 * plain["evidence"].z2[1]
    assert pulled["evidence"].z2[0] == pytest.approx(plain["evidence"].z2[0], rel=0.5)


def test_eval_shape_scores_the_mask_as_evidence_when_asked(tmp_path) -> None:
    checkpoint = _tiny_checkpoint(tmp_path)
    report = tmp_path / "report.md"
    arguments = [str(checkpoint), "--count", "3", "--samples", "2", "--out", str(report)]
    assert eval_main([*arguments, "--shape", "--evidence", "--silhouette-evidence"]) == 0
    record = json.loads((tmp_path / "shape.json").read_text())
    assert set(record["evidence_silhouette"]) >= SHAPE_KEYS
    assert record["evidence_silhouette"]["examples"] == 3
    # the mask moved the fit: not the keypoint-only evidence posterior's numbers
    assert record["evidence_silhouette"]["pve_t_sc_mm"] != record["evidence"]["pve_t_sc_mm"]
    assert "evidence_silhouette" in report.read_text()
