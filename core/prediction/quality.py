"""How far to trust one reading: a calibrated score in [0, 1] and named flags.

:func:`reading_quality` reads a :class:`~hkpd.prediction.posterior.BodyPosterior` and what it
already carries (the detection, the crop, the keypoint fit's report, the person mask, the
network's reading the fit started from) and returns a :class:`ReadingQuality`; nothing is
fitted again (its cost is one mode mesh, a few milliseconds). ``BodyPosterior.quality`` is this,
computed once per posterior.

**The score** is the probability that the reading is *not off*, where off means the mode's 2D
keypoints lie on average more than 0.2 of the person's size from where they truly are (the
project's measure on coco_mini and synthetic photos: ``docs/prediction.md``, "Quality score").
It is a logistic rule on a few standardised signals (:data:`SCORE_SIGNALS`, some of
:data:`SIGNAL_NAMES`) whose weights (:data:`QUALITY_WEIGHTS`) were chosen by
``docs/experiments/quality_fit.py`` on coco_mini train2017 and synthetic photos with hard cases
only; calibrated means that among readings scored
about ``s``, about ``s`` are not off.

**The flags** (:data:`FLAG_MEANINGS`) name what is wrong in words, each by a fixed threshold
on one signal; they do not enter the score (the signals do).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from hkpd.coco_keypoints import COCO17_MIRROR_ORDER, COCO17_NAMES
from hkpd.kinematic_tree import rotation_angle
from hkpd.prediction.reader_agreement import READER_SIGNAL_NAMES, detection_agreement
from hkpd.proxy import CONFIDENCE_THRESHOLD, CROP_MARGIN

if TYPE_CHECKING:
    from hkpd.prediction.posterior import BodyPosterior

SIGNAL_NAMES: tuple[str, ...] = (
    "confident_share",
    "mean_confidence",
    "log2_person_px",
    "outside_share",
    "misfit",
    "downweighted_share",
    "prior_shift",
    "mask_outside",
    "face_minus_shoulders",
    "detector_score",
    "mask_share",
    "log10_landmark_spread",
    "box_offset",
    *READER_SIGNAL_NAMES,
)
"""The signals the score reads, in :attr:`ReadingQuality.signals`' order:

- ``confident_share``: share of the 17 keypoints the detector scores >= 0.6;
- ``mean_confidence``: the detector's mean confidence over the 17;
- ``log2_person_px``: log2 of the person's size in photo pixels (the crop side / 1.2: the
  detected keypoints' longer extent);
- ``outside_share``: share of the 17 detected keypoints placed outside the photo;
- ``misfit``: mean distance of the mode's reprojected keypoints from the evidence keypoints,
  in units of the person's size (1 when there is no evidence);
- ``downweighted_share``: share of the evidence keypoints the fit's robust weights treat as
  outliers (weight < 0.5);
- ``prior_shift``: mean angle (radians) between the network's most likely joint rotations (the
  reading the fit started from) and the posterior's, the global rotation included;
- ``mask_outside``: share of the mode's reprojected keypoints inside the crop where the
  detector's person mask says background (probability < 0.2; 0 without a mask);
- ``face_minus_shoulders``: the nose's confidence logit minus the shoulders' mean (low when the
  face is weakly seen against the body: a back view, ``docs/evidence.md``), clipped to ±10;
- ``detector_score``: BlazePose's person-detector score (0 when it found nobody in the given
  box and the landmark model read the box itself);
- ``mask_share``: share of the crop's known pixels that BlazePose's person mask gives to the
  person (probability >= 0.5; 0 without a mask): large when the mask spills onto people nearby;
- ``log10_landmark_spread``: log10 of how far BlazePose's keypoints move, as a fraction of the
  person's size, when it reads the person again from a slightly moved crop
  (:func:`hkpd.prediction.detection.landmark_spread.landmark_spread`, floored at 0.001); NaN
  when it was not measured (a detection made by hand, a posterior without a photo), and then
  weighed as the fitting data's mean;
- ``box_offset``: distance between the centre of the detected person's box (all 33 BlazePose
  landmarks, ``KeypointDetection.person_box``) and the centre of the box the search was
  restricted to (``bbox``), as a fraction of that box's longer side (0 when no box was given):
  large when the detector took someone beside the person the box was drawn around;
- ``log10_readers_distance``, ``readers_disputed_share``, ``readers_swap_gain``,
  ``readers_torso_offset``: how far the second keypoint reader (MoveNet Thunder) disagrees
  with BlazePose (:class:`hkpd.prediction.reader_agreement.ReaderAgreement`: log10 of the
  mean distance between their keypoints, the share of keypoints further apart than 0.15 of the
  person's size, how much closer they come with one reader's left and right traded, how far
  apart their torsos are; shares of the person's size); NaN when the second reader did not
  read the person (``second_reader=False``, a detection made by hand), and then weighed as
  the fitting data's mean.

A fallback to the network's posterior is a flag, not a signal: none of the fitting readings fell
back, so the data could not weigh it.
"""

SIGNAL_DIRECTIONS: dict[str, int] = {
    "mean_confidence": 1,
    "log2_person_px": 1,
    "outside_share": -1,
    "misfit": -1,
    "prior_shift": -1,
    "mask_outside": -1,
    "detector_score": 1,
    "log10_landmark_spread": -1,
    "box_offset": -1,
    "log10_readers_distance": -1,
    "readers_disputed_share": -1,
    "readers_swap_gain": -1,
    "readers_torso_offset": -1,
}
"""The signals the score may weigh, each with the sign its weight must have (+1: a higher
signal means a more trustworthy reading): ``docs/experiments/quality_fit.py`` drops a signal
whose fitted weight comes out against it. The other signals repeat one of these
(``confident_share``) or have no agreed direction: ``downweighted_share`` and
``face_minus_shoulders`` came out weighted against their meaning (more outliers or a weaker face
scored *higher*) and ``mask_share`` is large both for a person filling the crop and for a mask
spilling onto people nearby."""

SCORE_SIGNALS: tuple[str, ...] = (
    "log2_person_px",
    "misfit",
    "prior_shift",
    "mask_outside",
    "log10_landmark_spread",
    "box_offset",
    "log10_readers_distance",
    "readers_disputed_share",
    "readers_swap_gain",
)
"""The signals the score weighs: those of :data:`SIGNAL_DIRECTIONS` whose fitted weights agree
with their meaning. Fitted with the others, ``outside_share``, ``readers_torso_offset`` (it
repeats the readers' distance), ``mean_confidence`` (the detector is often confidently wrong
about a neighbour or a small person) and ``detector_score`` came out weighted against theirs,
so ``docs/experiments/quality_fit.py`` dropped them in that order; they still raise flags
(``docs/prediction.md``, "Quality score")."""

QUALITY_MEAN = (7.115, 0.02683, 0.09392, 0.09094, -1.632, 0.04842, -1.129, 0.2662, -0.09624)
"""Each score signal's mean over the fitting data (:data:`SCORE_SIGNALS` order)."""

QUALITY_SPREAD = (0.9274, 0.008959, 0.06524, 0.08158, 0.4346, 0.09714, 0.4847, 0.3164, 0.122)
"""Each signal's standard deviation over the fitting data."""

QUALITY_WEIGHTS = (
    3.579, 0.2071, -0.1795, -0.494, -0.409, -1.14, -0.7215, -0.6428, -0.396, -0.1997,
)  # fmt: skip
"""The logistic rule's weights: the bias, then one per standardised score signal, as
``python docs/experiments/quality_fit.py fit`` printed them (readings collected on 2026-12-06
with the shipped predictor and both keypoint readers, before the readers' agreement entered the
fit as evidence: coco_mini train2017, 43 people in their annotated boxes and 27 in the
detector's, and 208 synthetic photos of seed 1)."""

SMALL_PERSON_PX = 96.0
"""``small_person``: the person spans fewer photo pixels than this (the network reads 256)."""

FEW_CONFIDENT = 10
"""``few_confident_keypoints``: fewer of the 17 keypoints than this are confident (>= 0.6)."""

EDGE_FRACTION = 0.01
"""``cut_off_by_edge``: the detected person's box comes within this share of the photo's larger
side of its edge, or a detected keypoint lies outside the photo."""

FAR_FROM_NETWORK_RADIANS = 0.35
"""``fit_far_from_network``: the fit moved the joints on average by more than this (20°)."""

MISFIT_FRACTION = 0.1
"""``keypoints_not_fitted``: the mode misses the evidence keypoints by more than this share of
the person's size on average."""

MASK_OUTSIDE_SHARE = 0.25
"""``body_outside_mask``: more than this share of the mode's keypoints lie on the person mask's
background."""

FACE_BEHIND_SHOULDERS_LOGIT = -1.5
"""``facing_ambiguous``: the nose's confidence logit lies this far below the shoulders' mean
(``docs/evidence.md``: back views' median -2.0, front views' 0.4 on val2017), or the nose and
eyes are not all confident."""

SECOND_FACE_SCORE = 0.25
"""``facing_ambiguous`` also when the second reader (MoveNet Thunder) scores the nose or an eye
below this: on coco_mini train2017's people labelled by eye (``people_labels.json``, boxes >= 80
px) it caught all 6 back views and 1 of 36 others (AUROC of its weakest face score for a back
view 0.99; BlazePose's face-against-shoulders logit: 0.63); on val2017 8 of 10 and 3 of 22."""

MASK_BACKGROUND = 0.2
"""A crop pixel whose person-mask probability is below this counts as background."""

FLAG_MEANINGS: dict[str, str] = {
    "few_confident_keypoints": f"fewer than {FEW_CONFIDENT} of 17 keypoints are confident",
    "small_person": f"the person spans fewer than {SMALL_PERSON_PX:.0f} photo pixels",
    "cut_off_by_edge": "the person reaches the photo's edge or keypoints lie outside it",
    "fit_far_from_network": "the keypoint fit moved the joints far from the network's reading",
    "keypoints_not_fitted": "the most likely body misses the detected keypoints",
    "body_outside_mask": "the most likely body lies partly outside the detector's person mask",
    "fallback": "the keypoint fit failed: the network's own posterior is returned",
    "unstable_keypoints": "the detector's keypoints move when it looks again from a slightly "
    "different crop",
    "off_centre_in_box": "the person found is off the centre of the box given: it may be "
    "someone beside them",
    "turned_copy": "read from a copy of the photo turned upright, or from a body turned to "
    "face the other way",
    "facing_ambiguous": "the face is weakly seen: the person may face the other way (the "
    "turned-around reading may fit better)",
    "readers_disagree": "a second, independent keypoint reader places the body differently "
    "(other limbs, or another person)",
    "left_right_unsure": "the two keypoint readers disagree on which side is left and which "
    "is right",
    "looks_like_a_child": "the face looks like a child's: the body model is adult-only, so the "
    "body drawn is an adult's",
}
"""Every flag :func:`reading_quality` may set, and what it means: plain words a class reads
(the explorer's status line and captions show these, never the flag names)."""

UNSTABLE_SPREAD = 0.1
"""``unstable_keypoints``: the keypoints move by more than this share of the person's size on
average when the detector reads the person again (``log10_landmark_spread`` > -1)."""

READERS_DISPUTED_SHARE = 0.5
"""``readers_disagree``: the second reader places more than this share of the 17 keypoints
further than 0.15 of the person's size from BlazePose's (``readers_disputed_share``) ..."""

READERS_TORSO_OFFSET = 0.25
"""... or its torso's centre more than this share of the person's size from BlazePose's."""

SWAP_GAIN = 0.1
"""``left_right_unsure``: the second reader comes closer to BlazePose by more than this share of
the person's size on average when its left and right are traded (``readers_swap_gain``)."""

OFF_CENTRE_OFFSET = 0.2
"""``off_centre_in_box``: the detected person's box is centred more than this share of the
given box's longer side from the box's centre."""

WARNING_FLAGS: frozenset[str] = frozenset(
    {
        "few_confident_keypoints",
        "fit_far_from_network",
        "keypoints_not_fitted",
        "body_outside_mask",
        "fallback",
        "unstable_keypoints",
        "off_centre_in_box",
        "readers_disagree",
        "left_right_unsure",
    }
)
"""The flags that warn (:attr:`ReadingQuality.low`) whatever the score: those under which more
than a third of the fitting readings were off (twice the 18 % of all of them; coco_mini
train2017 and the seed-1 synthetic photos: ``docs/prediction.md``, "Quality score"), and a
failed or missed fit. The reader flags' thresholds were chosen on the same readings (the
fewest warnings that keep the off share among readings not warned below 5 %: 3.3 %, 34 % warned;
``readers_disagree`` 48 % off, ``left_right_unsure`` 35 %). The others (``small_person``,
``cut_off_by_edge``, ``turned_copy``, ``facing_ambiguous``: 17-27 % off) are notes: they say
what to look at, and warn only with a low score."""

LOW_SCORE = 0.5
"""Below this score a reading is shown with a warning (the overview, the explorer)."""


@dataclass(frozen=True)
class ReadingQuality:
    """How far to trust one reading (module docstring).

    Attributes:
        score: in [0, 1], the calibrated probability that the reading is not off (its mode's
            keypoints within 0.2 of the person's size of the truth on average).
        flags: short names of what looks wrong, :data:`FLAG_MEANINGS` order (empty: nothing).
        signals: ``{name: value}`` of :data:`SIGNAL_NAMES`, what the score read.
    """

    score: float
    flags: tuple[str, ...]
    signals: dict[str, float]

    def __repr__(self) -> str:
        return f"ReadingQuality(score={self.score:.2f}, flags={self.flags})"

    @property
    def low(self) -> bool:
        """The score is below :data:`LOW_SCORE` or a :data:`WARNING_FLAGS` flag is set: show a
        warning."""
        return self.score < LOW_SCORE or not WARNING_FLAGS.isdisjoint(self.flags)

    def warning(self) -> str:
        """One line for a picture or a status bar: the score and the flags ("" when
        :attr:`low` is False)."""
        if not self.low:
            return ""
        named = ", ".join(self.flags) if self.flags else "no single cause"
        return f"quality {self.score:.2f}: {named}"

    def as_dict(self) -> dict[str, object]:
        """``{"score": s, "flags": [...]}`` as summary.json writes it."""
        return {"score": round(self.score, 4), "flags": list(self.flags)}


def quality_score(signals: np.ndarray) -> np.ndarray:
    """``(..., S)`` signals (:data:`SCORE_SIGNALS` order) -> ``(...)`` scores in [0, 1]; a NaN
    signal (not measured) counts as the fitting data's mean."""
    values = np.asarray(signals, dtype=np.float64)
    standard = np.nan_to_num((values - np.asarray(QUALITY_MEAN)) / np.asarray(QUALITY_SPREAD))
    weights = np.asarray(QUALITY_WEIGHTS)
    logit = weights[0] + standard @ weights[1:]
    return 1.0 / (1.0 + np.exp(-np.clip(logit, -30.0, 30.0)))


def reading_quality(posterior: BodyPosterior) -> ReadingQuality:
    """The quality record of ``posterior`` (module docstring)."""
    signals = reading_signals(posterior)
    score = float(quality_score(np.array([signals[name] for name in SCORE_SIGNALS])))
    return ReadingQuality(score, reading_flags(posterior, signals), signals)


def reading_signals(posterior: BodyPosterior) -> dict[str, float]:
    """``{name: value}`` of :data:`SIGNAL_NAMES` for ``posterior``."""
    confidences = _detector_confidences(posterior)
    keypoints = _detector_keypoints(posterior)
    person_px = _person_px(posterior, keypoints, confidences)
    mode_points = posterior.mode().keypoints2d[0].detach().cpu().double().numpy()  # (17, 2)
    if posterior.turned:  # the turned body's left keypoints explain the detector's right ones
        mode_points = mode_points[list(COCO17_MIRROR_ORDER)]
    return {
        "confident_share": float(np.mean(confidences >= CONFIDENCE_THRESHOLD)),
        "mean_confidence": float(confidences.mean()),
        "log2_person_px": math.log2(max(person_px, 1.0)),
        "outside_share": _outside_share(posterior, keypoints),
        "misfit": _misfit(posterior, mode_points, keypoints, person_px),
        "downweighted_share": _downweighted_share(posterior),
        "prior_shift": _prior_shift(posterior),
        "mask_outside": _mask_outside(posterior, mode_points),
        "face_minus_shoulders": face_minus_shoulders(confidences),
        "detector_score": _detector_score(posterior),
        "mask_share": _mask_share(posterior),
        "log10_landmark_spread": _log10_landmark_spread(posterior),
        "box_offset": _box_offset(posterior),
        **_reader_signals(posterior),
    }


def reading_flags(posterior: BodyPosterior, signals: dict[str, float]) -> tuple[str, ...]:
    """The flags of ``posterior`` whose thresholds ``signals`` pass, :data:`FLAG_MEANINGS`
    order."""
    confidences = _detector_confidences(posterior)
    fit = posterior.evidence_fit
    raised = {
        "few_confident_keypoints": int((confidences >= CONFIDENCE_THRESHOLD).sum()) < FEW_CONFIDENT,
        "small_person": 2.0 ** signals["log2_person_px"] < SMALL_PERSON_PX,
        "cut_off_by_edge": signals["outside_share"] > 0 or _box_at_edge(posterior),
        "fit_far_from_network": signals["prior_shift"] > FAR_FROM_NETWORK_RADIANS,
        "keypoints_not_fitted": signals["misfit"] > MISFIT_FRACTION,
        "body_outside_mask": signals["mask_outside"] > MASK_OUTSIDE_SHARE,
        "fallback": posterior.fallback_reason is not None,
        "unstable_keypoints": signals["log10_landmark_spread"] > math.log10(UNSTABLE_SPREAD),
        "off_centre_in_box": signals["box_offset"] > OFF_CENTRE_OFFSET,
        "turned_copy": bool(
            posterior.turned
            or (fit is not None and posterior.conditioned and (fit.turned or fit.start == 1))
        ),
        "facing_ambiguous": facing_ambiguous(confidences) or _second_reader_sees_no_face(posterior),
        "readers_disagree": bool(
            signals["readers_disputed_share"] > READERS_DISPUTED_SHARE
            or signals["readers_torso_offset"] > READERS_TORSO_OFFSET
        ),
        "left_right_unsure": bool(signals["readers_swap_gain"] > SWAP_GAIN),
        "looks_like_a_child": posterior.face is not None and posterior.face.child,
    }
    return tuple(name for name in FLAG_MEANINGS if raised[name])


def face_minus_shoulders(confidences: np.ndarray) -> float:
    """``(17,)`` detector confidences -> the nose's logit minus the shoulders' mean logit,
    clipped to ±10."""
    names = list(COCO17_NAMES)
    clipped = np.clip(np.asarray(confidences, dtype=np.float64), 1e-6, 1 - 1e-6)
    logits = np.log(clipped / (1 - clipped))
    shoulders = [names.index("left_shoulder"), names.index("right_shoulder")]
    return float(np.clip(logits[names.index("nose")] - logits[shoulders].mean(), -10.0, 10.0))


def facing_ambiguous(confidences: np.ndarray) -> bool:
    """``(17,)`` detector confidences -> the face is weakly seen against the shoulders
    (:data:`FACE_BEHIND_SHOULDERS_LOGIT`) or the nose and eyes are not all confident."""
    names = list(COCO17_NAMES)
    face = [names.index(name) for name in ("nose", "left_eye", "right_eye")]
    behind = face_minus_shoulders(confidences) < FACE_BEHIND_SHOULDERS_LOGIT
    weak = (np.asarray(confidences, dtype=np.float64)[face] < CONFIDENCE_THRESHOLD).any()
    return bool(behind or weak)


def _second_reader_sees_no_face(posterior: BodyPosterior) -> bool:
    """The second reader scores the nose or an eye below :data:`SECOND_FACE_SCORE` (False when
    it did not read the person)."""
    prepared = posterior.network_input
    second = None if prepared is None else getattr(prepared.detection, "second_reading", None)
    if second is None:
        return False
    return bool(np.asarray(second.scores, dtype=np.float64)[:3].min() < SECOND_FACE_SCORE)


def _reader_signals(posterior: BodyPosterior) -> dict[str, float]:
    """The second reader's signals (:data:`READER_SIGNAL_NAMES`); NaN when it did not read."""
    prepared = posterior.network_input
    agreement = None if prepared is None else detection_agreement(prepared.detection)
    if agreement is None:
        return dict.fromkeys(READER_SIGNAL_NAMES, float("nan"))
    return agreement.signals()


def _detector_score(posterior: BodyPosterior) -> float:
    """BlazePose's person-detector score; 0 when it found nobody in the box; 1 when unknown
    (no photo)."""
    prepared = posterior.network_input
    if prepared is None:
        return 1.0
    score = getattr(prepared.detection, "detector_score", 1.0)
    return 0.0 if score is None else float(score)


def _log10_landmark_spread(posterior: BodyPosterior) -> float:
    """log10 of the detection's ``landmark_spread`` (floored at 0.001); NaN when unknown."""
    prepared = posterior.network_input
    spread = None if prepared is None else getattr(prepared.detection, "landmark_spread", None)
    return float("nan") if spread is None else math.log10(max(float(spread), 1e-3))


def _search_box(posterior: BodyPosterior) -> np.ndarray | None:
    """``(4,)`` the box the detector's search was restricted to, photo pixels; None when the
    whole photo was searched."""
    prepared = posterior.network_input
    box = None if prepared is None else getattr(prepared.detection, "search_box", None)
    return None if box is None else np.asarray(box, dtype=np.float64)


def _box_offset(posterior: BodyPosterior) -> float:
    """Distance from the centre of the detected person's box to the centre of the box searched,
    / the searched box's longer side; 0 when the whole photo was searched."""
    box = _search_box(posterior)
    if box is None:
        return 0.0
    person = np.asarray(posterior.network_input.detection.person_box, dtype=np.float64)
    side = max(float((box[2:] - box[:2]).max()), 1.0)
    return float(np.linalg.norm((person[:2] + person[2:]) / 2 - (box[:2] + box[2:]) / 2) / side)


def _detector_confidences(posterior: BodyPosterior) -> np.ndarray:
    """``(17,)`` the detector's own confidences (before the evidence rule zeroed any)."""
    if posterior.network_input is not None:
        return np.asarray(posterior.network_input.detection.confidences, dtype=np.float64)
    return posterior.confidences.detach().cpu().double().numpy()


def _detector_keypoints(posterior: BodyPosterior) -> np.ndarray:
    """``(17, 2)`` detected keypoints, photo pixels."""
    return posterior.keypoints.detach().cpu().double().numpy()


def _person_px(posterior: BodyPosterior, keypoints: np.ndarray, confidences: np.ndarray) -> float:
    """The person's size in photo pixels: the crop's side / 1.2 (the keypoints' longer extent
    it was made from), or for a crop that gives no side, the confident keypoints' extent."""
    side = getattr(posterior.crop, "side", None)
    if side is not None:
        return float(side) / CROP_MARGIN
    confident = keypoints[confidences >= CONFIDENCE_THRESHOLD]
    return float(np.ptp(confident, axis=0).max()) if len(confident) >= 2 else 1.0


def _image_size(posterior: BodyPosterior) -> tuple[int, int] | None:
    prepared = posterior.network_input
    return None if prepared is None else tuple(prepared.detection.image_size)


def _outside_share(posterior: BodyPosterior, keypoints: np.ndarray) -> float:
    """Share of the 17 detected keypoints outside the photo (0 when the photo is unknown)."""
    size = _image_size(posterior)
    if size is None:
        return 0.0
    width, height = size
    inside = (keypoints >= -0.5).all(-1) & (keypoints[:, 0] <= width - 0.5)
    inside &= keypoints[:, 1] <= height - 0.5
    return float(1.0 - inside.mean())


def _box_at_edge(posterior: BodyPosterior) -> bool:
    """The detected person's box comes within :data:`EDGE_FRACTION` of the photo's edge."""
    size = _image_size(posterior)
    if size is None:
        return False
    width, height = size
    x0, y0, x1, y1 = np.asarray(posterior.network_input.detection.person_box, dtype=np.float64)
    margin = EDGE_FRACTION * max(width, height)
    return bool(min(x0, y0, width - x1, height - y1) < margin)


def _misfit(
    posterior: BodyPosterior, mode_points: np.ndarray, keypoints: np.ndarray, person_px: float
) -> float:
    """Mean distance of the mode's keypoints from the evidence keypoints / the person's size."""
    evidence = _evidence(posterior)
    if not evidence.any():
        return 1.0
    distance = np.linalg.norm(mode_points[evidence] - keypoints[evidence], axis=-1)
    return float(distance.mean() / max(person_px, 1.0))


def _evidence(posterior: BodyPosterior) -> np.ndarray:
    if posterior.evidence is None:
        return _detector_confidences(posterior) >= CONFIDENCE_THRESHOLD
    return posterior.evidence.detach().cpu().numpy().astype(bool)


def _downweighted_share(posterior: BodyPosterior) -> float:
    """Share of the evidence keypoints with robust weight < 0.5 (0 without a fit)."""
    fit, evidence = posterior.evidence_fit, _evidence(posterior)
    if fit is None or fit.keypoint_weights is None or not evidence.any():
        return 0.0
    weights = fit.keypoint_weights.detach().cpu().numpy()[evidence]
    return float(np.mean(weights < 0.5))


def _prior_shift(posterior: BodyPosterior) -> float:
    """Mean rotation angle (radians) between the network reading's modal joint rotations and
    global rotation and the posterior's (0 for the network's own posterior)."""
    if posterior.prior is None or not posterior.conditioned:
        return 0.0
    before = torch.cat(
        (posterior.prior.pose_distribution.mode[0], posterior.prior.global_orient[None])
    )
    after = torch.cat((posterior.pose_distribution.mode[0], posterior.global_orient[None]))
    return float(rotation_angle(before.double(), after.double()).mean())


def _mask_share(posterior: BodyPosterior) -> float:
    """Share of the crop's known pixels with person-mask probability >= 0.5 (0 without one)."""
    prepared = posterior.network_input
    if prepared is None or prepared.person_mask is None:
        return 0.0
    mask = np.asarray(prepared.person_mask) >= 0.5
    known = prepared.person_mask_known
    known = np.ones(mask.shape, bool) if known is None else np.asarray(known, bool)
    return float(mask[known].mean()) if known.any() else 0.0


def _mask_outside(posterior: BodyPosterior, mode_points: np.ndarray) -> float:
    """Share of the mode's keypoints inside the crop that land on the person mask's known
    background (0 without a mask or when none lands in the crop)."""
    prepared = posterior.network_input
    if prepared is None or prepared.person_mask is None:
        return 0.0
    mask = np.asarray(prepared.person_mask)
    known = (
        np.ones(mask.shape, bool)
        if prepared.person_mask_known is None
        else np.asarray(prepared.person_mask_known)
    )
    pixels = np.round(np.asarray(posterior.crop.image_to_crop(mode_points))).astype(np.int64)
    size = mask.shape[0]
    inside = ((pixels >= 0) & (pixels < size)).all(-1)
    columns, rows = pixels[inside, 0], pixels[inside, 1]
    counted = known[rows, columns]
    if not counted.any():
        return 0.0
    return float(np.mean(mask[rows, columns][counted] < MASK_BACKGROUND))
