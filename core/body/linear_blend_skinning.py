"""Posing math of an SMPL-format body: forward kinematics and linear blend skinning.

All functions are pure, batched and differentiable, and run on any device in float32 or float64.
Lengths are in metres.

Skinning strategy (measured)
----------------------------
Per vertex ``i``, LBS blends the joints' 3×4 transforms with its weights, ``T_i = Σ_j w_ij A_j``,
and applies ``T_i`` to the rest vertex. Vertices have at most 7 non-zero weights (most 1-3).
Candidates were timed on the development VM (2 vCPUs, AMD EPYC with AVX-512, torch 2.13 CPU,
2 threads), computing rest vertices (10 shape coefficients) plus skinning for B = 100 bodies
of the shipped mesh (13,492 vertices), float32, no autograd; best and median over 3 rounds of
the median of 20 calls (the VM's timings drift by up to 2x):

==========================================================================  =========  ======
candidate                                                                    best ms   median
==========================================================================  =========  ======
dense, vertex-major: ``W @ A`` to ``(B, V, 3, 4)``, then apply                  53.6      55.3
vertex-major, in chunks of 512 vertices                                         27.9      28.0
sparse top-k: gather each vertex's ≤ 7 transforms, grouped by joint count       98.5     119.2
block-sparse: vertices grouped by dominant joint, local joint sets              43.2      48.2
coordinate-major ``(B, 3, V)``, dense                                           55.2      58.3
coordinate-major, in chunks of 4 bodies                                         17.7      19.1
coordinate-major, chunks of 512 vertices, all 24 joints                         14.8      15.6
coordinate-major, chunks of 512 vertices, each chunk's own joints (**used**)    12.9      14.3
  the same with chunks of 256 / 1,024 vertices                              15.4 / 15.5
==========================================================================  =========  ======

The big intermediates are slow because each call streams tens of MB of freshly allocated memory
(page faults included); the gathers cost more than the FLOPs they save. What wins is
*coordinate-major chunks of consecutive vertices*: the vertex index is the fastest axis, so every
element-wise step is a contiguous vector operation, and a chunk's ``(B, 12, n)`` blended
transforms stay in cache. Each chunk multiplies only by the joints that influence it
(consecutive vertices of a mesh belong to few body parts: 5.7 joints per 512-vertex chunk on
the shipped mesh instead of 24), and the blend shapes are added inside the same chunk, so the
rest vertices are never materialised in full. The best chunk size shrinks as the batch grows
(about 512 vertices at B = 100, 4,096 at B = 10, the whole mesh at B = 1): see
:func:`chunk_size_for`. Other devices get one chunk (a GPU wants large kernels).
:func:`blend_and_skin` implements this; ``benchmarks/bench_body_model.py`` times the whole
forward pass.

Keypoints (a linear regressor applied to the posed vertices) are not read off the vertices:
regression and skinning are both linear, so the regressor is folded through the skinning
weights and blend shapes once (:func:`fold_readout_through_skinning`), and each call then costs
a ``(B, D) @ (D, 17·24·4)`` product and a ``(17, 96) @ (96, 3)`` product per body. Reading the
keypoints off each chunk's vertices instead cost 3-4 ms at B = 100.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import torch

from hkpd.kinematic_tree import compose_global_rotations, validate_parents


@lru_cache(maxsize=16)
def _ancestor_rows(parents: tuple[int, ...]) -> tuple[tuple[int, ...], ...]:
    """For each joint, the joints on its chain to the root frame, itself included."""
    rows = []
    for joint in range(len(parents)):
        chain = [joint]
        while parents[chain[-1]] != -1:
            chain.append(parents[chain[-1]])
        rows.append(tuple(chain))
    return tuple(rows)


def ancestor_matrix(
    parents: Sequence[int], dtype: torch.dtype = torch.float32, device: torch.device | None = None
) -> torch.Tensor:
    """``(J, J)`` matrix ``M`` with ``M[j, k] = 1`` when joint k is j or one of j's ancestors.

    Summing per-joint quantities down the tree is one product: ``M @ x`` adds to every joint
    the values of all joints on its path to the root frame.
    """
    checked = validate_parents(parents)
    matrix = torch.zeros(len(checked), len(checked), dtype=dtype, device=device)
    for joint, chain in enumerate(_ancestor_rows(checked)):
        matrix[joint, list(chain)] = 1.0
    return matrix


def forward_kinematics(
    rest_joints: torch.Tensor,
    rotations: torch.Tensor,
    parents: Sequence[int],
    ancestors: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Global joint rotations and posed joint locations from rest joints and relative rotations.

    Every joint turns its subtree about its own rest location: ``G_j = G_parent(j) R_j`` and
    ``p_j = p_parent(j) + G_parent(j) (J_j - J_parent(j))``. A joint whose parent is -1 (the root)
    turns about itself: ``G_j = R_j``, ``p_j = J_j``. Rotations are composed per tree depth
    (:func:`hkpd.kinematic_tree.compose_global_rotations`); the locations are then one product
    with the :func:`ancestor_matrix`.

    Args:
        rest_joints: ``(..., J, 3)`` rest (T-pose) joint locations, metres.
        rotations: ``(..., J, 3, 3)`` rotation of each joint relative to its parent's frame;
            for the root this is the global orientation.
        parents: length-J parents, -1 for the root, parents before children.
        ancestors: optional precomputed ``ancestor_matrix(parents)`` (same dtype and device).

    Returns:
        ``(global_rotations (..., J, 3, 3), posed_joints (..., J, 3))``, metres.
    """
    checked = validate_parents(parents)
    joints = len(checked)
    if rest_joints.shape[-2:] != (joints, 3) or rotations.shape[-3:] != (joints, 3, 3):
        raise ValueError(
            f"expected rest_joints (..., {joints}, 3) and rotations (..., {joints}, 3, 3), got "
            f"{tuple(rest_joints.shape)} and {tuple(rotations.shape)}"
        )
    global_rotations = compose_global_rotations(rotations, checked)
    batch = torch.broadcast_shapes(rest_joints.shape[:-2], rotations.shape[:-3])
    rest_joints = rest_joints.expand(*batch, joints, 3)
    parent_index = [max(parent, 0) for parent in checked]
    is_root = torch.tensor([parent == -1 for parent in checked], device=rest_joints.device)
    # Offset of each joint from its parent (the root: from the origin, left unrotated).
    offsets = rest_joints - torch.where(
        is_root[:, None], torch.zeros_like(rest_joints), rest_joints[..., parent_index, :]
    )
    parent_rotations = global_rotations[..., parent_index, :, :]
    rotated = torch.where(
        is_root[:, None], offsets, (parent_rotations @ offsets.unsqueeze(-1)).squeeze(-1)
    )
    if ancestors is None:
        ancestors = ancestor_matrix(checked, rest_joints.dtype, rest_joints.device)
    return global_rotations, ancestors @ rotated


def skinning_transforms(
    global_rotations: torch.Tensor,
    posed_joints: torch.Tensor,
    rest_joints: torch.Tensor,
    translation: torch.Tensor | None = None,
) -> torch.Tensor:
    """Per-joint 3×4 transforms that carry rest-pose points to the posed body.

    ``A_j x = G_j (x - J_j) + p_j + translation``.

    Args:
        global_rotations: ``(..., J, 3, 3)``.
        posed_joints: ``(..., J, 3)`` metres.
        rest_joints: ``(..., J, 3)`` metres.
        translation: optional ``(..., 3)`` metres, added to every point.

    Returns:
        ``(..., J, 3, 4)``: rotation in ``[..., :3]``, translation in ``[..., 3]``.
    """
    offset = posed_joints - (global_rotations @ rest_joints.unsqueeze(-1)).squeeze(-1)
    if translation is not None:
        offset = offset + translation.unsqueeze(-2)
    return torch.cat((global_rotations, offset.unsqueeze(-1)), dim=-1)


def linear_blend_skinning(
    rest_vertices: torch.Tensor, transforms: torch.Tensor, weights: torch.Tensor
) -> torch.Tensor:
    """Plain dense LBS: ``v'_i = (Σ_j w_ij A_j) [v_i; 1]``.

    Simple and general (any batch shape); :func:`blend_and_skin` is the fast path for a fixed
    mesh.

    Args:
        rest_vertices: ``(..., V, 3)`` rest vertices, metres.
        transforms: ``(..., J, 3, 4)`` from :func:`skinning_transforms`.
        weights: ``(V, J)`` skinning weights, rows summing to 1.

    Returns:
        ``(..., V, 3)`` posed vertices, metres.
    """
    blended = (weights @ transforms.flatten(-2)).unflatten(-1, (3, 4))  # (..., V, 3, 4)
    return (blended[..., :3] @ rest_vertices.unsqueeze(-1)).squeeze(-1) + blended[..., 3]


@dataclass(frozen=True)
class VertexChunks:
    """Consecutive vertex ranges, each with the joints that influence it.

    Attributes:
        starts, ends: chunk ``c`` is vertices ``starts[c]:ends[c]`` (Python ints).
        joints: per chunk, ``(u,)`` long: the joints with a non-zero weight on the chunk.
        weights: per chunk, ``(u, n)``: those joints' weights on the chunk's ``n`` vertices,
            renormalised so every vertex's weights sum to 1 in the working dtype.
    """

    starts: tuple[int, ...]
    ends: tuple[int, ...]
    joints: tuple[torch.Tensor, ...]
    weights: tuple[torch.Tensor, ...]

    @property
    def num_vertices(self) -> int:
        """V."""
        return self.ends[-1] if self.ends else 0


def chunk_vertices(weights: torch.Tensor, chunk_size: int) -> VertexChunks:
    """Cut a mesh into chunks of ``chunk_size`` consecutive vertices for :func:`blend_and_skin`.

    Args:
        weights: ``(V, J)`` skinning weights (non-negative; rows are renormalised to sum to 1).
        chunk_size: vertices per chunk (the last chunk may be shorter).

    Returns:
        The chunks, on ``weights``' device and dtype.
    """
    if chunk_size < 1:
        raise ValueError(f"chunk_size must be positive, got {chunk_size}")
    vertices = weights.shape[0]
    normalised = weights / weights.sum(dim=1, keepdim=True)
    starts = tuple(range(0, vertices, chunk_size))
    ends = tuple(min(start + chunk_size, vertices) for start in starts)
    joints, chunk_weights = [], []
    for start, end in zip(starts, ends, strict=True):
        block = normalised[start:end]
        used = (block != 0).any(dim=0).nonzero().squeeze(1)
        joints.append(used)
        chunk_weights.append(block[:, used].T.contiguous())
    return VertexChunks(starts, ends, tuple(joints), tuple(chunk_weights))


CHUNK_ELEMENTS = 49_152
"""Target ``batch × vertices`` per chunk on the CPU: a chunk's ``(B, 12, n)`` blended transforms
then take about 2 MB, the size of a core's L2 cache (measured: 384-512 vertices best at B = 100,
4,096 at B = 10, the whole mesh at B = 1)."""


def chunk_size_for(batch: int, num_vertices: int, device: torch.device) -> int:
    """Vertices per chunk for a batch of ``batch`` bodies: cache-sized on the CPU, all elsewhere.

    On the CPU this is :data:`CHUNK_ELEMENTS` / ``batch`` rounded to a power of two (so only a
    few chunkings are ever built), at least 256.
    """
    if device.type != "cpu":
        return max(num_vertices, 1)
    ideal = CHUNK_ELEMENTS / max(batch, 1)
    size = max(256, 2 ** round(math.log2(ideal)))
    return min(size, max(num_vertices, 1))


def blend_and_skin(
    template: torch.Tensor,
    blend_shapes: torch.Tensor | None,
    coefficients: torch.Tensor | None,
    transforms: torch.Tensor,
    chunks: VertexChunks,
) -> torch.Tensor:
    """Blend shapes, then linear blend skinning, in one pass over cache-sized vertex chunks.

    Computes ``v'_i = (Σ_j w_ij A_j) [t_i + Σ_d c_d s_id; 1]`` for every vertex: the rest vertex
    from the template ``t`` and the blend shapes ``s`` weighted by ``coefficients``, skinned by
    the joint transforms ``A``. The mesh arrays are coordinate-major (the vertex is the last,
    contiguous axis), which keeps every step a contiguous vector operation; see the module
    docstring for the measurements behind this layout.

    Args:
        template: ``(3, V)`` rest vertices of the mean body, metres, coordinate-major.
        blend_shapes: ``(3, D, V)`` blend shapes (metres per unit coefficient), or None.
        coefficients: ``(B, D)`` blend-shape coefficients, or None (the template alone).
        transforms: ``(B, J, 3, 4)`` from :func:`skinning_transforms`.
        chunks: from :func:`chunk_vertices` (same device and dtype).

    Returns:
        ``(B, V, 3)`` posed vertices, metres.
    """
    batch, joints = transforms.shape[0], transforms.shape[1]
    vertices = template.shape[1]
    if chunks.num_vertices != vertices:
        raise ValueError(f"chunks cover {chunks.num_vertices} vertices, the mesh has {vertices}")
    # Rows ordered (body, column of the 3x4, row of the 3x4), so that a chunk's blended transforms
    # come out of one matrix product already coordinate-major: (B, 4, 3, n).
    rows = transforms.permute(0, 3, 2, 1).reshape(batch * 12, joints)
    use_blend = coefficients is not None and blend_shapes is not None and blend_shapes.shape[1] > 0
    if use_blend:
        per_coordinate = coefficients.expand(3, batch, coefficients.shape[1])
    # Without autograd, chunks are written straight into the output while in cache; with it,
    # they are concatenated (slice assignment would copy the whole gradient once per chunk).
    tracking = torch.is_grad_enabled() and any(
        tensor is not None and tensor.requires_grad
        for tensor in (template, blend_shapes, coefficients, transforms)
    )
    output = None if tracking else transforms.new_empty(batch, vertices, 3)
    posed_chunks = []
    for start, end, used, weights in zip(
        chunks.starts, chunks.ends, chunks.joints, chunks.weights, strict=True
    ):
        count = end - start
        if use_blend:  # (3, B, n)
            rest = torch.baddbmm(
                template[:, None, start:end], per_coordinate, blend_shapes[:, :, start:end]
            )
        else:
            rest = template[:, None, start:end].expand(3, batch, count)
        blended = (rows.index_select(1, used) @ weights).view(batch, 4, 3, count)
        posed = torch.addcmul(blended[:, 3], blended[:, 0], rest[0].unsqueeze(1))
        posed = posed.addcmul_(blended[:, 1], rest[1].unsqueeze(1))
        posed = posed.addcmul_(blended[:, 2], rest[2].unsqueeze(1))  # (B, 3, n)
        if output is None:
            posed_chunks.append(posed.transpose(1, 2))
        else:
            output[:, start:end] = posed.transpose(1, 2)
    if output is not None:
        return output
    if not posed_chunks:
        return transforms.new_zeros(batch, 0, 3)
    return torch.cat(posed_chunks, dim=1)


@dataclass(frozen=True)
class SkinnedReadout:
    """A linear readout of the posed vertices (such as ``keypoints = regressor @ vertices``)
    folded through the skinning, so that it needs no vertices at run time.

    Readout and skinning are both linear: ``Σ_i r_ki v'_i = Σ_j A_j H_kj`` with
    ``H_kj = Σ_i r_ki w_ij [t_i + S_i c; 1] = constant_kj + linear_kj c``, which depend only on
    the blend coefficients ``c``.

    Attributes:
        constant: ``(1, R * J * 4)`` the ``H_kj`` of the template.
        linear: ``(D, R * J * 4)`` their change per blend coefficient, or None.
        num_outputs: R.
    """

    constant: torch.Tensor
    linear: torch.Tensor | None
    num_outputs: int


def fold_readout_through_skinning(
    readout: torch.Tensor,
    template: torch.Tensor,
    blend_shapes: torch.Tensor | None,
    weights: torch.Tensor,
) -> SkinnedReadout:
    """Precompute :class:`SkinnedReadout` for a mesh.

    Args:
        readout: ``(R, V)`` the linear map from posed vertices (e.g. a keypoint regressor).
        template: ``(V, 3)`` rest vertices of the mean body, metres.
        blend_shapes: ``(V, 3, D)`` blend shapes, or None.
        weights: ``(V, J)`` skinning weights (rows renormalised to sum to 1, as
            :func:`chunk_vertices` does).

    Returns:
        The folded readout, on ``readout``'s device and dtype.
    """
    outputs = readout.shape[0]
    weights = weights / weights.sum(dim=1, keepdim=True)
    homogeneous = torch.cat((template, torch.ones_like(template[:, :1])), dim=1)  # (V, 4)
    per_vertex = readout.unsqueeze(-1) * weights  # (R, V, J)
    constant = torch.einsum("rvj,vc->rjc", per_vertex, homogeneous).reshape(1, -1)
    linear = None
    if blend_shapes is not None and blend_shapes.shape[-1] > 0:
        padded = torch.cat((blend_shapes, torch.zeros_like(blend_shapes[:, :1])), dim=1)
        linear = torch.einsum("rvj,vcd->drjc", per_vertex, padded).reshape(padded.shape[-1], -1)
    return SkinnedReadout(constant.contiguous(), linear, outputs)


def apply_skinned_readout(
    folded: SkinnedReadout, coefficients: torch.Tensor | None, transforms: torch.Tensor
) -> torch.Tensor:
    """The readout of the posed vertices, ``Σ_i r_ki v'_i``, without computing the vertices.

    Args:
        folded: from :func:`fold_readout_through_skinning`.
        coefficients: ``(B, D)`` blend-shape coefficients, or None (the template alone).
        transforms: ``(B, J, 3, 4)`` from :func:`skinning_transforms`.

    Returns:
        ``(B, R, 3)``, metres.
    """
    batch, joints = transforms.shape[0], transforms.shape[1]
    if coefficients is None or folded.linear is None:
        mixed = folded.constant.expand(batch, -1)
    else:
        mixed = torch.addmm(folded.constant, coefficients, folded.linear)
    mixed = mixed.view(batch, folded.num_outputs, joints * 4)
    columns = transforms.transpose(2, 3).reshape(batch, joints * 4, 3)
    return mixed @ columns
