"""Per-vertex uncertainty of a predicted body: how far sampled meshes spread around their mean.

The paper's supplementary material colours each vertex by the mean Euclidean distance of 100
sampled meshes' vertex from the sample-mean vertex; :func:`vertex_uncertainty` computes that.
"""

from __future__ import annotations

import torch


def vertex_uncertainty(vertices: torch.Tensor) -> torch.Tensor:
    """Mean distance of each vertex's samples from their mean: ``mean_n |v_n - mean_m v_m|``.

    Args:
        vertices: ``(..., N, V, 3)`` N sampled meshes (for example 100 from the predicted
            distribution) of V vertices, metres; leading dimensions are batch dimensions.

    Returns:
        ``(..., V)`` uncertainty per vertex, metres (0 where all samples agree).
    """
    if vertices.dim() < 3 or vertices.shape[-1] != 3:
        raise ValueError(
            f"vertices must have shape (..., N, V, 3) (N samples of V vertices), "
            f"got {tuple(vertices.shape)}"
        )
    if vertices.shape[-3] == 0:
        raise ValueError("vertex_uncertainty needs at least one sample (N >= 1)")
    mean = vertices.mean(dim=-3, keepdim=True)
    return torch.linalg.vector_norm(vertices - mean, dim=-1).mean(dim=-2)
