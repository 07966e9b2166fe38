"""KinematicMatrixFisher and forward kinematics of rotations on the SMPL tree."""

from __future__ import annotations

import pytest
import roma
import torch

from hkpd.distributions import KinematicMatrixFisher, MatrixFisher, compose_global_rotations
from hkpd.kinematic_tree import (
    BODY_JOINT_NAMES,
    BODY_PARENTS,
    SMPL_JOINT_NAMES,
    SMPL_PARENTS,
    ancestors,
    depth_levels,
    validate_parents,
)

J = len(BODY_PARENTS)


def distribution(batch: int = 3, scale: float = 5.0, seed: int = 0) -> KinematicMatrixFisher:
    torch.manual_seed(seed)
    return KinematicMatrixFisher(
        scale * torch.randn(batch, J, 3, 3, dtype=torch.float64), BODY_PARENTS
    )


def test_smpl_tree() -> None:
    assert len(SMPL_JOINT_NAMES) == 24 and len(BODY_JOINT_NAMES) == 23
    assert validate_parents(SMPL_PARENTS) == SMPL_PARENTS
    assert BODY_JOINT_NAMES[BODY_PARENTS.index(-1)] == "left_hip"
    wrist = BODY_JOINT_NAMES.index("left_wrist")
    assert [BODY_JOINT_NAMES[j] for j in ancestors(BODY_PARENTS, wrist)] == [
        "left_elbow", "left_shoulder", "left_collar", "spine3", "spine2", "spine1",
    ]  # fmt: skip
    levels = depth_levels(BODY_PARENTS)
    assert sorted(j for level in levels for j in level) == list(range(J))


def test_invalid_parents_are_rejected() -> None:
    with pytest.raises(ValueError, match="parents"):
        validate_parents([-1, 2, 0])
    with pytest.raises(ValueError, match=r"\(\.\.\., 23, 3, 3\)"):
        KinematicMatrixFisher(torch.zeros(2, 5, 3, 3), BODY_PARENTS)


def test_sample_shapes_and_log_prob_factorise() -> None:
    d = distribution()
    samples = d.rsample(7)
    assert samples.shape == (7, 3, J, 3, 3)
    assert d.mode.shape == (3, J, 3, 3) and d.concentration.shape == (3, J, 3)
    per_joint = MatrixFisher(d.F).log_prob(samples)
    assert torch.allclose(d.log_prob(samples), per_joint.sum(-1))
    assert d.last_acceptance_rate.shape == (3, J)
    assert d.entropy().shape == (3,)


def test_gradients_reach_every_joint() -> None:
    torch.manual_seed(1)
    F = (5.0 * torch.randn(2, J, 3, 3)).requires_grad_()
    d = KinematicMatrixFisher(F, BODY_PARENTS)
    global_rotations = d.global_rotations(d.rsample(4))
    global_rotations.sum().backward()
    assert torch.isfinite(F.grad).all()
    assert (F.grad.abs().sum((-1, -2)) > 0).all()


def _naive_forward_kinematics(relative: torch.Tensor, root: torch.Tensor) -> torch.Tensor:
    result = []
    for joint, parent in enumerate(BODY_PARENTS):
        base = root if parent == -1 else result[parent]
        result.append(base @ relative[..., joint, :, :])
    return torch.stack(result, dim=-3)


def test_compose_global_rotations_matches_naive_chain() -> None:
    torch.manual_seed(2)
    relative = roma.random_rotmat((4, J), dtype=torch.float64)
    root = roma.random_rotmat(4, dtype=torch.float64)
    composed = compose_global_rotations(relative, BODY_PARENTS, root)
    assert torch.allclose(composed, _naive_forward_kinematics(relative, root))
    without_root = compose_global_rotations(relative, BODY_PARENTS)
    identity = torch.eye(3, dtype=torch.float64).expand(4, 3, 3)
    assert torch.allclose(without_root, _naive_forward_kinematics(relative, identity))
    # A root shared by a batch of samples broadcasts.
    samples = roma.random_rotmat((5, 4, J), dtype=torch.float64)
    assert compose_global_rotations(samples, BODY_PARENTS, root).shape == (5, 4, J, 3, 3)


@pytest.mark.parametrize(
    "joints",
    [4, [4, 7, 10], torch.tensor([j in (17, 19) for j in range(J)])],
    ids=["index", "list", "mask"],
)
def test_scale_concentration_changes_only_selected_joints(joints) -> None:
    d = distribution()
    scaled = d.scale_concentration(joints, 3.0)
    selected = torch.zeros(J, dtype=torch.bool)
    selected[torch.as_tensor(joints)] = True
    ratio = scaled.joints.S / d.joints.S
    assert torch.allclose(ratio[:, selected], torch.full_like(ratio[:, selected], 3.0))
    assert torch.allclose(ratio[:, ~selected], torch.ones_like(ratio[:, ~selected]))
    assert torch.allclose(scaled.mode, d.mode, atol=1e-10)
    assert scaled.parents == d.parents


def test_scale_concentration_to_zero_gives_uniform_joint() -> None:
    d = distribution()
    flattened = d.scale_concentration(0, 0.0)
    assert torch.allclose(flattened.log_normalizer[:, 0], torch.zeros(3, dtype=torch.float64))


def test_scale_concentration_rejects_bad_input() -> None:
    d = distribution()
    with pytest.raises(IndexError):
        d.scale_concentration(23, 2.0)
    with pytest.raises(ValueError, match="non-negative"):
        d.scale_concentration(0, -1.0)


def test_expand() -> None:
    d = distribution(batch=1)
    expanded = d.expand((4,))
    assert expanded.batch_shape == (4,) and expanded.sample(2).shape == (2, 4, J, 3, 3)
