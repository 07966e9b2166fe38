"""Hand and foot landmarks on the body model: BlazePose's knuckles, heels and toes, and
COCO-WholeBody's six foot points, as small vertex regressors chosen on the rest mesh.

BlazePose returns 33 landmarks; besides the 17 COCO keypoints it has three on each hand
(17-22: pinky and index knuckles, thumb) and two on each foot (29-32: heel, foot index, the
tip of the longest toes). COCO-WholeBody adds six foot points (big toe, small toe, heel of
each foot). Each landmark here is the mean of a few rest-mesh vertices (a regressor with
equal weights), chosen once per body model from its rest geometry, part labels and joints
(:func:`extremity_landmarks`; deterministic, about a millisecond), so no asset is rebuilt. Each
rule picks a set of vertices; the landmark averages the :data:`MAX_VERTICES` of them nearest
the set's centroid (cheap to pose in the fit):

- The rest pose has y up, the body facing +z, its left side at +x; arms out along ±x, palms
  down, thumbs forward. Rules are written for the left side and applied to the right side's
  parts with x negated.
- **Pinky / index knuckle**: the fingers' vertices (part ``*_hand``) in a 2 cm slab across
  the hand just beyond the finger-base joint (``*_hand`` joint; the thumb lies before it);
  the pinky is the slab's backmost 1.5 cm
  (least z), the index finger its frontmost 1.5 cm. The mean of both surfaces lies inside the
  finger's base, as a knuckle detector's point does.
- **Thumb**: the fingers part's frontmost 2 cm (the thumb points forward): its distal half.
- **Heel**: foot vertices (parts ``*_ankle`` and ``*_foot``) within 4 cm of the sole, and of
  those the backmost centimetre.
- **Foot index** (BlazePose's toe): the toes part (``*_foot``) frontmost centimetre.
- **Big toe / small toe** (WholeBody): the frontmost centimetre of the toes' medial third /
  lateral fifth (medial: towards the body's midline).
- **WholeBody heel**: BlazePose's heel regressor.

``docs/body_model.md`` ("Hand and foot landmarks") has the table; ``tests/test_extremity_
landmarks.py`` checks that they sit where they should.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import torch

from hkpd.body.body_model import BodyModel

BLAZEPOSE_EXTREMITY_NAMES = (
    "left_pinky",
    "right_pinky",
    "left_index",
    "right_index",
    "left_thumb",
    "right_thumb",
    "left_heel",
    "right_heel",
    "left_foot_index",
    "right_foot_index",
)
"""BlazePose's hand and foot landmarks, in BlazePose's order (landmarks 17-22, 29-32)."""

BLAZEPOSE_EXTREMITY_INDICES = (17, 18, 19, 20, 21, 22, 29, 30, 31, 32)
"""BlazePose landmark index of each of :data:`BLAZEPOSE_EXTREMITY_NAMES`."""

EXTREMITY_MIRROR = (1, 0, 3, 2, 5, 4, 7, 6, 9, 8)
"""Index of each extremity landmark's left/right counterpart (mirror images swap them)."""

WHOLEBODY_FOOT_NAMES = (
    "left_big_toe",
    "left_small_toe",
    "left_heel",
    "right_big_toe",
    "right_small_toe",
    "right_heel",
)
"""COCO-WholeBody's six foot points (its keypoints 17-22), in its order."""

LANDMARK_NAMES = BLAZEPOSE_EXTREMITY_NAMES + WHOLEBODY_FOOT_NAMES
"""All landmarks of :class:`ExtremityLandmarks`: the 10 BlazePose ones, then the 6 foot points."""

NUM_EXTREMITY = len(BLAZEPOSE_EXTREMITY_NAMES)
NUM_FOOT = len(WHOLEBODY_FOOT_NAMES)

_SLAB = 0.01  # half-width of the knuckle slab, metres
_KNUCKLE_BAND = 0.015
_THUMB_BAND = 0.02
_SOLE_BAND = 0.04
_TIP_BAND = 0.01
MAX_VERTICES = 8
"""Each landmark averages at most this many vertices: those of its rule's set nearest the set's
centroid (the fit poses every vertex a landmark reads for each of its ~86 × B states)."""


@dataclass(frozen=True)
class ExtremityLandmarks:
    """The landmarks as a sparse regressor on a body model's vertices.

    Attributes:
        vertex_indices: ``(P,)`` long, the mesh vertices the landmarks read (sorted, unique).
        weights: ``(L, P)`` float64, each row sums to 1: landmark ``l`` is
            ``weights[l] @ vertices[vertex_indices]``. ``L = 16``, :data:`LANDMARK_NAMES` order.
    """

    vertex_indices: torch.Tensor
    weights: torch.Tensor

    def of_subset(self, subset_vertices: torch.Tensor) -> torch.Tensor:
        """``(..., P, 3)`` the posed :attr:`vertex_indices` -> ``(..., L, 3)`` landmarks."""
        weights = self.weights.to(dtype=subset_vertices.dtype, device=subset_vertices.device)
        return torch.einsum("lp,...pc->...lc", weights, subset_vertices)

    def of_mesh(self, vertices: torch.Tensor) -> torch.Tensor:
        """``(..., V, 3)`` whole meshes -> ``(..., L, 3)`` landmarks."""
        index = self.vertex_indices.to(vertices.device)
        return self.of_subset(vertices.index_select(-2, index))

    def rows(self, names: tuple[str, ...]) -> ExtremityLandmarks:
        """The regressor of ``names`` alone (rows of :data:`LANDMARK_NAMES`), on the vertices
        those rows read."""
        unknown = [name for name in names if name not in LANDMARK_NAMES]
        if unknown:
            raise ValueError(f"unknown landmark names {unknown}; known: {LANDMARK_NAMES}")
        weights = self.weights[[LANDMARK_NAMES.index(name) for name in names]]
        used = (weights != 0).any(0)
        return ExtremityLandmarks(self.vertex_indices[used], weights[:, used])


_CACHE: weakref.WeakKeyDictionary[BodyModel, ExtremityLandmarks] = weakref.WeakKeyDictionary()


def extremity_landmarks(body: BodyModel) -> ExtremityLandmarks:
    """The 16 landmarks of ``body`` (:data:`LANDMARK_NAMES`), chosen on its rest mesh by the
    rules of the module docstring; cached per model object.

    Raises:
        ValueError: the model lacks the SMPL part labels the rules read (``left_hand``, …).
    """
    cached = _CACHE.get(body)
    if cached is None:
        cached = _choose(body)
        _CACHE[body] = cached
    return cached


def _choose(body: BodyModel) -> ExtremityLandmarks:
    """Apply the rules to both sides and gather the vertex sets into one regressor."""
    needed = ("left_hand", "right_hand", "left_ankle", "right_ankle", "left_foot", "right_foot")
    missing = [name for name in needed if name not in body.part_names]
    if missing:
        raise ValueError(f"the body model has no part labels {missing}; hand and foot landmarks "
                         "need SMPL's part labels (the shipped model has them)")  # fmt: skip
    vertices = body.v_template.detach().to("cpu", torch.float64)
    joints = body.joint_template.detach().to("cpu", torch.float64)
    labels = body.part_labels.detach().cpu()
    sets: dict[str, torch.Tensor] = {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        flipped = vertices * torch.tensor([sign, 1.0, 1.0], dtype=torch.float64)
        hand_joint = float(joints[body.joint_names.index(f"{side}_hand"), 0]) * sign

        def part(name: str, side: str = side) -> torch.Tensor:
            return torch.nonzero(labels == body.part_names.index(f"{side}_{name}"))[:, 0]

        sets.update(_hand_sets(side, flipped, part("hand"), hand_joint))
        sets.update(_foot_sets(side, flipped, part("ankle"), part("foot")))
    sets = {name: _nearest_centre(vertices, chosen) for name, chosen in sets.items()}
    for side in ("left", "right"):
        sets[f"{side}_heel_wholebody"] = sets[f"{side}_heel"]
    order = [*BLAZEPOSE_EXTREMITY_NAMES] + [
        f"{name}_wholebody" if name.endswith("heel") else name for name in WHOLEBODY_FOOT_NAMES
    ]
    used = torch.unique(torch.cat([sets[name] for name in order]))
    weights = torch.zeros(len(order), used.numel(), dtype=torch.float64)
    for row, name in enumerate(order):
        columns = torch.searchsorted(used, sets[name])
        weights[row, columns] = 1.0 / sets[name].numel()
    return ExtremityLandmarks(used, weights)


def _nearest_centre(vertices: torch.Tensor, chosen: torch.Tensor) -> torch.Tensor:
    """The :data:`MAX_VERTICES` of ``chosen`` nearest their centroid (all when fewer), sorted."""
    if chosen.numel() <= MAX_VERTICES:
        return chosen
    points = vertices[chosen]
    distance = (points - points.mean(0)).norm(dim=-1)
    return torch.sort(chosen[torch.argsort(distance)[:MAX_VERTICES]]).values


def _band(values: torch.Tensor, indices: torch.Tensor, width: float, top: bool) -> torch.Tensor:
    """``indices`` whose ``values`` lie within ``width`` of their max (``top``) or min."""
    if indices.numel() == 0:
        raise ValueError("a landmark rule found no vertices; is this an SMPL-format body?")
    picked = values[indices]
    edge = picked.max() if top else picked.min()
    keep = (picked >= edge - width) if top else (picked <= edge + width)
    return indices[keep]


def _hand_sets(
    side: str, vertices: torch.Tensor, fingers: torch.Tensor, hand_joint_x: float
) -> dict[str, torch.Tensor]:
    """Pinky and index knuckles and thumb of one hand (``vertices`` as the left side)."""
    offset = vertices[fingers, 0] - hand_joint_x
    slab = fingers[(offset >= 0) & (offset <= 2 * _SLAB)]  # the fingers' side: no thumb
    z = vertices[:, 2]
    return {
        f"{side}_pinky": _band(z, slab, _KNUCKLE_BAND, top=False),
        f"{side}_index": _band(z, slab, _KNUCKLE_BAND, top=True),
        f"{side}_thumb": _band(z, fingers, _THUMB_BAND, top=True),
    }


def _foot_sets(
    side: str, vertices: torch.Tensor, ankle: torch.Tensor, toes: torch.Tensor
) -> dict[str, torch.Tensor]:
    """Heel, foot index, big and small toe of one foot (``vertices`` as the left side)."""
    x, y, z = vertices.unbind(-1)
    foot = torch.cat((ankle, toes))
    sole = _band(y, foot, _SOLE_BAND, top=False)
    toe_x = x[toes]
    low, high = float(toe_x.min()), float(toe_x.max())
    medial = toes[toe_x <= low + (high - low) / 3]
    lateral = toes[toe_x >= high - (high - low) / 5]
    return {
        f"{side}_heel": _band(z, sole, _TIP_BAND, top=False),
        f"{side}_foot_index": _band(z, toes, _TIP_BAND, top=True),
        f"{side}_big_toe": _band(z, medial, _TIP_BAND, top=True),
        f"{side}_small_toe": _band(z, lateral, _TIP_BAND, top=True),
    }
