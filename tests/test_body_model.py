"""BodyModel and the skinning functions on a small synthetic body (no shipped asset needed)."""

from __future__ import annotations

import numpy as np
import pytest
import roma
import torch
from synthetic_body import synthetic_asset

from hkpd.body import BodyAsset, BodyModel, BodyOutput, load_body_asset, save_body_asset
from hkpd.body import body_model as body_model_module
from hkpd.body.linear_blend_skinning import (
    apply_skinned_readout,
    blend_and_skin,
    chunk_vertices,
    fold_readout_through_skinning,
    forward_kinematics,
    linear_blend_skinning,
    skinning_transforms,
)
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel(synthetic_asset()).double()


@pytest.fixture(scope="module")
def body_with_posedirs() -> BodyModel:
    return BodyModel(synthetic_asset(with_posedirs=True, seed=1)).double()


def random_pose(batch: int, max_angle: float = 1.5, seed: int = 0, dtype=torch.float64):
    generator = torch.Generator().manual_seed(seed)
    rotvecs = torch.randn(batch, 24, 3, generator=generator, dtype=dtype)
    rotvecs = (
        torch.nn.functional.normalize(rotvecs, dim=-1)
        * max_angle
        * torch.rand(batch, 24, 1, generator=generator, dtype=dtype)
    )
    rotations = roma.rotvec_to_rotmat(rotvecs)
    betas = torch.randn(batch, 4, generator=generator, dtype=dtype)
    transl = torch.randn(batch, 3, generator=generator, dtype=dtype)
    return betas, rotations[:, 1:], rotations[:, 0], transl


def identity_pose(batch: int, dtype=torch.float64) -> torch.Tensor:
    return torch.eye(3, dtype=dtype).expand(batch, 23, 3, 3)


def subtree(joint: int) -> set[int]:
    members = {joint}
    for child, parent in enumerate(SMPL_PARENTS):
        if parent in members:
            members.add(child)
    return members


def naive_pose(asset: BodyAsset, betas, body_pose, global_orient, transl):
    """Per-vertex LBS written out with loops, in float64 numpy: the reference."""
    betas, body_pose = np.asarray(betas, np.float64), np.asarray(body_pose, np.float64)
    global_orient, transl = np.asarray(global_orient, np.float64), np.asarray(transl, np.float64)
    rest = asset.v_template.astype(np.float64) + asset.shapedirs.astype(np.float64) @ betas
    if asset.posedirs is not None:
        rest = rest + asset.posedirs.astype(np.float64) @ (body_pose - np.eye(3)).reshape(-1)
    rest_joints = asset.joint_template + asset.joint_shapedirs.astype(np.float64) @ betas
    local = [global_orient, *body_pose]
    world_rotation, world_joint = [], []
    for joint, parent in enumerate(asset.parents):
        if parent == -1:
            world_rotation.append(local[joint])
            world_joint.append(rest_joints[joint])
        else:
            world_rotation.append(world_rotation[parent] @ local[joint])
            offset = rest_joints[joint] - rest_joints[parent]
            world_joint.append(world_joint[parent] + world_rotation[parent] @ offset)
    weights = asset.skinning_weights.astype(np.float64)
    posed = np.zeros_like(rest)
    for vertex in range(len(rest)):
        for joint in range(len(asset.parents)):
            weight = weights[vertex, joint]
            if weight != 0:
                moved = world_rotation[joint] @ (rest[vertex] - rest_joints[joint])
                posed[vertex] += weight * (moved + world_joint[joint])
        posed[vertex] /= weights[vertex].sum()
    return posed + transl, np.array(world_joint) + transl


def test_attributes_and_output_shapes(body: BodyModel) -> None:
    assert body.num_betas == 4 and body.num_vertices == body.v_template.shape[0]
    assert body.parents == SMPL_PARENTS and body.joint_names == SMPL_JOINT_NAMES
    assert body.part_names == SMPL_JOINT_NAMES and body.part_labels.shape == (body.num_vertices,)
    assert body.faces.dtype == torch.long and body.faces.shape[1] == 3
    betas, body_pose, global_orient, transl = random_pose(3)
    output = body(betas, body_pose, global_orient, transl)
    assert isinstance(output, BodyOutput)
    assert output.vertices.shape == (3, body.num_vertices, 3)
    assert output.joints.shape == (3, 24, 3) and output.keypoints.shape == (3, 17, 3)
    assert body.tpose(betas).shape == (3, body.num_vertices, 3)
    assert body.rest_joints(betas).shape == (3, 24, 3)


def test_zero_pose_and_betas_give_the_template(body: BodyModel) -> None:
    zero = torch.zeros(2, 4, dtype=torch.float64)
    output = body(zero, identity_pose(2))
    assert torch.allclose(output.vertices, body.v_template.expand(2, -1, -1), atol=1e-12)
    assert torch.allclose(output.joints, body.joint_template.expand(2, -1, -1), atol=1e-12)


def test_zero_pose_gives_the_rest_shape_and_joints(body: BodyModel) -> None:
    betas = torch.randn(3, 4, dtype=torch.float64)
    output = body(betas, identity_pose(3))
    assert torch.allclose(output.vertices, body.tpose(betas), atol=1e-12)
    assert torch.allclose(output.joints, body.rest_joints(betas), atol=1e-12)
    expected = body.v_template + torch.einsum("vck,bk->bvc", body.shapedirs, betas)
    assert torch.allclose(body.tpose(betas), expected, atol=1e-12)


@pytest.mark.parametrize("joint_name", ["left_elbow", "spine2", "right_hip", "head"])
def test_rotating_a_joint_moves_only_its_skinned_subtree(body: BodyModel, joint_name) -> None:
    joint = SMPL_JOINT_NAMES.index(joint_name)
    body_pose = identity_pose(1).clone()
    body_pose[0, joint - 1] = roma.rotvec_to_rotmat(torch.tensor([0.3, -0.7, 0.5]).double())
    betas = torch.randn(1, 4, dtype=torch.float64)
    moved = (body(betas, body_pose).vertices - body.tpose(betas))[0].norm(dim=-1) > 1e-12
    influenced = body.skinning_weights[:, sorted(subtree(joint))].sum(dim=1) > 0
    assert moved.any() and not (moved & ~influenced).any()
    joints_moved = (body(betas, body_pose).joints - body.rest_joints(betas))[0].norm(dim=-1)
    assert set((joints_moved > 1e-12).nonzero().flatten().tolist()) <= subtree(joint) - {joint}


def test_global_orient_turns_rigidly_about_the_root_joint_and_transl_translates(
    body: BodyModel,
) -> None:
    betas, body_pose, global_orient, transl = random_pose(2, seed=3)
    plain = body(betas, body_pose)
    turned = body(betas, body_pose, global_orient)
    root = body.rest_joints(betas)[:, :1]

    def turn(points: torch.Tensor) -> torch.Tensor:
        return (points - root) @ global_orient.transpose(1, 2) + root

    assert torch.allclose(turned.vertices, turn(plain.vertices), atol=1e-12)
    assert torch.allclose(turned.joints, turn(plain.joints), atol=1e-12)
    assert torch.allclose(turned.keypoints, turn(plain.keypoints), atol=1e-12)
    moved = body(betas, body_pose, global_orient, transl)
    shift = transl.unsqueeze(1)
    assert torch.allclose(moved.vertices, turned.vertices + shift, atol=1e-12)
    assert torch.allclose(moved.joints, turned.joints + shift, atol=1e-12)
    assert torch.allclose(moved.keypoints, turned.keypoints + shift, atol=1e-12)


@pytest.mark.parametrize("with_posedirs", [False, True])
def test_matches_naive_per_vertex_skinning(body, body_with_posedirs, with_posedirs) -> None:
    model = body_with_posedirs if with_posedirs else body
    asset = synthetic_asset(with_posedirs=True, seed=1) if with_posedirs else synthetic_asset()
    betas, body_pose, global_orient, transl = random_pose(3, seed=4)
    output = model(betas, body_pose, global_orient, transl)
    for index in range(3):
        vertices, joints = naive_pose(
            asset, betas[index], body_pose[index], global_orient[index], transl[index]
        )
        assert np.allclose(output.vertices[index].numpy(), vertices, atol=1e-10)
        assert np.allclose(output.joints[index].numpy(), joints, atol=1e-10)
    keypoints = model.keypoint_regressor @ output.vertices
    assert torch.allclose(output.keypoints, keypoints, atol=1e-12)


def test_posedirs_are_applied(body_with_posedirs: BodyModel) -> None:
    model = body_with_posedirs
    betas, body_pose, _, _ = random_pose(2, seed=5)
    assert torch.allclose(model(betas, identity_pose(2)).vertices, model.tpose(betas), atol=1e-12)
    without = BodyModel(synthetic_asset(with_posedirs=True, seed=1))
    without.posedirs = None
    without = without.double()
    difference = model(betas, body_pose).vertices - without(betas, body_pose).vertices
    assert difference.abs().max() > 1e-3


@pytest.mark.parametrize("chunk_size", [1, 7, 64, 10_000])
def test_chunked_blend_and_skin_matches_dense_skinning(chunk_size: int) -> None:
    asset = synthetic_asset(with_posedirs=True, seed=2)
    model = BodyModel(asset).double()
    betas, body_pose, global_orient, transl = random_pose(4, seed=6)
    rotations = torch.cat((global_orient.unsqueeze(1), body_pose), dim=1)
    rest_joints = model.rest_joints(betas)
    global_rotations, posed_joints = forward_kinematics(rest_joints, rotations, SMPL_PARENTS)
    transforms = skinning_transforms(global_rotations, posed_joints, rest_joints, transl)
    features = (body_pose - torch.eye(3, dtype=torch.float64)).flatten(1)
    rest = model.tpose(betas) + torch.einsum("vcp,bp->bvc", model.posedirs, features)
    dense = linear_blend_skinning(rest, transforms, model.skinning_weights)
    blend_shapes = torch.cat((model.shapedirs, model.posedirs), dim=2).permute(1, 2, 0)
    chunks = chunk_vertices(model.skinning_weights, chunk_size)
    coefficients = torch.cat((betas, features), dim=1)
    fast = blend_and_skin(
        model.v_template.T.contiguous(), blend_shapes.contiguous(), coefficients, transforms, chunks
    )
    assert torch.allclose(fast, dense, atol=1e-12)
    folded = fold_readout_through_skinning(
        model.keypoint_regressor,
        model.v_template,
        torch.cat((model.shapedirs, model.posedirs), dim=2),
        model.skinning_weights,
    )
    keypoints = apply_skinned_readout(folded, coefficients, transforms)
    assert torch.allclose(keypoints, model.keypoint_regressor @ dense, atol=1e-12)


def test_gradients_reach_betas_and_rotations(body: BodyModel) -> None:
    betas, body_pose, global_orient, transl = random_pose(2, seed=7)
    betas.requires_grad_(True)
    rotvecs = roma.rotmat_to_rotvec(body_pose).requires_grad_(True)
    output = body(betas, roma.rotvec_to_rotmat(rotvecs), global_orient, transl)
    (output.vertices.square().sum() + output.keypoints.sum()).backward()
    assert betas.grad is not None and betas.grad.abs().min() > 0
    # Leaf joints (hands, feet, head) move no vertices' joints but still turn their tubes.
    assert rotvecs.grad is not None and (rotvecs.grad.norm(dim=-1) > 0).all()


def test_gradcheck_in_float64_on_a_tiny_body() -> None:
    tiny = BodyModel(synthetic_asset(rings_per_bone=1, ring_size=3, num_betas=2, seed=3))
    tiny = tiny.double()
    betas, body_pose, global_orient, transl = random_pose(1, seed=8)
    betas = betas[:, :2].clone().requires_grad_(True)
    rotvecs = roma.rotmat_to_rotvec(body_pose).requires_grad_(True)
    orient = global_orient.clone().requires_grad_(True)
    transl = transl.clone().requires_grad_(True)

    def posed(betas, rotvecs, orient, transl):
        output = tiny(betas, roma.rotvec_to_rotmat(rotvecs), orient, transl)
        return output.vertices, output.joints, output.keypoints

    assert torch.autograd.gradcheck(posed, (betas, rotvecs, orient, transl))


def test_gradcheck_through_several_chunks() -> None:
    asset = synthetic_asset(rings_per_bone=1, ring_size=3, num_betas=2, seed=4)
    model = BodyModel(asset).double()
    generator = torch.Generator().manual_seed(9)
    transforms = torch.randn(1, 24, 3, 4, dtype=torch.float64, generator=generator)
    coefficients = torch.randn(1, 2, dtype=torch.float64, generator=generator)
    transforms.requires_grad_(True)
    coefficients.requires_grad_(True)
    chunks = chunk_vertices(model.skinning_weights, 10)
    template = model.v_template.T.contiguous()
    blend_shapes = model.shapedirs.permute(1, 2, 0).contiguous()

    def skin(coefficients, transforms):
        return blend_and_skin(template, blend_shapes, coefficients, transforms, chunks)

    assert torch.autograd.gradcheck(skin, (coefficients, transforms))


def test_float32_and_float64_agree() -> None:
    asset = synthetic_asset(with_posedirs=True, seed=5)
    single, double = BodyModel(asset), BodyModel(asset).double()
    assert single.v_template.dtype == torch.float32 and double.v_template.dtype == torch.float64
    betas, body_pose, global_orient, transl = random_pose(3, seed=10)
    high = double(betas, body_pose, global_orient, transl)
    low = single(betas.float(), body_pose.float(), global_orient.float(), transl.float())
    for name in ("vertices", "joints", "keypoints"):
        assert getattr(low, name).dtype == torch.float32
        assert torch.allclose(getattr(low, name).double(), getattr(high, name), atol=2e-5)


def test_large_batches_use_the_same_maths(body: BodyModel) -> None:
    # Big batches pick smaller vertex chunks on the CPU; the result must not change.
    betas, body_pose, global_orient, transl = random_pose(300, seed=11)
    together = body(betas, body_pose, global_orient, transl).vertices
    one = body(betas[:1], body_pose[:1], global_orient[:1], transl[:1]).vertices
    assert torch.allclose(together[:1], one, atol=1e-12)


def test_no_keypoints_without_a_regressor() -> None:
    model = BodyModel(synthetic_asset(with_keypoints=False))
    output = model(torch.zeros(1, 4), torch.eye(3).expand(1, 23, 3, 3))
    assert output.keypoints is None


def test_invalid_inputs_are_rejected_clearly(body: BodyModel) -> None:
    pose = identity_pose(2)
    with pytest.raises(ValueError, match=r"betas must have shape \(B, 4\)"):
        body(torch.zeros(2, 10, dtype=torch.float64), pose)
    with pytest.raises(ValueError, match=r"body_pose must have shape \(2, 23, 3, 3\)"):
        body(torch.zeros(2, 4, dtype=torch.float64), torch.zeros(2, 24, 3, 3).double())
    with pytest.raises(ValueError, match=r"global_orient must have shape \(2, 3, 3\)"):
        body(torch.zeros(2, 4, dtype=torch.float64), pose, torch.zeros(2, 3).double())
    with pytest.raises(ValueError, match=r"transl must have shape \(2, 3\)"):
        body(torch.zeros(2, 4, dtype=torch.float64), pose, None, torch.zeros(3).double())
    with pytest.raises(ValueError, match="dtype"):
        body(torch.zeros(2, 4), pose)


def test_module_conversions_rebuild_the_derived_arrays() -> None:
    model = BodyModel(synthetic_asset())
    betas, body_pose, global_orient, transl = random_pose(2, seed=12, dtype=torch.float32)
    first = model(betas, body_pose, global_orient, transl).vertices
    model.double()
    second = model(betas.double(), body_pose.double(), global_orient.double(), transl.double())
    assert second.vertices.dtype == torch.float64
    assert torch.allclose(first.double(), second.vertices, atol=1e-5)
    with torch.no_grad():
        model.v_template += 1.0  # an in-place edit must not leave stale copies behind
    moved = model(betas.double(), body_pose.double(), global_orient.double(), transl.double())
    assert not torch.allclose(moved.vertices, second.vertices)
    state = BodyModel(synthetic_asset()).double().state_dict()
    model.load_state_dict(state)
    again = model(betas.double(), body_pose.double(), global_orient.double(), transl.double())
    assert torch.allclose(again.vertices, second.vertices, atol=1e-12)


def test_missing_shipped_asset_explains_how_to_build_it(monkeypatch) -> None:
    monkeypatch.setattr(body_model_module, "SHIPPED_ASSET", ("body", "no_such_file.npz"))
    with pytest.raises(FileNotFoundError, match="build_from_anny"):
        BodyModel()


def test_asset_round_trip_and_validation(tmp_path) -> None:
    asset = synthetic_asset(with_posedirs=True)
    path = tmp_path / "body.npz"
    save_body_asset(asset, path)
    loaded = load_body_asset(path)
    assert loaded.source == str(path) and loaded.metadata == asset.metadata
    for name in ("v_template", "faces", "shapedirs", "skinning_weights", "posedirs", "parents"):
        assert np.array_equal(getattr(loaded, name), getattr(asset, name))
    assert loaded.joint_names == SMPL_JOINT_NAMES and loaded.num_betas == 4
    with np.load(path) as archive:
        assert archive["faces"].dtype == np.int32 and archive["part_labels"].dtype == np.uint8
        assert archive["shapedirs"].dtype == np.float32 and archive["joint_names"].shape == (24,)
    assert load_body_asset(path, num_betas=2).shapedirs.shape[2] == 2

    with np.load(path) as archive:
        fields = dict(archive)
    broken = tmp_path / "broken.npz"
    np.savez(broken, **{**fields, "shapedirs": fields["shapedirs"][:-1]})
    with pytest.raises(ValueError, match=r"broken\.npz: field 'shapedirs' must have shape"):
        load_body_asset(broken)
    np.savez(broken, **{key: value for key, value in fields.items() if key != "parents"})
    with pytest.raises(ValueError, match=r"broken\.npz: missing field\(s\) \['parents'\]"):
        load_body_asset(broken)
    weights = fields["skinning_weights"].copy()
    weights[5] *= 2
    np.savez(broken, **{**fields, "skinning_weights": weights})
    with pytest.raises(ValueError, match="'skinning_weights' rows must sum to 1, row 5"):
        load_body_asset(broken)
    with pytest.raises(FileNotFoundError, match=r"nowhere\.npz"):
        load_body_asset(tmp_path / "nowhere.npz")
    with pytest.raises(ValueError, match="asked for 7 shape coefficients"):
        load_body_asset(path, num_betas=7)


def test_inference_mode_first_then_autograd() -> None:
    model = BodyModel(synthetic_asset())
    betas, body_pose, global_orient, transl = random_pose(2, seed=13, dtype=torch.float32)
    with torch.inference_mode():
        fast = model(betas, body_pose, global_orient, transl).vertices
    betas.requires_grad_(True)
    slow = model(betas, body_pose, global_orient, transl).vertices
    slow.sum().backward()
    assert betas.grad is not None and torch.allclose(fast, slow.detach(), atol=1e-6)
