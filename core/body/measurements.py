"""Body measurements of a shape: height, mass, chest, waist and hip girths, shoulder width.

Every measurement is taken on the rest (T-pose) body of shape ``betas``, so it does not depend
on the pose, and is a smooth function of ``betas`` (linear for height and shoulder width,
nearly so for the girths, cubic for mass), which lets a Gaussian over ``betas`` give each one a
mean and a standard deviation by linearisation, and a stated value condition the Gaussian
(:mod:`hkpd.stated_body`). Where each is taken (``docs/shape.md``, "Measurements"):

- ``height_m``: the highest vertex of the head minus the lowest of the soles, the two vertices
  chosen on the mean body (metres).
- ``mass_kg``: the volume enclosed by the mesh times :data:`BODY_DENSITY_KG_PER_M3`.
- ``chest_m``, ``waist_m``, ``hip_m``: a tape around the torso, i.e. the perimeter of the
  convex hull of the body's horizontal cross-section (arms left out). The heights are chosen on
  the mean body between joints: the chest the fullest section from 15 to 2 cm under the
  armpits (the lowest upper-arm vertex), the waist the narrowest between ``spine1`` and
  ``spine3``, the hip the fullest between 15 cm under and 5 cm over the ``pelvis`` joint
  (thighs included). The hull's points are fixed points on mesh edges, so a new shape moves
  them with the surface.
- ``shoulder_width_m``: the distance between the two shoulder joints (the centres of the
  shoulder balls, a few centimetres inside a tape's biacromial breadth).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
import torch

from hkpd.stated_body import MEASUREMENT_NAMES

BODY_DENSITY_KG_PER_M3 = 980.0
"""Whole-body density used for mass: Anny's own (``anny.anthropometry``), which its
WHO-calibrated weights were matched with; measured human densities span about 940-1080."""

_TORSO_PARTS = ("pelvis", "spine1", "spine2", "spine3", "neck", "left_collar", "right_collar")
_HIP_PARTS = ("pelvis", "left_hip", "right_hip", "spine1")
_SCAN_STEPS = 41


@dataclass(frozen=True)
class GirthLoop:
    """A closed tape on the mesh: ``P`` points, each on a fixed edge ``(a, b)`` at fraction
    ``t`` from ``a``, in hull order.

    Attributes:
        start: ``(P,)`` long vertex indices; end: ``(P,)``; fraction: ``(P,)`` float64.
        height: the plane's height on the mean body (metres).
    """

    start: torch.Tensor
    end: torch.Tensor
    fraction: torch.Tensor
    height: float

    def perimeter(self, vertices: torch.Tensor) -> torch.Tensor:
        """``(N,)`` length of the loop on ``(N, V, 3)`` rest vertices (metres)."""
        t = self.fraction.to(vertices.dtype)[:, None]
        points = vertices[:, self.start] * (1 - t) + vertices[:, self.end] * t
        return (points - points.roll(1, dims=1)).norm(dim=-1).sum(-1)

    def perimeter_jacobian(self, vertices: torch.Tensor, shapedirs: torch.Tensor) -> torch.Tensor:
        """``(K,)`` derivative of the loop's length on ``(V, 3)`` rest vertices along each shape
        direction of ``shapedirs`` ``(V, 3, K)`` (rest vertices are linear in the betas)."""
        t = self.fraction.to(vertices.dtype)[:, None]
        points = vertices[self.start] * (1 - t) + vertices[self.end] * t  # (L, 3)
        moves = shapedirs[self.start] * (1 - t)[..., None] + shapedirs[self.end] * t[..., None]
        sides = points - points.roll(1, dims=0)
        units = sides / sides.norm(dim=-1, keepdim=True)
        return torch.einsum("lc,lck->k", units, moves - moves.roll(1, dims=0))


class BodyMeasurer:
    """The six measurements of any shape of one body model.

    Args:
        body: a :class:`hkpd.body.BodyModel` (any dtype; the measurer works in float64 on the
            CPU). Its part names must include SMPL's torso and hip parts.
    """

    def __init__(self, body: torch.nn.Module) -> None:
        self.v_template = body.v_template.detach().double().cpu()
        self.shapedirs = body.shapedirs.detach().double().cpu()
        self.joint_template = body.joint_template.detach().double().cpu()
        self.joint_shapedirs = body.joint_shapedirs.detach().double().cpu()
        self.faces = body.faces.detach().cpu()
        names = list(body.joint_names)
        self.shoulders = (names.index("left_shoulder"), names.index("right_shoulder"))
        heights = self.v_template[:, 1]
        self.top, self.bottom = int(heights.argmax()), int(heights.argmin())
        labels = body.part_labels.detach().cpu()
        part_names = list(body.part_names)
        joints = {name: float(self.joint_template[names.index(name), 1]) for name in names}
        torso = _vertex_set(labels, part_names, _TORSO_PARTS)
        hips = _vertex_set(labels, part_names, _HIP_PARTS)
        armpit = _armpit_height(self.v_template, labels, part_names)
        self.loops = {
            "chest_m": self._girth(torso, armpit - 0.15, armpit - 0.02, fullest=True),
            "waist_m": self._girth(torso, joints["spine1"], joints["spine3"], fullest=False),
            "hip_m": self._girth(hips, joints["pelvis"] - 0.15, joints["pelvis"] + 0.05, True),
        }

    def _girth(self, allowed: torch.Tensor, low: float, high: float, fullest: bool) -> GirthLoop:
        """The fullest (or narrowest) horizontal tape of the mean body between two heights."""
        candidates = [
            _hull_loop(self.v_template, self.faces, allowed, float(height))
            for height in np.linspace(low, high, _SCAN_STEPS)
        ]
        candidates = [loop for loop in candidates if loop is not None]
        if not candidates:
            raise ValueError(
                f"no cross-section of the body between heights {low:.3f} and {high:.3f}"
            )
        template = self.v_template[None]
        lengths = [float(loop.perimeter(template)) for loop in candidates]
        return candidates[int(np.argmax(lengths) if fullest else np.argmin(lengths))]

    def rest_vertices(self, betas: torch.Tensor) -> torch.Tensor:
        """``(N, V, 3)`` rest vertices of ``(N, K)`` betas (float64, metres)."""
        betas = betas.double()
        return self.v_template + torch.einsum("vck,nk->nvc", self.shapedirs, betas)

    def __call__(self, betas: torch.Tensor) -> torch.Tensor:
        """``(N, 6)`` measurements of ``(N, K)`` shapes, columns :data:`MEASUREMENT_NAMES`
        (metres, and kilograms for mass), float64."""
        betas = torch.as_tensor(betas).double().cpu()
        vertices = self.rest_vertices(betas)
        joints = self.joint_template + torch.einsum("jck,nk->njc", self.joint_shapedirs, betas)
        height = vertices[:, self.top, 1] - vertices[:, self.bottom, 1]
        corners = vertices[:, self.faces]  # (N, F, 3, 3)
        volume = (torch.linalg.cross(corners[:, :, 0], corners[:, :, 1]) * corners[:, :, 2]).sum(
            (-1, -2)
        ) / 6.0
        left, right = self.shoulders
        columns = {
            "height_m": height,
            "mass_kg": volume.abs() * BODY_DENSITY_KG_PER_M3,
            **{name: loop.perimeter(vertices) for name, loop in self.loops.items()},
            "shoulder_width_m": (joints[:, left] - joints[:, right]).norm(dim=-1),
        }
        return torch.stack([columns[name] for name in MEASUREMENT_NAMES], dim=-1)

    def jacobian(self, betas: torch.Tensor) -> torch.Tensor:
        """``(6, K)`` derivatives of the measurements at one shape ``betas`` ``(K,)``, in closed
        form: rest vertices and joints are linear in the betas, so each measurement's
        derivative is its derivative in the vertices along the shape directions (equal to
        reverse-mode autodiff to ~1e-12, ~10× faster: the explorer measures both sexes after
        every occluder edit, issue 58)."""
        point = torch.as_tensor(betas).double().cpu()
        vertices = self.rest_vertices(point[None])[0]
        joints = self.joint_template + torch.einsum("jck,k->jc", self.joint_shapedirs, point)
        dirs = self.shapedirs
        height = dirs[self.top, 1] - dirs[self.bottom, 1]
        corners = vertices[self.faces]  # (F, 3, 3)
        by_vertex = torch.zeros_like(vertices)  # d volume / d vertex: Σ (c0 × c1) · c2 / 6
        for corner in range(3):
            after, before = corners[:, (corner + 1) % 3], corners[:, (corner + 2) % 3]
            by_vertex.index_add_(0, self.faces[:, corner], torch.linalg.cross(after, before))
        volume_gradient = torch.einsum("vc,vck->k", by_vertex, dirs) / 6.0
        volume = (torch.linalg.cross(corners[:, 0], corners[:, 1]) * corners[:, 2]).sum() / 6.0
        left, right = self.shoulders
        across = joints[left] - joints[right]
        joint_moves = self.joint_shapedirs[left] - self.joint_shapedirs[right]
        rows = {
            "height_m": height,
            "mass_kg": torch.sign(volume) * volume_gradient * BODY_DENSITY_KG_PER_M3,
            **{name: loop.perimeter_jacobian(vertices, dirs) for name, loop in self.loops.items()},
            "shoulder_width_m": (across / across.norm()) @ joint_moves,
        }
        return torch.stack([rows[name] for name in MEASUREMENT_NAMES])

    def gaussian(
        self, mean: torch.Tensor, covariance: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Means ``(6,)`` and standard deviations ``(6,)`` of the measurements of
        ``betas ~ N(mean (K,), covariance (K, K))``, linearised at the mean."""
        mean = torch.as_tensor(mean).double().cpu()
        covariance = torch.as_tensor(covariance).double().cpu()
        jacobian = self.jacobian(mean)
        variance = torch.einsum("mk,kl,ml->m", jacobian, covariance, jacobian)
        return self(mean[None])[0], variance.clamp_min(0.0).sqrt()


def _vertex_set(
    labels: torch.Tensor, part_names: list[str], parts: tuple[str, ...]
) -> torch.Tensor:
    """``(V,)`` bool: the vertices labelled with one of ``parts``."""
    missing = [part for part in parts if part not in part_names]
    if missing:
        raise ValueError(f"the body model has no part(s) {missing}; measurements need SMPL's parts")
    wanted = torch.tensor([part_names.index(part) for part in parts])
    return torch.isin(labels, wanted)


def _armpit_height(vertices: torch.Tensor, labels: torch.Tensor, part_names: list[str]) -> float:
    """The lowest point of the upper arms' vertices (the armpits in a T-pose), metres."""
    arms = _vertex_set(labels, part_names, ("left_shoulder", "right_shoulder"))
    return float(vertices[arms, 1].min())


def _hull_loop(
    vertices: torch.Tensor, faces: torch.Tensor, allowed: torch.Tensor, height: float
) -> GirthLoop | None:
    """The convex hull of the plane ``y = height``'s cut through the faces whose three vertices
    are all ``allowed``, as points on fixed edges (None when the plane misses them)."""
    kept = faces[allowed[faces].all(1)]
    edges = torch.cat((kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]))
    y = vertices[:, 1]
    below, above = y[edges[:, 0]] - height, y[edges[:, 1]] - height
    crossing = (below * above) < 0
    if int(crossing.sum()) < 3:
        return None
    edges = edges[crossing]
    fraction = below[crossing] / (below[crossing] - above[crossing])
    points = (
        vertices[edges[:, 0]] * (1 - fraction[:, None]) + vertices[edges[:, 1]] * fraction[:, None]
    )
    order = _convex_hull(points[:, [0, 2]].numpy())
    if len(order) < 3:
        return None
    index = torch.as_tensor(order)
    return GirthLoop(edges[index, 0], edges[index, 1], fraction[index], height)


def _convex_hull(points: np.ndarray) -> list[int]:
    """Indices of the 2D convex hull of ``(P, 2)`` points, counter-clockwise (monotone chain)."""
    order = sorted(range(len(points)), key=lambda i: (points[i, 0], points[i, 1]))

    def turn(o: int, a: int, b: int) -> float:
        (ox, oy), (ax, ay), (bx, by) = points[o], points[a], points[b]
        return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox)

    def chain(indices: list[int]) -> list[int]:
        hull: list[int] = []
        for index in indices:
            while len(hull) >= 2 and turn(hull[-2], hull[-1], index) <= 0:
                hull.pop()
            hull.append(index)
        return hull

    lower, upper = chain(order), chain(order[::-1])
    return lower[:-1] + upper[:-1]


_MEASURERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def body_measurer(body: torch.nn.Module) -> BodyMeasurer:
    """The :class:`BodyMeasurer` of ``body``, made once per body model (about 0.7 s)."""
    measurer = _MEASURERS.get(body)
    if measurer is None:
        measurer = _MEASURERS[body] = BodyMeasurer(body)
    return measurer
