"""A few mesh vertices posed on their own: what a silhouette-like term reads in the fit.

Posing the whole mesh for each of the solver's ``86 × B`` copies costs ~50× the keypoints;
a term that needs only a few hundred surface points (the silhouette's outline) gets them from a
body model of those vertices alone (:func:`vertex_subset_model`): the same template, blend
shapes, pose correctives, skinning weights and joints, so the points are exactly the full
mesh's vertices at a small fraction of the cost. :func:`farthest_point_indices` picks points
spread evenly over a surface.
"""

from __future__ import annotations

import numpy as np
import torch

from hkpd.body import BodyAsset, BodyModel


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
