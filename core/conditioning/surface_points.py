"""A few mesh vertices posed on their own: what a silhouette-like term reads in the fit.

Posing the whole mesh for each of the solver's ``86 × B`` copies costs ~50× the keypoints;
a term that needs only a few hundred surface points (the silhouette's outline) gets them from a
body model of those vertices alone (:func:`vertex_subset_model`): the same template, blend
shapes, pose correctives, skinning weights and joints, so the points are exactly the full
mesh's vertices at a small fraction of the cost. :class:`SurfaceSamples` are such points,
spread evenly over the mesh (:func:`farthest_point_indices`), each with two face neighbours for
its normal: chosen once per body model (0.2 s), shared by every photo's term.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from hkpd.body import BodyAsset, BodyModel

DEFAULT_SURFACE_POINTS = 400
"""Surface points a silhouette term projects (farthest-point samples of the mesh)."""


@dataclass(frozen=True)
class SurfaceSamples:
    """Mesh vertices spread evenly over a body model's surface, with a face each.

    Attributes:
        points: ``(P,)`` long vertex indices, farthest-point samples of the rest mesh.
        first, second: ``(P,)`` the two other corners of a face holding each point, in the
            face's order, so ``(first - point) × (second - point)`` is the face's outward normal
            (faces are counter-clockwise seen from outside).
    """

    points: torch.Tensor
    first: torch.Tensor
    second: torch.Tensor

    @classmethod
    def of(cls, body: BodyModel, count: int = DEFAULT_SURFACE_POINTS) -> SurfaceSamples:
        """``count`` samples of ``body``'s mesh (deterministic; make them once per model)."""
        points = farthest_point_indices(body.v_template.to(torch.float64), count)
        faces = body.faces
        hits = faces[None] == points[:, None, None]  # (P, F, 3)
        face = hits.any(-1).to(torch.int8).argmax(-1)  # the first face holding each point
        corner = hits[torch.arange(points.numel()), face].to(torch.int8).argmax(-1)
        rows = faces[face]
        first = rows.gather(1, ((corner + 1) % 3)[:, None])[:, 0]
        second = rows.gather(1, ((corner + 2) % 3)[:, None])[:, 0]
        return cls(points, first, second)

    @property
    def count(self) -> int:
        """P."""
        return int(self.points.numel())

    def vertex_indices(self) -> torch.Tensor:
        """``(3P,)`` the points, then their first and second neighbours: the vertices to pose."""
        return torch.cat((self.points, self.first, self.second))


def vertex_subset_model(body: BodyModel, vertex_indices: torch.Tensor) -> BodyModel:
    """A body model whose vertices are ``body``'s ``vertex_indices`` (no faces, no keypoint
    regressor), on ``body``'s device and dtype.

    Its joints are ``body``'s (joint template and shape directions are kept whole), so its
    posed vertices equal ``body(...).vertices[:, vertex_indices]`` (the asset stores float32,
    as the shipped model's arrays are).

    Args:
        body: the full model.
        vertex_indices: ``(P,)`` long, indices into ``body``'s vertices.
    """
    index = vertex_indices.detach().cpu().numpy()

    def rows(buffer: torch.Tensor | None) -> np.ndarray | None:
        return None if buffer is None else buffer.detach().cpu().numpy()[index]

    asset = BodyAsset(
        v_template=rows(body.v_template),
        faces=np.zeros((0, 3), dtype=np.int32),
        shapedirs=rows(body.shapedirs),
        joint_template=body.joint_template.detach().cpu().numpy(),
        joint_shapedirs=body.joint_shapedirs.detach().cpu().numpy(),
        skinning_weights=rows(body.skinning_weights),
        parents=np.asarray(body.parents),
        joint_names=body.joint_names,
        part_labels=rows(body.part_labels),
        part_names=body.part_names,
        posedirs=rows(body.posedirs),
        source="vertex subset of the fit's body model",
    )
    return BodyModel(asset).to(dtype=body.dtype, device=body.device)


def farthest_point_indices(points: torch.Tensor, count: int) -> torch.Tensor:
    """``(count,)`` long indices of ``points (M, D)`` chosen by farthest-point sampling from
    point 0: each next one is the farthest from those chosen (deterministic, evenly spread).
    All ``M`` indices when ``count >= M``."""
    total = points.shape[0]
    if count >= total:
        return torch.arange(total, device=points.device)
    chosen = torch.zeros(count, dtype=torch.long, device=points.device)
    nearest = (points - points[0]).square().sum(-1)
    for step in range(1, count):
        chosen[step] = int(nearest.argmax())
        nearest = torch.minimum(nearest, (points - points[chosen[step]]).square().sum(-1))
    return chosen
