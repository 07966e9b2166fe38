"""Rendering the shipped body: watertight silhouettes, self-occlusion, determinism (CPU)."""

from __future__ import annotations

import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.rendering import ClothingTextureSampler, MeshRenderer, sample_lighting

SIZE = 128
FOCAL = 150.0


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


def posed(body: BodyModel, body_pose: torch.Tensor) -> torch.Tensor:
    batch = body_pose.shape[0]
    out = body(
        torch.zeros(batch, body.num_betas),
        body_pose,
        FRONTAL_GLOBAL_ORIENT.expand(batch, 3, 3),
        torch.tensor([0.0, 0.2, 2.5]).expand(batch, 3),
    )
    return out.vertices


def arm_forward_pose() -> torch.Tensor:
    """Left arm swung from the T-pose (along +x) to point forward, down and across the belly."""
    pose = torch.eye(3).repeat(1, 23, 1, 1)
    direction = torch.nn.functional.normalize(torch.tensor([-0.45, -0.55, 0.7]), dim=0)
    axis = torch.nn.functional.normalize(
        torch.linalg.cross(torch.tensor([1.0, 0, 0]), direction), dim=0
    )
    pose[0, 15] = roma.rotvec_to_rotmat(axis * torch.acos(direction[0]))  # joint 16, left_shoulder
    return pose


def render(renderer: MeshRenderer, vertices: torch.Tensor, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    batch = vertices.shape[0]
    colours = torch.rand(batch, renderer.num_faces, 3, generator=generator)
    return renderer.render(
        vertices, torch.full((batch,), FOCAL), colours, sample_lighting(batch, generator)
    )


def test_body_silhouette_has_no_holes_and_culling_changes_nothing(body: BodyModel):
    generator = torch.Generator().manual_seed(0)
    pose = roma.rotvec_to_rotmat(torch.randn(2, 23, 3, generator=generator) * 0.3)
    vertices = posed(body, pose)
    culled = render(MeshRenderer(body.faces, SIZE), vertices)
    both_sides = render(MeshRenderer(body.faces, SIZE, cull_backfaces=False), vertices)
    mask = culled.mask
    assert mask.sum() > 1000
    # A background pixel with all four neighbours on the body would be a hole.
    inner = mask[:, :-2, 1:-1] & mask[:, 2:, 1:-1] & mask[:, 1:-1, :-2] & mask[:, 1:-1, 2:]
    assert not (inner & ~mask[:, 1:-1, 1:-1]).any()
    # The body is closed: back faces never win the depth test.
    assert (culled.face_index != both_sides.face_index).float().mean() < 1e-3
    assert torch.equal(culled.mask, both_sides.mask)


def test_arm_in_front_of_torso_occludes_it(body: BodyModel):
    vertices = posed(body, arm_forward_pose())
    full = render(MeshRenderer(body.faces, SIZE), vertices)
    face_part = body.part_labels[body.faces[:, 0]]
    torso_faces = torch.isin(face_part, torch.tensor([0, 3, 6, 9]))
    torso_only = render(MeshRenderer(body.faces[torso_faces], SIZE), vertices)
    arm_parts = torch.tensor([16, 18, 20, 22])
    arm_pixels = torch.isin(full.part_map(face_part), arm_parts)
    overlap = arm_pixels & torso_only.mask
    assert overlap.sum() > 100  # the arm covers part of the torso on screen
    gap = torso_only.depth[overlap] - full.depth[overlap]
    assert (gap > 0).all()
    assert (gap > 0.1).float().mean() > 0.5  # the forearm floats well in front of the belly
    # The z-buffer never shows anything behind the torso.
    assert (full.depth <= torso_only.depth).all()
    # Where the torso is visible, the full render sees the same surface.
    torso_visible = torch.isin(full.part_map(face_part), torch.tensor([0, 3, 6, 9]))
    assert torch.allclose(full.depth[torso_visible], torso_only.depth[torso_visible])


def test_textured_body_render_is_deterministic(body: BodyModel):
    sampler = ClothingTextureSampler(body.v_template, body.faces, body.part_labels)
    vertices = posed(body, torch.eye(3).repeat(2, 23, 1, 1))
    renderer = MeshRenderer(body.faces, SIZE)
    outputs = []
    for _ in range(2):
        generator = torch.Generator().manual_seed(11)
        colours = sampler.sample(2, generator)
        lighting = sample_lighting(2, generator)
        outputs.append(renderer.render(vertices, torch.full((2,), FOCAL), colours, lighting))
    assert torch.equal(outputs[0].rgb, outputs[1].rgb)
    assert torch.equal(outputs[0].face_index, outputs[1].face_index)
    assert (outputs[0].rgb.amax(dim=1)[outputs[0].mask] > 0).all()
