"""Render the pictures of the body model in docs/figures (run after building the asset).

Usage: python docs/figures/scripts/make_body_figures.py

A small painter's-algorithm renderer (flat Lambert shading, OpenCV polygon fill) is enough for
documentation pictures; training uses the batched renderer in the library instead.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import roma
import torch

from hkpd.body import BodyModel

OUT = Path(__file__).resolve().parents[1]
SKIN = np.array([0.80, 0.68, 0.60])


def render(
    vertices: np.ndarray,
    faces: np.ndarray,
    size: int = 420,
    yaw_deg: float = 0.0,
    view_metres: float | None = None,
) -> np.ndarray:
    """Orthographic render of a mesh seen from +Z after turning it by ``yaw_deg`` about Y.

    The mesh fills the image unless ``view_metres`` fixes the width shown (centred on X = 0,
    feet 5 cm above the bottom edge), so that several bodies share one scale.
    """
    yaw = np.deg2rad(yaw_deg)
    turn = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    points = vertices @ turn.T
    if view_metres is None:
        centre = (points.max(0) + points.min(0)) / 2
        scale = 0.9 * size / (points.max(0) - points.min(0))[:2].max()
    else:
        centre = np.array([0.0, points[:, 1].min() - 0.05 + view_metres / 2, 0.0])
        scale = size / view_metres
    pixels = (points[:, :2] - centre[:2]) * scale * np.array([1, -1]) + size / 2
    corners = points[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-12
    light = np.array([0.3, 0.4, 1.0]) / np.linalg.norm([0.3, 0.4, 1.0])
    shade = 0.25 + 0.75 * np.clip(normals @ light, 0, 1)
    visible = normals[:, 2] > 0
    order = np.argsort(corners[:, :, 2].mean(1))
    image = np.full((size, size, 3), 255, dtype=np.uint8)
    for face in order:
        if not visible[face]:
            continue
        colour = tuple(int(c) for c in (SKIN * shade[face] * 255)[::-1])
        cv2.fillConvexPoly(
            image, np.round(pixels[faces[face]] * 16).astype(np.int32), colour, cv2.LINE_8, 4
        )
    return image


def label(image: np.ndarray, text: str) -> np.ndarray:
    cv2.putText(image, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (40, 40, 40), 1, cv2.LINE_AA)
    return image


def main() -> None:
    OUT.mkdir(exist_ok=True)
    body = BodyModel().double()
    faces = body.faces.numpy()
    zero = torch.zeros(1, body.num_betas, dtype=torch.float64)
    template = body.tpose(zero)[0].numpy()
    row = [
        label(render(template, faces), "template, front"),
        label(render(template, faces, yaw_deg=90), "template, side"),
    ]
    cv2.imwrite(str(OUT / "body_template.png"), np.concatenate(row, axis=1))

    generator = torch.Generator().manual_seed(3)
    betas = 1.5 * torch.randn(4, body.num_betas, generator=generator, dtype=torch.float64)
    shapes = [
        label(render(v.numpy(), faces, view_metres=2.3), f"beta0 = {b[0]:+.1f}")
        for v, b in zip(body.tpose(betas), betas, strict=True)
    ]
    cv2.imwrite(str(OUT / "body_shapes.png"), np.concatenate(shapes, axis=1))

    torch.manual_seed(4)
    pose = roma.rotvec_to_rotmat(0.35 * torch.randn(4, 23, 3, dtype=torch.float64))
    posed = body(betas, pose).vertices
    poses = [
        label(render(v.numpy(), faces, yaw_deg=20), f"random pose {i + 1}")
        for i, v in enumerate(posed)
    ]
    cv2.imwrite(str(OUT / "body_poses.png"), np.concatenate(poses, axis=1))
    print(f"wrote figures to {OUT}")


if __name__ == "__main__":
    main()
