"""A small synthetic SMPL-like body for tests: one tube of vertices per bone of a T-pose skeleton.

Every vertex is skinned to its own joint and, near the joint, to the joint's parent, so which
vertices a rotation may move is known exactly. Shape directions are smooth functions of the
rest position.
"""

from __future__ import annotations

import numpy as np

from hkpd.body import BodyAsset
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS

T_POSE_JOINTS = np.array(
    [
        [0.00, 0.00, 0.00], [0.06, -0.09, 0.00], [-0.06, -0.09, 0.00], [0.00, 0.11, -0.02],
        [0.10, -0.47, 0.00], [-0.10, -0.47, 0.00], [0.00, 0.25, 0.00], [0.09, -0.87, -0.04],
        [-0.09, -0.87, -0.04], [0.00, 0.31, 0.02], [0.12, -0.93, 0.08], [-0.12, -0.93, 0.08],
        [0.00, 0.52, 0.00], [0.08, 0.43, 0.00], [-0.08, 0.43, 0.00], [0.00, 0.60, 0.05],
        [0.18, 0.46, 0.00], [-0.18, 0.46, 0.00], [0.44, 0.46, 0.00], [-0.44, 0.46, 0.00],
        [0.70, 0.46, 0.00], [-0.70, 0.46, 0.00], [0.79, 0.46, 0.00], [-0.79, 0.46, 0.00],
    ]
)  # fmt: skip
"""Rough SMPL T-pose joint locations, metres (Y up, facing +Z, the body's left along +X)."""

CHILD = {parent: joint for joint, parent in reversed(list(enumerate(SMPL_PARENTS))) if parent >= 0}
"""First child of each non-leaf joint (the bone its tube follows)."""


def _smooth_directions(points: np.ndarray, num: int, rng: np.random.Generator) -> np.ndarray:
    """``(P, 3, num)`` smooth displacement fields evaluated at ``points`` ``(P, 3)``, metres."""
    frequency = rng.normal(size=(num, 3, 3)) * 2.0
    phase = rng.uniform(0, 2 * np.pi, size=(num, 3))
    amplitude = rng.uniform(0.005, 0.02, size=(num, 3))
    waves = np.einsum("pd,kcd->pck", points, frequency) + phase.T[None]
    return amplitude.T[None] * np.sin(waves)


def synthetic_body(
    rings_per_bone: int = 2,
    ring_size: int = 5,
    num_betas: int = 4,
    with_posedirs: bool = False,
    with_keypoints: bool = True,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """The synthetic body's arrays, float64, with an SMPL-style ``J_regressor`` as well.

    Returns:
        A dict with the :class:`BodyAsset` fields (``v_template``, ``faces``, ``shapedirs``,
        ``joint_template``, ``joint_shapedirs``, ``skinning_weights``, ``parents``,
        ``part_labels``, optional ``posedirs``/``keypoint_regressor``) plus ``J_regressor``
        ``(24, V)``, from which the joint fields are computed exactly as SMPL does.
    """
    rng = np.random.default_rng(seed)
    vertices, weights, owners, faces = [], [], [], []
    angles = np.linspace(0, 2 * np.pi, ring_size, endpoint=False)
    for joint, parent in enumerate(SMPL_PARENTS):
        start = T_POSE_JOINTS[joint]
        end = T_POSE_JOINTS[CHILD[joint]] if joint in CHILD else start + np.array([0.0, 0.06, 0.0])
        axis = (end - start) / np.linalg.norm(end - start)
        side = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        up = np.cross(axis, side)
        first = len(vertices)
        for ring in range(rings_per_bone):
            along = (ring + 0.5) / rings_per_bone
            centre = start + along * (end - start)
            for angle in angles:
                vertices.append(centre + 0.03 * (np.cos(angle) * side + np.sin(angle) * up))
                row = np.zeros(len(SMPL_PARENTS))
                share = 0.0 if parent == -1 or ring > 0 else 0.2 + 0.6 * rng.uniform()
                row[joint] = 1.0 - share
                if share:
                    row[parent] = share
                weights.append(row)
                owners.append(joint)
        faces += [[first, first + k + 1, first + k] for k in range(1, ring_size - 1)]  # cap
        for ring in range(rings_per_bone - 1):
            for k in range(ring_size):
                a = first + ring * ring_size + k
                b = first + ring * ring_size + (k + 1) % ring_size
                faces += [[a, b, a + ring_size], [b, b + ring_size, a + ring_size]]
    v_template = np.array(vertices)
    weights = np.array(weights)
    owners = np.array(owners)
    count = len(v_template)
    # SMPL-style regressor: each joint is the mean of its tube's vertices shifted back to the
    # joint, i.e. a linear function of the vertices (rows sum to 1).
    regressor = np.zeros((len(SMPL_PARENTS), count))
    for joint in range(len(SMPL_PARENTS)):
        regressor[joint, owners == joint] = 1.0 / np.count_nonzero(owners == joint)
    shapedirs = _smooth_directions(v_template, num_betas, rng)
    # Joints: the skeleton exactly, moved with the vertices by the shape directions.
    fields = {
        "v_template": v_template,
        "faces": np.array(faces),
        "shapedirs": shapedirs,
        "joint_template": T_POSE_JOINTS.copy(),
        "joint_shapedirs": np.einsum("jv,vck->jck", regressor, shapedirs),
        "skinning_weights": weights,
        "parents": np.array(SMPL_PARENTS),
        "part_labels": weights.argmax(axis=1),
        "J_regressor": regressor,
    }
    if with_posedirs:
        fields["posedirs"] = 0.01 * rng.normal(size=(count, 3, 207))
    if with_keypoints:
        keypoints = rng.uniform(size=(17, count)) * (rng.uniform(size=(17, count)) < 0.2)
        keypoints[:, 0] += 1e-3
        fields["keypoint_regressor"] = keypoints / keypoints.sum(axis=1, keepdims=True)
    return fields


def synthetic_asset(**options) -> BodyAsset:
    """:func:`synthetic_body` as a :class:`BodyAsset` (stored as float32, as the format says)."""
    fields = synthetic_body(**options)
    return BodyAsset(
        v_template=fields["v_template"],
        faces=fields["faces"],
        shapedirs=fields["shapedirs"],
        joint_template=fields["joint_template"],
        joint_shapedirs=fields["joint_shapedirs"],
        skinning_weights=fields["skinning_weights"],
        parents=fields["parents"],
        joint_names=SMPL_JOINT_NAMES,
        part_labels=fields["part_labels"],
        part_names=SMPL_JOINT_NAMES,
        keypoint_regressor=fields.get("keypoint_regressor"),
        posedirs=fields.get("posedirs"),
        metadata='{"source": "tests/synthetic_body.py"}',
        source="synthetic test body",
    )
