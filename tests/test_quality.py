"""The reading quality record (``hkpd.prediction.quality``) and its metrics."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.coco_keypoints import COCO17_NAMES
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.quality_metrics import (
    auroc,
    off_share_above,
    quality_summary,
    quality_table,
    reliability_rows,
)
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.quality import (
    FLAG_MEANINGS,
    QUALITY_MEAN,
    QUALITY_WEIGHTS,
    SCORE_SIGNALS,
    SIGNAL_DIRECTIONS,
    SIGNAL_NAMES,
    WARNING_FLAGS,
    ReadingQuality,
    facing_ambiguous,
    quality_score,
)

PHOTO = (1000, 1000)


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


def reading(
    body: BodyModel,
    side: float = 480.0,
    confidences: np.ndarray | None = None,
    box: tuple[float, float, float, float] | None = None,
    shift: tuple[float, float] = (0.0, 0.0),
    search_box: tuple[float, float, float, float] | None = None,
    landmark_spread: float | None = 0.01,
) -> BodyPosterior:
    """A network posterior of a standing body in a ``side``-pixel crop at the photo's centre,
    its keypoints where the mode reprojects (moved by ``shift`` pixels), as a photo's reading
    would carry them (a stand-in detection: confidences, the photo's size, the person's box,
    the box searched and the landmark spread)."""
    F = 40.0 * torch.eye(3).expand(23, 3, 3).clone()
    distribution = BodyDistribution(
        F, torch.zeros(10), torch.full((10,), 0.3), FRONTAL_GLOBAL_ORIENT.clone(),
        torch.tensor([0.9, 0.0, 0.0]),
    )  # fmt: skip
    crop = CropTransform((500.0, 500.0), side, 256)
    confidences = np.full(17, 0.95) if confidences is None else np.asarray(confidences, float)
    posterior = BodyPosterior(distribution, crop, torch.zeros(17, 2), torch.ones(17), body)
    keypoints = posterior.mode().keypoints2d[0] + torch.tensor(shift, dtype=torch.float32)
    points = keypoints.double().numpy()
    if box is None:
        box = (*points.min(0), *points.max(0))
    detection = SimpleNamespace(
        confidences=confidences,
        image_size=PHOTO,
        person_box=np.asarray(box, np.float64),
        search_box=None if search_box is None else np.asarray(search_box, np.float64),
        landmark_spread=landmark_spread,
    )
    prepared = SimpleNamespace(detection=detection, person_mask=None, person_mask_known=None)
    return replace(
        posterior,
        keypoints=keypoints,
        confidences=torch.as_tensor(confidences, dtype=torch.float32),
        network_input=prepared,
    )


def test_a_clear_large_person_has_no_flags_and_a_score_in_the_unit_interval(body) -> None:
    quality = reading(body).quality
    assert isinstance(quality, ReadingQuality)
    assert 0.0 <= quality.score <= 1.0
    assert quality.flags == ()
    assert set(quality.signals) == set(SIGNAL_NAMES)
    assert quality.signals["misfit"] < 1e-3  # the keypoints are where the mode reprojects
    assert quality.as_dict() == {"score": round(quality.score, 4), "flags": []}


def test_quality_is_computed_once_per_posterior(body) -> None:
    posterior = reading(body)
    assert posterior.quality is posterior.quality


def test_a_small_person_is_flagged_as_a_note(body) -> None:
    large, small = reading(body).quality, reading(body, side=80.0).quality
    assert "small_person" in small.flags and "small_person" not in large.flags
    assert not small.low  # a note: it warns only with a low score
    assert small.score <= large.score


def test_a_box_at_the_photo_edge_is_flagged(body) -> None:
    quality = reading(body, box=(0.0, 300.0, 600.0, 700.0)).quality
    assert "cut_off_by_edge" in quality.flags


def test_keypoints_outside_the_photo_are_flagged_and_scored_lower(body) -> None:
    inside = reading(body).quality
    outside = reading(body, shift=(0.0, 700.0)).quality  # the legs below the photo's bottom
    assert outside.signals["outside_share"] > 0.2
    assert "cut_off_by_edge" in outside.flags
    assert outside.score < inside.score


def test_low_confidences_are_flagged_and_the_score_never_falls_with_confidence(body) -> None:
    scores = []
    for level in (0.1, 0.3, 0.5, 0.7, 0.9):
        confidences = np.full(17, 0.95)
        confidences[5:] = level  # everything below the face
        quality = reading(body, confidences=confidences).quality
        scores.append(quality.score)
        assert ("few_confident_keypoints" in quality.flags) == (level < 0.6)
    assert np.all(np.diff(scores) >= 0)  # never lower with more confidence


def test_the_score_falls_as_the_mode_misses_the_keypoints(body) -> None:
    scores = [reading(body, shift=(dx, 0.0)).quality.score for dx in (0.0, 40.0, 120.0)]
    assert scores[0] >= scores[1] >= scores[2] and scores[0] > scores[2]
    missed = reading(body, shift=(120.0, 0.0)).quality
    assert "keypoints_not_fitted" in missed.flags


def test_a_weak_face_against_the_shoulders_is_facing_ambiguous() -> None:
    names = list(COCO17_NAMES)
    confidences = np.full(17, 0.99)
    assert not facing_ambiguous(confidences)
    confidences[names.index("nose")] = 0.7  # confident, but far below the shoulders' logits
    assert facing_ambiguous(confidences)
    confidences = np.full(17, 0.9)
    confidences[names.index("left_eye")] = 0.3
    assert facing_ambiguous(confidences)


def test_the_weights_point_the_obvious_way() -> None:
    weights = dict(zip(SCORE_SIGNALS, QUALITY_WEIGHTS[1:], strict=True))
    assert set(SCORE_SIGNALS) <= set(SIGNAL_DIRECTIONS) <= set(SIGNAL_NAMES)
    for name, weight in weights.items():
        assert weight * SIGNAL_DIRECTIONS[name] > 0, name
    assert len(QUALITY_MEAN) == len(SCORE_SIGNALS) == len(QUALITY_WEIGHTS) - 1


def test_quality_score_is_a_probability_for_any_signals() -> None:
    rng = np.random.default_rng(0)
    signals = rng.normal(0, 100, size=(200, len(SCORE_SIGNALS)))
    scores = quality_score(signals)
    assert scores.shape == (200,) and ((scores >= 0) & (scores <= 1)).all()


def test_the_flags_are_documented() -> None:
    assert all(name.isidentifier() and len(name) <= 24 for name in FLAG_MEANINGS)
    warning = ReadingQuality(0.2, ("small_person",), {}).warning()
    assert "0.20" in warning and "small_person" in warning
    assert ReadingQuality(0.9, (), {}).warning() == ""
    assert WARNING_FLAGS.issubset(FLAG_MEANINGS)
    assert ReadingQuality(0.9, ("small_person",), {}).warning() == ""  # a note alone
    assert ReadingQuality(0.9, ("unstable_keypoints",), {}).low


def test_auroc_counts_ranks_and_ties() -> None:
    off = np.array([True, True, False, False])
    assert auroc(np.array([0.1, 0.2, 0.8, 0.9]), off) == 1.0
    assert auroc(np.array([0.9, 0.8, 0.2, 0.1]), off) == 0.0
    assert auroc(np.full(4, 0.5), off) == 0.5
    assert np.isnan(auroc(np.array([0.1, 0.2]), np.array([False, False])))
    with pytest.raises(ValueError, match="same shape"):
        auroc(np.zeros(3), np.zeros(4, bool))


def test_reliability_rows_and_the_off_share_above_the_threshold() -> None:
    score = np.array([0.1, 0.15, 0.55, 0.95, 1.0])
    off = np.array([True, False, True, False, False])
    rows = reliability_rows(score, off)
    assert [row["count"] for row in rows] == [2, 1, 2]
    assert rows[0]["not_off"] == 0.5 and rows[-1]["not_off"] == 1.0
    assert off_share_above(score, off) == pytest.approx(1 / 3)
    summary = quality_summary(score, np.where(off, 0.5, 0.05))
    assert summary["off"] == 2 and summary["readings"] == 5
    table = quality_table("toy", score, np.where(off, 0.5, 0.05))
    assert "| 0.9-1.0 | 2 |" in table and "AUROC" in table


def test_the_explorer_status_warns_on_a_low_reading_and_shows_a_good_ones_score() -> None:
    from hkpd.explorer.panels.status import quality_text

    low = quality_text(SimpleNamespace(quality=ReadingQuality(0.2, ("small_person",), {})))
    assert "Check this reading" in low and "0.20" in low
    assert FLAG_MEANINGS["small_person"] in low and "small_person" not in low  # words, not names
    assert quality_text(SimpleNamespace(quality=ReadingQuality(0.9, (), {}))) == " *Quality 0.90.*"
    noted = ReadingQuality(0.9, ("small_person",), {})
    assert quality_text(SimpleNamespace(quality=noted)) == (
        f" *Quality 0.90; note: {FLAG_MEANINGS['small_person']}.*"
    )
    warned = ReadingQuality(0.9, ("small_person", "off_centre_in_box"), {})
    text = quality_text(SimpleNamespace(quality=warned))
    assert "Check this reading" in text and FLAG_MEANINGS["off_centre_in_box"] in text
    assert quality_text(SimpleNamespace()) == ""  # a custom provider's posterior


def test_a_crop_without_a_side_sizes_the_person_by_its_keypoints(body) -> None:
    posterior = reading(body)
    crop = SimpleNamespace(size=256, crop_to_image=posterior.crop.crop_to_image)
    bare = replace(posterior, crop=crop, network_input=None)
    quality = bare.quality
    extent = np.ptp(posterior.keypoints.numpy(), axis=0).max()
    assert 2.0 ** quality.signals["log2_person_px"] == pytest.approx(extent, rel=1e-5)
    assert 0.0 <= quality.score <= 1.0


def test_hard_synthetic_photos_are_reproducible_and_their_truth_is_in_the_photo() -> None:
    from hkpd.evaluation.quality_data import CANVAS, hard_synthetic_photos, reading_error

    photos = hard_synthetic_photos(4, seed=3)
    again = hard_synthetic_photos(4, seed=3)
    for photo, copy in zip(photos, again, strict=True):
        assert photo.image.shape == (CANVAS, CANVAS, 3) and photo.image.dtype == np.uint8
        assert np.array_equal(photo.image, copy.image)
        shown = photo.keypoints[photo.visible]
        assert ((shown >= 0) & (shown <= CANVAS - 1)).all()
        assert 1.0 <= photo.size <= 2 * CANVAS
        if photo.search_box is not None:  # a second person: read in the first one's box
            x0, y0, x1, y1 = photo.search_box
            assert (shown[:, 0] >= x0).all() and (shown[:, 0] <= x1).all()
            assert (shown[:, 1] >= y0).all() and (shown[:, 1] <= y1).all()
    truth, visible = photos[0].keypoints, np.ones(17, bool)
    moved = truth + np.array([30.0, 40.0])  # 50 px off everywhere
    assert reading_error(moved, truth, visible, 250.0) == pytest.approx(0.2)


def test_a_person_off_the_centre_of_the_given_box_is_flagged(body) -> None:
    points = reading(body).keypoints.double().numpy()
    centre = (points.min(0) + points.max(0)) / 2
    side = float(np.ptp(points, axis=0).max()) * 1.3
    around = (*(centre - side / 2), *(centre + side / 2))
    centred = reading(body, search_box=around).quality
    assert centred.signals["box_offset"] == pytest.approx(0.0, abs=1e-6)
    assert "off_centre_in_box" not in centred.flags
    beside = (around[0] + 0.4 * side, around[1], around[2] + 0.4 * side, around[3])
    moved = reading(body, search_box=beside).quality
    assert moved.signals["box_offset"] == pytest.approx(0.4, abs=1e-6)
    assert "off_centre_in_box" in moved.flags
    assert moved.score < centred.score
    assert reading(body).quality.signals["box_offset"] == 0.0  # no box given


def test_keypoints_that_move_on_a_second_look_are_flagged_and_scored_lower(body) -> None:
    steady = reading(body, landmark_spread=0.01).quality
    moving = reading(body, landmark_spread=0.3).quality
    assert steady.signals["log10_landmark_spread"] == pytest.approx(-2.0)
    assert "unstable_keypoints" in moving.flags and "unstable_keypoints" not in steady.flags
    assert moving.score < steady.score


def test_an_unmeasured_landmark_spread_counts_as_the_fitting_mean(body) -> None:
    unknown = reading(body, landmark_spread=None).quality
    assert np.isnan(unknown.signals["log10_landmark_spread"])
    assert "unstable_keypoints" not in unknown.flags
    signals = np.array([unknown.signals[name] for name in SCORE_SIGNALS])
    if "log10_landmark_spread" in SCORE_SIGNALS:
        index = SCORE_SIGNALS.index("log10_landmark_spread")
        signals[index] = QUALITY_MEAN[index]
    assert unknown.score == pytest.approx(float(quality_score(signals)))


def test_the_overview_shows_a_low_readings_warning_in_red_under_the_footer(body) -> None:
    from hkpd.prediction.exports.overview import make_overview
    from hkpd.prediction.exports.uncertainty_colours import UncertaintyColourScale
    from hkpd.prediction.image_input import load_image

    posterior = reading(body)
    mode = posterior.mode()
    points = posterior.keypoints.double().numpy()
    pictures = []
    for warning in ("", ReadingQuality(0.3, ("unstable_keypoints",), {}).warning()):
        pictures.append(
            make_overview(
                load_image(np.full((1000, 1000, 3), 90, np.uint8)), posterior.crop, points,
                np.ones(17), points, None, mode.vertices[0], body.faces,
                np.zeros(body.faces.max() + 1), UncertaintyColourScale(), height=240,
                caption="run", warning=warning,
            )
        )  # fmt: skip
    plain, warned = pictures
    assert warned.shape[0] == plain.shape[0] + 26  # one more footer row
    row = warned[-26:, warned.shape[1] // 2 :].astype(int)
    assert ((row[..., 0] > 150) & (row[..., 1] < 90)).sum() > 50  # red text


def test_hkpd_predict_names_a_reading_to_check_on_the_console() -> None:
    from hkpd.prediction.cli import _photo_note

    def posterior(quality: ReadingQuality, fallback: str | None = None) -> SimpleNamespace:
        return SimpleNamespace(quality=quality, fallback_reason=fallback, evidence_fit=None)

    assert _photo_note(posterior(ReadingQuality(0.9, ("small_person",), {})), False) is None
    warned = _photo_note(posterior(ReadingQuality(0.38, ("off_centre_in_box",), {})), False)
    assert warned == "check this reading: quality 0.38: off_centre_in_box"
    both = _photo_note(posterior(ReadingQuality(0.2, ("fallback",), {}), "fit failed"), False)
    assert both.startswith("network posterior (fit failed); check this reading: quality 0.20")
