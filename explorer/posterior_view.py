"""Everything the scene shows about a posterior, computed in one go in the worker thread.

:func:`adjust_posterior` applies the user's concentration and shape-spread factors to the
predicted posterior; :func:`compute_view` draws the samples once (``num_samples`` of them, the
first ``num_displayed`` are also the meshes shown) and derives the mode, the per-vertex
uncertainty, the reprojected 2D keypoints and the selected joint's principal axes; given the
*baseline* uncertainty (:func:`baseline_uncertainty`: the same photo without occluders, default
concentrations, same seed and sample count), also each vertex's change ratio.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from hkpd.explorer.state import StateSnapshot
from hkpd.kinematic_tree import BODY_JOINT_NAMES, BODY_PARENTS, compose_global_rotations
from hkpd.prediction.posterior import BodyMeshes, BodyPosterior
from hkpd.uncertainty import vertex_uncertainty


@dataclass(frozen=True)
class JointAxes:
    """The principal axes of one joint's matrix-Fisher distribution, placed on the mode body.

    Attributes:
        joint: body-joint name.
        origin: ``(3,)`` joint position in the camera-aligned body frame, metres.
        axes: ``(3, 3)`` unit axes as COLUMNS, body frame: rotations of the joint about axis
            ``i`` (relative to its parent) have concentration ``concentrations[i]``.
        concentrations: ``(3,)`` ``s_j + s_k`` per axis, after the user's factors.
    """

    joint: str
    origin: np.ndarray
    axes: np.ndarray
    concentrations: np.ndarray


@dataclass(frozen=True)
class PosteriorView:
    """What the scene draws for one state of the sliders (numpy, float32, body frame, metres).

    Attributes:
        posterior: the adjusted posterior the samples came from.
        mode_vertices: ``(V, 3)``.
        mode_joints: ``(24, 3)``.
        mode_keypoints2d: ``(17, 2)`` photo pixels.
        sample_vertices: ``(K, V, 3)`` the displayed samples (K = num_displayed).
        sample_keypoints2d: ``(N, 17, 2)`` photo pixels of all N samples.
        uncertainty: ``(V,)`` metres, over all N samples.
        axes: principal axes of the selected joint.
        sampling_version: the state version this view was computed for.
        change_ratio: ``(V,)`` ``uncertainty`` / the baseline's (dimensionless), or None when
            no baseline was given.
    """

    posterior: BodyPosterior
    mode_vertices: np.ndarray
    mode_joints: np.ndarray
    mode_keypoints2d: np.ndarray
    sample_vertices: np.ndarray
    sample_keypoints2d: np.ndarray
    uncertainty: np.ndarray
    axes: JointAxes
    sampling_version: int
    change_ratio: np.ndarray | None = None


def adjust_posterior(base: BodyPosterior, snapshot: StateSnapshot) -> BodyPosterior:
    """``base`` with the snapshot's per-joint x global concentration and shape-std factors.

    Joints sharing a factor are scaled in one :meth:`BodyPosterior.with_concentration` call.
    """
    posterior = base
    groups: dict[float, list[int]] = {}
    for joint, factor in enumerate(snapshot.concentration_factors):
        groups.setdefault(round(factor, 9), []).append(joint)
    for factor, joints in groups.items():
        if factor != 1.0:
            posterior = posterior.with_concentration(joints, factor)
    if snapshot.shape_std_factor != 1.0:
        posterior = posterior.with_shape_std(snapshot.shape_std_factor)
    return posterior


def joint_axes(posterior: BodyPosterior, joint: str, mode_joints: np.ndarray) -> JointAxes:
    """Principal axes of ``joint`` drawn at its position on the mode body.

    With ``F = U S V^T`` the rotation is ``R = U Q V^T`` with ``Q`` near identity; a rotation
    of ``Q`` about axis ``e_i`` is a rotation about ``U e_i`` in the PARENT's frame, so the
    axes shown are ``G_parent U`` with ``G_parent`` the parent's global rotation in the mode.
    """
    index = BODY_JOINT_NAMES.index(joint)
    distribution = posterior.pose_distribution
    with torch.no_grad():
        mode = distribution.mode[0]
        global_rot = compose_global_rotations(mode, BODY_PARENTS, posterior.global_orient)
        parent = BODY_PARENTS[index]
        parent_rot = posterior.global_orient if parent < 0 else global_rot[parent]
        axes = parent_rot @ distribution.joints.U[0, index]
        concentrations = distribution.concentration[0, index]
    return JointAxes(
        joint=joint,
        origin=np.asarray(mode_joints[index + 1], dtype=np.float32),
        axes=axes.double().cpu().numpy().astype(np.float32),
        concentrations=concentrations.double().cpu().numpy(),
    )


MIN_BASELINE_M = 1e-4
"""Floor of the baseline uncertainty in the change ratio (0.1 mm: no division by zero)."""


def baseline_uncertainty(baseline: BodyPosterior, num_samples: int, seed: int) -> np.ndarray:
    """``(V,)`` metres: per-vertex uncertainty of ``baseline`` (unadjusted: default
    concentrations) over ``num_samples`` samples drawn with ``seed``, as :func:`compute_view`
    draws them (the same seed keeps the sampling noise of the two alike)."""
    samples = baseline.sample(num_samples, seed=seed)
    return vertex_uncertainty(samples.vertices).float().cpu().numpy()


def compute_view(
    base: BodyPosterior,
    snapshot: StateSnapshot,
    baseline_m: np.ndarray | None = None,
    mode: BodyMeshes | None = None,
) -> PosteriorView:
    """Adjust, sample and summarise (see the module docstring). Seeded by ``snapshot.seed``.

    Args:
        base: the predicted posterior.
        snapshot: the sliders.
        baseline_m: ``(V,)`` the baseline's uncertainty (:func:`baseline_uncertainty`), metres,
            or None (then ``change_ratio`` is None).
        mode: ``base.mode()`` when the caller keeps it (the sliders scale concentrations and
            the shape spread, never the modal rotations or the mean shape, so every view of
            ``base`` has the same most likely body); None: computed here.
    """
    posterior = adjust_posterior(base, snapshot)
    mode = posterior.mode() if mode is None else mode
    samples = posterior.sample(snapshot.num_samples, seed=snapshot.seed)
    shown = min(snapshot.num_displayed, snapshot.num_samples)
    uncertainty = vertex_uncertainty(samples.vertices).float().cpu().numpy()
    mode_joints = mode.joints[0].float().cpu().numpy()
    return PosteriorView(
        posterior=posterior,
        mode_vertices=mode.vertices[0].float().cpu().numpy(),
        mode_joints=mode_joints,
        mode_keypoints2d=mode.keypoints2d[0].float().cpu().numpy(),
        sample_vertices=samples.vertices[:shown].float().cpu().numpy(),
        sample_keypoints2d=samples.keypoints2d.float().cpu().numpy(),
        uncertainty=uncertainty,
        axes=joint_axes(posterior, snapshot.selected_joint, mode_joints),
        sampling_version=snapshot.sampling_version,
        change_ratio=None
        if baseline_m is None
        else uncertainty / np.maximum(np.asarray(baseline_m, np.float32), MIN_BASELINE_M),
    )


def part_uncertainty(uncertainty: np.ndarray, part_labels: np.ndarray) -> dict[str, float]:
    """Mean uncertainty (metres) of the vertices of each SMPL joint group, by joint name.

    Args:
        uncertainty: ``(V,)`` metres.
        part_labels: ``(V,)`` ints 0..23 (0 = pelvis).
    """
    names = ("pelvis", *BODY_JOINT_NAMES)
    labels = np.asarray(part_labels)
    return {
        name: float(uncertainty[labels == part].mean())
        for part, name in enumerate(names)
        if np.any(labels == part)
    }
