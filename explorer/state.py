"""The explorer's application state: pure data and rules, no viser, no torch.

One :class:`ExplorerState` is shared by every browser tab; all access goes through its lock, so
two tabs editing at once never see half-applied changes. Two version counters tell the worker
what is stale: ``prediction_version`` (photo or occluders changed: run the predictor again) and
``sampling_version`` (concentration, shape spread, sample count or seed changed: draw new samples
from the current posterior). The shapes of further photos of the same person (combined with the
current photo's into one shape) are kept as plain numbers; a new photo starts a new person.
What the user stated about the person's body (:class:`BodyStatement`: sex, measurements)
belongs to that person too: a new photo starts with nothing stated, and a change predicts again.

Occluder boxes are ``(x0, y0, x1, y1)`` in original-photo pixels, pixel-edge coordinates (pixel
column ``i`` spans ``[i, i + 1)``), exactly what :func:`hkpd.prediction.apply_occluders` takes.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field, replace
from typing import Any

from hkpd.explorer.body_settings import NOTHING_STATED, BodyStatement
from hkpd.kinematic_tree import BODY_JOINT_NAMES, body_joint_index

NUM_BODY_JOINTS = len(BODY_JOINT_NAMES)

MIN_OCCLUDER_SIDE = 2.0
"""Smallest occluder side in pixels; smaller drags are treated as clicks and ignored."""

MAX_OCCLUDERS = 16
"""More boxes than this would clutter the panel; the 17th is refused."""

CONCENTRATION_EXPONENT_RANGE = (-1.0, 1.0)
"""Sliders act on log10 of the factor: 0.1x .. 10x."""

MAX_SAMPLES = 200
"""Upper bound on the number of samples drawn for the heatmap."""

MAX_DISPLAYED_SAMPLES = 30
"""Upper bound on the number of sample meshes drawn in the scene."""

LIMB_GROUPS: dict[str, tuple[str, ...]] = {
    "Spine and head": ("spine1", "spine2", "spine3", "neck", "head"),
    "Left arm": ("left_collar", "left_shoulder", "left_elbow", "left_wrist", "left_hand"),
    "Right arm": ("right_collar", "right_shoulder", "right_elbow", "right_wrist", "right_hand"),
    "Left leg": ("left_hip", "left_knee", "left_ankle", "left_foot"),
    "Right leg": ("right_hip", "right_knee", "right_ankle", "right_foot"),
}
"""The 23 body joints grouped by limb, for the concentration folders."""

MAX_SAME_PERSON_PHOTOS = 20
"""Further photos of the same person kept at most (besides the current photo)."""


@dataclass(frozen=True)
class SamePersonShape:
    """The shape Gaussian predicted for one more photo of the current person.

    Attributes:
        name: the photo's file name (for the panel).
        mean: ``K`` mean shape coefficients.
        std: ``K`` their standard deviations (> 0).
        sexes: the photo's shape per sex (:class:`hkpd.prediction.sex_latent.SexShapes`), or
            None; with it the photos combine per sex (:mod:`hkpd.prediction.sex_combination`).
        stated: what the photo was predicted with (:class:`hkpd.stated_body.StatedBody`), or
            None.
    """

    name: str
    mean: tuple[float, ...]
    std: tuple[float, ...]
    sexes: Any = field(default=None, compare=False, hash=False, repr=False)
    stated: Any = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Occluder:
    """One rectangular occluder on the photo.

    Attributes:
        ident: stable id (never reused while the app runs).
        box: ``(x0, y0, x1, y1)`` original-photo pixels, ``x0 < x1``, ``y0 < y1``.
        enabled: disabled occluders stay listed but are not applied.
    """

    ident: int
    box: tuple[float, float, float, float]
    enabled: bool = True


def clamp_box(
    box: tuple[float, float, float, float], width: int, height: int
) -> tuple[float, float, float, float] | None:
    """Order a box's corners, clip it to a ``width x height`` photo, round to whole pixels.

    Returns:
        ``(x0, y0, x1, y1)`` integers (as floats) inside ``[0, width] x [0, height]``, or None
        when less than
        :data:`MIN_OCCLUDER_SIDE` pixels of it remain on the photo (or it is not finite).
    """
    if not all(math.isfinite(v) for v in box):
        return None
    x0, x1 = sorted((float(box[0]), float(box[2])))
    y0, y1 = sorted((float(box[1]), float(box[3])))
    x0, x1 = (float(round(min(max(v, 0.0), width))) for v in (x0, x1))
    y0, y1 = (float(round(min(max(v, 0.0), height))) for v in (y0, y1))
    if x1 - x0 < MIN_OCCLUDER_SIDE or y1 - y0 < MIN_OCCLUDER_SIDE:
        return None
    return (x0, y0, x1, y1)


@dataclass(frozen=True)
class StateSnapshot:
    """A consistent copy of the state, taken under the lock (safe to read without it)."""

    image_size: tuple[int, int]
    occluders: tuple[Occluder, ...]
    joint_exponents: tuple[float, ...]
    global_exponent: float
    shape_std_exponent: float
    num_samples: int
    num_displayed: int
    seed: int
    selected_joint: str
    prediction_version: int
    sampling_version: int
    evidence: bool = True
    person_box: tuple[float, float, float, float] | None = None
    same_person: tuple[SamePersonShape, ...] = ()
    silhouette: bool = False
    stated: BodyStatement = NOTHING_STATED
    turned_around: bool = False

    @property
    def active_boxes(self) -> list[tuple[float, float, float, float]]:
        """Boxes of the enabled occluders, in list order."""
        return [o.box for o in self.occluders if o.enabled]

    @property
    def concentration_factors(self) -> tuple[float, ...]:
        """``(23,)`` combined factor per joint: ``10 ** (joint + global exponent)``."""
        return tuple(10.0 ** (e + self.global_exponent) for e in self.joint_exponents)

    @property
    def shape_std_factor(self) -> float:
        """Factor on the predicted shape standard deviations."""
        return 10.0**self.shape_std_exponent


@dataclass
class ExplorerState:
    """Thread-safe, mutable state of the explorer (see the module docstring).

    Every mutator validates its input, applies the change under the lock and bumps the version
    that the change makes stale; it returns whether anything changed, so callers can skip work.
    """

    image_size: tuple[int, int] = (1, 1)
    num_samples: int = 100
    num_displayed: int = 10
    seed: int = 0
    selected_joint: str = "left_elbow"
    evidence: bool = True
    person_box: tuple[float, float, float, float] | None = None
    silhouette: bool = False
    turned_around: bool = False
    _occluders: list[Occluder] = field(default_factory=list)
    _joint_exponents: list[float] = field(default_factory=lambda: [0.0] * NUM_BODY_JOINTS)
    _global_exponent: float = 0.0
    _shape_std_exponent: float = 0.0
    _same_person: list[SamePersonShape] = field(default_factory=list)
    _stated: BodyStatement = NOTHING_STATED
    _next_ident: int = 1
    _prediction_version: int = 0
    _sampling_version: int = 0
    _lock: threading.RLock = field(default_factory=threading.RLock, repr=False)

    # ------------------------------------------------------------------ reading
    def snapshot(self) -> StateSnapshot:
        """A consistent immutable copy of everything."""
        with self._lock:
            return StateSnapshot(
                image_size=self.image_size,
                occluders=tuple(self._occluders),
                joint_exponents=tuple(self._joint_exponents),
                global_exponent=self._global_exponent,
                shape_std_exponent=self._shape_std_exponent,
                num_samples=self.num_samples,
                num_displayed=self.num_displayed,
                seed=self.seed,
                selected_joint=self.selected_joint,
                prediction_version=self._prediction_version,
                sampling_version=self._sampling_version,
                evidence=self.evidence,
                person_box=self.person_box,
                same_person=tuple(self._same_person),
                silhouette=self.silhouette,
                stated=self._stated,
                turned_around=self.turned_around,
            )

    def occluder(self, ident: int) -> Occluder:
        """The occluder with this id; KeyError if it was deleted."""
        with self._lock:
            index = self._find(ident)
            if index is None:
                raise KeyError(f"no occluder with id {ident}")
            return self._occluders[index]

    # ------------------------------------------------------------------ photo
    def set_image(
        self, width: int, height: int, person_box: tuple[float, float, float, float] | None = None
    ) -> None:
        """A new photo: its size, no occluders, no person box, no further photos of the same
        person, nothing stated about the body and not turned around (they belong to the old
        photo's person) unless ``person_box`` is given; concentration edits are kept."""
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width}x{height}")
        with self._lock:
            self.image_size = (int(width), int(height))
            self._occluders.clear()
            self._next_ident = 1
            self._same_person.clear()
            self._stated = NOTHING_STATED
            self.turned_around = False
            self.person_box = None if person_box is None else clamp_box(person_box, width, height)
            self._prediction_version += 1

    def set_person_box(self, box: tuple[float, float, float, float] | None) -> bool:
        """Look for the person only inside ``box`` (photo pixels; None: anywhere). False if
        unchanged or the box is too small."""
        with self._lock:
            clamped = None if box is None else clamp_box(box, *self.image_size)
            if (box is not None and clamped is None) or clamped == self.person_box:
                return False
            self.person_box = clamped
            self._prediction_version += 1
            return True

    def set_evidence(self, enabled: bool) -> bool:
        """Condition on the photo's 2D keypoints (True) or show the network alone."""
        with self._lock:
            if self.evidence == bool(enabled):
                return False
            self.evidence = bool(enabled)
            self._prediction_version += 1
            return True

    def set_turned_around(self, enabled: bool) -> bool:
        """Show the turned-around reading of the person (True: the same keypoints fitted by a
        body facing the other way, :meth:`hkpd.prediction.BodyPosterior.turned_around`) or
        the reading as predicted."""
        with self._lock:
            if self.turned_around == bool(enabled):
                return False
            self.turned_around = bool(enabled)
            self._prediction_version += 1
            return True

    def set_silhouette(self, enabled: bool) -> bool:
        """Fit the person mask as well as the keypoints (True; only with :attr:`evidence`) or
        the keypoints alone."""
        with self._lock:
            if self.silhouette == bool(enabled):
                return False
            self.silhouette = bool(enabled)
            self._prediction_version += 1
            return True

    @property
    def stated(self) -> BodyStatement:
        """What the user stated about the person's body (sex, measurements)."""
        with self._lock:
            return self._stated

    def set_stated(self, stated: BodyStatement) -> bool:
        """State the person's sex and measurements (a checked :class:`BodyStatement`; an empty
        one: let the photo decide); False if unchanged."""
        if not isinstance(stated, BodyStatement):
            raise TypeError(f"expected a BodyStatement, got {type(stated).__name__}")
        with self._lock:
            if stated == self._stated:
                return False
            self._stated = stated
            self._prediction_version += 1
            return True

    @property
    def occluders_full(self) -> bool:
        """True when no further occluder can be added."""
        with self._lock:
            return len(self._occluders) >= MAX_OCCLUDERS

    # ------------------------------------------------------------------ same person
    def add_same_person_shape(
        self,
        name: str,
        mean: tuple[float, ...],
        std: tuple[float, ...],
        sexes: Any = None,
        stated: Any = None,
    ) -> bool:
        """Keep one more photo's shape Gaussian for the current person; False when
        :data:`MAX_SAME_PERSON_PHOTOS` are kept already.

        Raises:
            ValueError: mean and std of different lengths, non-finite values or stds <= 0.
        """
        mean = tuple(float(v) for v in mean)
        std = tuple(float(v) for v in std)
        if len(mean) != len(std) or not mean:
            raise ValueError(f"shape mean and std need the same length >= 1, got {len(mean)} "
                             f"and {len(std)}")  # fmt: skip
        if not all(math.isfinite(v) for v in mean + std) or min(std) <= 0:
            raise ValueError("shape means must be finite and stds finite and > 0")
        with self._lock:
            if len(self._same_person) >= MAX_SAME_PERSON_PHOTOS:
                return False
            if self._same_person and len(self._same_person[0].mean) != len(mean):
                raise ValueError(
                    f"this photo has {len(mean)} shape coefficients, the kept ones have "
                    f"{len(self._same_person[0].mean)}"
                )
            self._same_person.append(SamePersonShape(str(name), mean, std, sexes, stated))
            return True

    def clear_same_person(self) -> bool:
        """Forget the further photos of the person; False if there were none."""
        with self._lock:
            had_photos = bool(self._same_person)
            self._same_person.clear()
            return had_photos

    # ------------------------------------------------------------------ occluders
    def add_occluder(self, box: tuple[float, float, float, float]) -> Occluder | None:
        """Add a box (clamped to the photo); None when too small, off the photo or too many."""
        with self._lock:
            clamped = clamp_box(box, *self.image_size)
            if clamped is None or len(self._occluders) >= MAX_OCCLUDERS:
                return None
            occluder = Occluder(self._next_ident, clamped)
            self._next_ident += 1
            self._occluders.append(occluder)
            self._prediction_version += 1
            return occluder

    def move_occluder(self, ident: int, box: tuple[float, float, float, float]) -> bool:
        """Give an occluder a new box (clamped). False if unchanged, gone, or clamped away."""
        with self._lock:
            index = self._find(ident)
            clamped = clamp_box(box, *self.image_size)
            if index is None or clamped is None or clamped == self._occluders[index].box:
                return False
            self._occluders[index] = replace(self._occluders[index], box=clamped)
            self._prediction_version += 1
            return True

    def set_occluder_enabled(self, ident: int, enabled: bool) -> bool:
        """Switch an occluder on or off; False if unchanged or gone."""
        with self._lock:
            index = self._find(ident)
            if index is None or self._occluders[index].enabled == bool(enabled):
                return False
            self._occluders[index] = replace(self._occluders[index], enabled=bool(enabled))
            self._prediction_version += 1
            return True

    def delete_occluder(self, ident: int) -> bool:
        """Remove an occluder; False if it was already gone (two tabs clicking delete)."""
        with self._lock:
            index = self._find(ident)
            if index is None:
                return False
            del self._occluders[index]
            self._prediction_version += 1
            return True

    def clear_occluders(self) -> bool:
        """Remove every occluder (the next one is #1 again); False if there were none."""
        with self._lock:
            if not self._occluders:
                return False
            self._occluders.clear()
            self._next_ident = 1
            self._prediction_version += 1
            return True

    # ------------------------------------------------------------------ sampling controls
    def set_joint_exponent(self, joint: str, exponent: float) -> bool:
        """log10 of one joint's concentration factor, clipped to [-1, 1]."""
        index = body_joint_index(joint)
        value = _clip_exponent(exponent)
        with self._lock:
            if self._joint_exponents[index] == value:
                return False
            self._joint_exponents[index] = value
            self._sampling_version += 1
            return True

    def set_global_exponent(self, exponent: float) -> bool:
        """log10 of the factor applied to every joint's concentration, clipped to [-1, 1]."""
        return self._set_sampling("_global_exponent", _clip_exponent(exponent))

    def set_shape_std_exponent(self, exponent: float) -> bool:
        """log10 of the factor on the shape standard deviations, clipped to [-1, 1]."""
        return self._set_sampling("_shape_std_exponent", _clip_exponent(exponent))

    def reset_concentrations(self) -> bool:
        """All factors back to 1x; False if they already were."""
        with self._lock:
            if (
                not any(self._joint_exponents)
                and self._global_exponent == 0.0
                and self._shape_std_exponent == 0.0
            ):
                return False
            self._joint_exponents = [0.0] * NUM_BODY_JOINTS
            self._global_exponent = 0.0
            self._shape_std_exponent = 0.0
            self._sampling_version += 1
            return True

    def set_num_samples(self, count: int) -> bool:
        """Samples drawn for the heatmap, 2 .. MAX_SAMPLES."""
        return self._set_sampling("num_samples", int(min(max(int(count), 2), MAX_SAMPLES)))

    def set_num_displayed(self, count: int) -> bool:
        """Sample meshes drawn in the scene, 0 .. MAX_DISPLAYED_SAMPLES."""
        value = int(min(max(int(count), 0), MAX_DISPLAYED_SAMPLES))
        return self._set_sampling("num_displayed", value)

    def set_seed(self, seed: int) -> bool:
        """Seed of the sample draw (>= 0)."""
        return self._set_sampling("seed", max(int(seed), 0))

    def next_seed(self) -> int:
        """Resample: move to the next seed and return it."""
        with self._lock:
            self.seed += 1
            self._sampling_version += 1
            return self.seed

    def select_joint(self, joint: str) -> bool:
        """The joint shown in the teaching panel."""
        body_joint_index(joint)
        return self._set_sampling("selected_joint", joint)

    # ------------------------------------------------------------------ helpers
    def _set_sampling(self, name: str, value: float | int | str) -> bool:
        """Set the sampling control ``name`` (an attribute) to ``value``, already validated, and
        make the samples stale; False if it already had that value."""
        with self._lock:
            if getattr(self, name) == value:
                return False
            setattr(self, name, value)
            self._sampling_version += 1
            return True

    def _find(self, ident: int) -> int | None:
        """Position of the occluder ``ident`` in the list; None if it is gone."""
        for index, occluder in enumerate(self._occluders):
            if occluder.ident == ident:
                return index
        return None


def _clip_exponent(exponent: float) -> float:
    value = float(exponent)
    if not math.isfinite(value):
        raise ValueError(f"exponent must be finite, got {exponent}")
    low, high = CONCENTRATION_EXPONENT_RANGE
    return round(min(max(value, low), high), 6)
