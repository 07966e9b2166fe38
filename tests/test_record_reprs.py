"""Short reprs of the public records (issue 51): at most 200 characters whatever they hold, and
the key facts named (shapes and batch, where the numbers come from), never the arrays."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.conditioning import KeypointFit
from hkpd.distributions import BodyDistribution
from hkpd.explorer.saved_scene import ScenePage
from hkpd.prediction import (
    CombinedShape,
    CropTransform,
    KeypointDetection,
    LoadedImage,
    NetworkInput,
    Occluders,
)
from hkpd.prediction.detection.person_mask import PersonMask
from hkpd.prediction.sex_latent import SexShapes

LIMIT = 200
LONG_PATH = "/data/" + "a_very_long_folder_name/" * 12 + "the_photo.jpg"


def distribution(*batch: int) -> BodyDistribution:
    """A record of batch shape ``batch`` (one example's random numbers, expanded)."""
    return BodyDistribution(
        torch.randn(23, 3, 3).expand(*batch, 23, 3, 3),
        torch.randn(10).expand(*batch, 10),
        (torch.rand(10) + 0.1).expand(*batch, 10),
        torch.eye(3).expand(*batch, 3, 3),
        torch.rand(3).expand(*batch, 3),
    )


def short(record: object) -> str:
    text = repr(record)
    assert len(text) <= LIMIT and "\n" not in text, text
    return text


@pytest.mark.parametrize("batch", [(), (4,), (1000, 1000)])
def test_body_distribution_names_its_batch_shape(batch) -> None:
    text = short(distribution(*batch))
    assert text.startswith("BodyDistribution(") and f"batch_shape={batch}" in text
    assert f"F={(*batch, 23, 3, 3)}" in text and f"shape_mean={(*batch, 10)}" in text
    assert "float32" in text and "cpu" in text
    assert "tensor(" not in text


def test_keypoint_fit_says_what_won_or_why_not() -> None:
    fitted = KeypointFit(
        conditioned=distribution(),
        reason="",
        evidence_count=15,
        start=1,
        turned=True,
        costs=torch.tensor([12.5, 3.25, 40.0]),
        row=1,
        iterations=14,
        converged=True,
        keypoint_weights=torch.ones(17),
        seconds=0.0456,
        terms=("keypoints", "silhouette"),
        shape_covariance=torch.eye(10),
    )
    text = short(fitted)
    assert text.startswith("KeypointFit(succeeded, start=1, turned")
    for fact in ("'silhouette'", "evidence_count=15", "iterations=14", "cost=3.25", "0.046"):
        assert fact in text, text
    failed = KeypointFit(None, "too few evidence keypoints: " + "x" * 500, evidence_count=2)
    text = short(failed)
    assert text.startswith("KeypointFit(failed: 'too few evidence keypoints") and "=2" in text


@pytest.mark.parametrize("count", [0, 1, 5])
def test_occluders_count_and_show_the_first_boxes(count) -> None:
    boxes = [(10.0 * i, 20.0, 10.0 * i + 5.5, 1e300) for i in range(count)]
    text = short(Occluders.of(boxes))
    assert text.startswith(f"Occluders({count} box")
    if count:
        assert "(0, 20, 5.5, 1e+300)" in text
    assert ("…" in text) == (count > 3)


def loaded_image(source: str = LONG_PATH) -> LoadedImage:
    return LoadedImage(np.zeros((720, 1080, 3), np.uint8), (4032, 2688), source)


def test_loaded_image_names_sizes_and_the_end_of_its_source() -> None:
    text = short(loaded_image())
    assert "1080x720" in text and "4032x2688" in text and "the_photo.jpg" in text
    assert "pixels" not in text and "array(" not in text
    plain = LoadedImage(np.zeros((720, 1080, 3), np.uint8), (1080, 720), "photo.png")
    assert repr(plain) == "LoadedImage(1080x720 RGB, source='photo.png')"


def detection() -> KeypointDetection:
    confidences = np.linspace(0.0, 1.0, 17)  # 7 at or above 0.6
    mask = PersonMask(np.full((256, 256), 0.9, np.float32), np.eye(2, 3), (4032, 2688))
    return KeypointDetection(
        keypoints=np.random.default_rng(0).uniform(0, 1000, (17, 2)),
        confidences=confidences,
        person_box=np.array([100.4, 200.6, 900.0, 2000.0]),
        mask_box=None,
        search_box=None,
        image_size=(4032, 2688),
        seconds=0.02,
        detector_score=0.87,
        person_mask=mask,
    )


def test_keypoint_detection_and_person_mask() -> None:
    text = short(detection())
    assert text.startswith("KeypointDetection(17 keypoints, 7 with confidence >= 0.6")
    assert "person_box=(100, 201, 900, 2000)" in text and "photo 4032x2688" in text
    assert "detector_score=0.87" in text and "person mask" in text
    text = short(detection().person_mask)
    assert text == "PersonMask(256x256 grid, 100% person (p >= 0.5), photo 4032x2688)"


def test_network_input_names_proxy_crop_evidence_and_photo() -> None:
    evidence = np.arange(17) % 2 == 0  # 9 of 17
    network_input = NetworkInput(
        proxy=torch.zeros(18, 256, 256),
        crop=CropTransform((583.7, 367.9), 457.95),
        crop_rgb=np.zeros((256, 256, 3), np.uint8),
        keypoints_crop=np.zeros((17, 2)),
        confidences=np.where(evidence, 0.9, 0.0),
        evidence=evidence,
        detection=detection(),
        image=loaded_image(),
        occluders=Occluders.of([(0, 0, 10, 10), (5, 5, 20, 20)]),
        person_mask=np.zeros((256, 256), np.float32),
    )
    text = short(network_input)
    for fact in (
        "proxy=(18, 256, 256)",
        "crop 458 px at (584, 368)",
        "evidence 9/17 keypoints",
        "2 occluders",
        "person mask",
        "photo 4032x2688",
        "the_photo.jpg",
    ):
        assert fact in text, text


def test_combined_shape_names_method_count_and_spread() -> None:
    combined = CombinedShape(
        method="product",
        count=3,
        betas_mean=torch.zeros(10),
        betas_std=torch.full((10,), 0.25),
        tpose_vertices=torch.zeros(6890, 3),
        vertex_uncertainty=torch.full((6890,), 0.0125),
        uncertainty_samples=100,
        faces=torch.zeros(13776, 3, dtype=torch.long),
    )
    text = short(combined)
    assert text.startswith("CombinedShape(method='product', count=3, betas=(10,)")
    assert "mean_std=0.250" in text and "vertices=(6890, 3)" in text and "0.0125" in text


@pytest.mark.parametrize("caption", ["Warrior lunge, 100 samples", "a long caption " * 30])
def test_scene_page_names_its_size_and_caption(caption) -> None:
    text = short(ScenePage(html="x" * 2_500_000, caption=caption))
    assert text.startswith("ScenePage(2.5 MB: ") and text.endswith(")")
    assert caption[:100] in text


def test_sex_shapes_name_the_probabilities() -> None:
    shapes = SexShapes(
        probabilities={"female": 0.623478, "male": 0.376522},
        means={"female": torch.randn(10), "male": torch.randn(10)},
        covariances={"female": torch.eye(10), "male": torch.eye(10)},
    )
    text = short(shapes)
    assert text == "SexShapes(female=0.623, male=0.377, stated=False, means (10,))"
