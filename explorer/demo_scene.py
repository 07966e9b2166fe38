"""The built-in demo photo: a synthetic person that hkpd renders itself, with known ground truth.

It needs nothing but the shipped body model, so ``hkpd-explore`` works offline on a fresh
install. The person (the shipped body in a relaxed walking pose, turned a little towards the
viewer's left) is rasterised with :func:`hkpd.rendering.rasterizer.rasterize` and shaded with
simple Lambert lighting; clothing colours follow the body-part labels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT, perspective_project
from hkpd.kinematic_tree import BODY_JOINT_NAMES, SMPL_JOINT_NAMES
from hkpd.rendering.rasterizer import rasterize

DEMO_SIZE = 512
"""Side of the rendered square, pixels; the photo is its central portrait crop."""

DEMO_WIDTH = 384
"""Width of the portrait demo photo (height = DEMO_SIZE)."""

DEMO_FOCAL_PX = 620.0
DEMO_TRANSL = (0.0, 0.12, 2.9)
"""Pelvis position in the camera frame, metres."""

DEMO_YAW_DEG = 20.0

# Relative joint rotations of the demo pose, axis-angle in degrees (SMPL axes of the parent).
DEMO_POSE_DEG: dict[str, tuple[float, float, float]] = {
    "left_hip": (-28.0, 0.0, 4.0),
    "right_hip": (14.0, 0.0, -4.0),
    "left_knee": (38.0, 0.0, 0.0),
    "right_knee": (12.0, 0.0, 0.0),
    "left_ankle": (-8.0, 0.0, 0.0),
    "spine1": (4.0, 0.0, 0.0),
    "spine2": (3.0, 6.0, 0.0),
    "neck": (-6.0, -10.0, 0.0),
    "head": (4.0, -8.0, 0.0),
    "left_shoulder": (0.0, -20.0, -58.0),
    "right_shoulder": (0.0, 15.0, 62.0),
    "left_elbow": (0.0, -75.0, 0.0),
    "right_elbow": (0.0, 35.0, 0.0),
    "left_wrist": (0.0, 0.0, -10.0),
}

_SKIN = np.array([224, 180, 150])
_SHIRT = np.array([70, 120, 190])
_TROUSERS = np.array([60, 60, 72])
_SHOES = np.array([150, 60, 45])
_HAIR = np.array([70, 48, 35])
_PART_GROUPS: tuple[tuple[tuple[str, ...], np.ndarray], ...] = (
    (("pelvis", "spine1", "spine2", "spine3", "left_collar", "right_collar", "left_shoulder",
      "right_shoulder"), _SHIRT),
    (("left_hip", "right_hip", "left_knee", "right_knee"), _TROUSERS),
    (("left_ankle", "right_ankle", "left_foot", "right_foot"), _SHOES),
    (("neck", "head", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hand",
      "right_hand"), _SKIN),
)  # fmt: skip
_PART_COLOURS: dict[str, np.ndarray] = {
    name: colour for names, colour in _PART_GROUPS for name in names
}


@dataclass(frozen=True)
class DemoScene:
    """The demo photo and the truth behind it.

    Attributes:
        image: ``(H, W, 3)`` uint8 RGB, ``H = 512``, ``W = 384``.
        body_pose: ``(23, 3, 3)`` true relative joint rotations.
        betas: ``(10,)`` true shape.
        global_orient: ``(3, 3)`` body-to-camera rotation.
        transl: ``(3,)`` pelvis position in the camera frame, metres.
        focal_px: focal length, pixels.
        principal_point: ``(2,)`` principal point in PHOTO pixels (pixel centres at integers).
        keypoints2d: ``(17, 2)`` true COCO keypoints in photo pixels (pixel-centre coords).
        vertices: ``(V, 3)`` true mesh in the camera frame, metres.
    """

    image: np.ndarray
    body_pose: torch.Tensor
    betas: torch.Tensor
    global_orient: torch.Tensor
    transl: torch.Tensor
    focal_px: float
    principal_point: np.ndarray
    keypoints2d: np.ndarray
    vertices: np.ndarray


def demo_pose() -> torch.Tensor:
    """``(23, 3, 3)`` relative rotations of the demo pose."""
    rotvecs = torch.zeros(len(BODY_JOINT_NAMES), 3, dtype=torch.float64)
    for name, degrees in DEMO_POSE_DEG.items():
        rotvecs[BODY_JOINT_NAMES.index(name)] = torch.tensor(degrees, dtype=torch.float64)
    return roma.rotvec_to_rotmat(torch.deg2rad(rotvecs)).float()


@lru_cache(maxsize=1)
def render_demo_scene() -> DemoScene:
    """Render the demo photo (about 0.3 s; cached)."""
    body = BodyModel()
    betas = torch.zeros(1, body.num_betas)
    betas[0, :2] = torch.tensor([0.4, -0.3])[: body.num_betas]
    yaw = roma.rotvec_to_rotmat(torch.tensor([0.0, math.radians(DEMO_YAW_DEG), 0.0]))
    global_orient = (FRONTAL_GLOBAL_ORIENT @ yaw.float())[None]
    pose = demo_pose()[None]
    with torch.no_grad():
        posed = body(betas, pose, global_orient)
    transl = torch.tensor(DEMO_TRANSL)
    vertices = posed.vertices - posed.joints[:, :1] + transl
    keypoints = posed.keypoints - posed.joints[:, :1] + transl
    faces = body.faces.long()
    raster = rasterize(vertices, faces, torch.tensor([DEMO_FOCAL_PX]), DEMO_SIZE)
    image = _background(DEMO_SIZE)
    face_index = raster.face_index[0].numpy()
    covered = face_index >= 0
    face_colours = _face_colours(body, vertices[0].numpy(), faces.numpy())
    image[covered] = face_colours[face_index[covered]]
    left = (DEMO_SIZE - DEMO_WIDTH) // 2
    keypoints2d = perspective_project(keypoints[0], DEMO_FOCAL_PX, DEMO_SIZE).numpy()
    keypoints2d[:, 0] -= left
    centre = (DEMO_SIZE - 1) / 2.0
    return DemoScene(
        image=np.ascontiguousarray(image[:, left : left + DEMO_WIDTH]),
        body_pose=pose[0],
        betas=betas[0],
        global_orient=global_orient[0],
        transl=transl,
        focal_px=DEMO_FOCAL_PX,
        principal_point=np.array([centre - left, centre]),
        keypoints2d=keypoints2d.astype(np.float64),
        vertices=vertices[0].numpy(),
    )


def _background(size: int) -> np.ndarray:
    """A pale wall over a floor, ``(size, size, 3)`` uint8."""
    rows = np.linspace(0.0, 1.0, size)[:, None, None]
    wall = np.array([232, 228, 218]) * (1.0 - 0.15 * rows) + np.array([10, 10, 20]) * rows
    floor = np.array([176, 160, 140]) * (1.1 - 0.3 * rows)
    horizon = int(size * 0.78)
    image = np.broadcast_to(wall, (size, size, 3)).copy()
    image[horizon:] = np.broadcast_to(floor[horizon:], (size - horizon, size, 3))
    return np.clip(image, 0, 255).astype(np.uint8)


def _face_colours(body: BodyModel, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(F, 3)`` uint8 Lambert-shaded colour of every face (light from the upper left)."""
    labels = body.part_labels.numpy()
    face_part = labels[faces[:, 0]]
    base = np.stack([_PART_COLOURS[SMPL_JOINT_NAMES[p]] for p in range(len(SMPL_JOINT_NAMES))])
    head = SMPL_JOINT_NAMES.index("head")
    corners = vertices[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-12
    light = np.array([-0.4, -0.6, -1.0])
    light /= np.linalg.norm(light)
    shade = 0.35 + 0.65 * np.clip(normals @ light, 0.0, 1.0)
    colours = base[face_part].astype(np.float64)
    # Hair: the top and back of the head.
    top_of_head = (face_part == head) & (corners[:, :, 1].mean(1) < np.percentile(
        corners[face_part == head][:, :, 1].mean(1), 45))  # fmt: skip
    colours[top_of_head] = _HAIR
    return np.clip(colours * shade[:, None], 0, 255).astype(np.uint8)
