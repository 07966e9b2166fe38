"""Render the retargeting check pictures docs/figures/poses_retarget_{daz,max,asf}.png, the
mirroring example docs/figures/poses_mirror.png and the procedural prior samples
docs/figures/poses_procedural.png.

Usage: python docs/figures/scripts/make_poses_figures.py [CMU_MOCAP_DIR]
(default /work/shared/data/cmu_mocap)

Each retargeting picture shows, for a few frames of one clip, the source BVH skeleton as a stick
figure (left) next to the SMPL body posed with the retargeted rotations (right), from the front
and from the body's left side. Both are drawn in the mocap world turned so that the pelvis faces
the viewer in the front row, so the two must match.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_body_figures import label, render

from hkpd.body import BodyModel
from hkpd.poses.bvh import load_bvh
from hkpd.poses.bvh_kinematics import forward_kinematics, local_rotations
from hkpd.poses.retargeting import retarget
from hkpd.poses.skeleton_flavours import detect_flavour

OUT = Path(__file__).resolve().parents[1]
SIZE = 300
CLIPS = {
    "daz": ("daz_bvh_Przestr/02_01.bvh", "daz_bvh_scaled_salsa_beemsoft/60_01_scaled.bvh"),
    "max": ("max_bvh_walk_shannonkao/26_01.bvh", "max_bvh_bvh11_131/131_03.bvh"),
    "asf": ("asf_named_bvh_Przestr_16/16_01.bvh", "asf_named_bvh_Przestr_16/16_02.bvh"),
}


def heading_turn(global_orient: np.ndarray, extra_deg: float) -> np.ndarray:
    """Rotation about Y that turns the pelvis's forward axis to +Z, then ``extra_deg`` more."""
    forward = global_orient[:, 2]
    yaw = np.arctan2(forward[0], forward[2])
    angle = -yaw + np.deg2rad(extra_deg)
    cos, sin = np.cos(angle), np.sin(angle)
    return np.array([[cos, 0, sin], [0, 1, 0], [-sin, 0, cos]])


def stick_figure(points: np.ndarray, parents: tuple[int, ...], keep: np.ndarray) -> np.ndarray:
    """Orthographic stick figure seen from +Z; left-side bones (x > 0 at rest) drawn blue."""
    centre = (points.max(0) + points.min(0)) / 2
    scale = 0.85 * SIZE / (points.max(0) - points.min(0))[:2].max()
    pixels = (points[:, :2] - centre[:2]) * scale * np.array([1, -1]) + SIZE / 2
    image = np.full((SIZE, SIZE, 3), 255, dtype=np.uint8)
    order = np.argsort(points[:, 2])
    for joint in order:
        parent = parents[joint]
        if parent < 0 or not keep[joint]:
            continue
        a = tuple(int(v) for v in np.round(pixels[parent]))
        b = tuple(int(v) for v in np.round(pixels[joint]))
        cv2.line(image, a, b, (60, 60, 60), 3, cv2.LINE_AA)
        cv2.circle(image, b, 3, (30, 30, 200), -1, cv2.LINE_AA)
    return image


def retarget_figure(path: Path, body: BodyModel, num_frames: int = 4) -> np.ndarray:
    motion = load_bvh(path)
    flavour = detect_flavour(motion.skeleton)
    clip = retarget(motion, flavour)
    rotations = local_rotations(motion)
    if flavour.drop_first_frame:
        rotations = rotations[1:]
    _, positions = forward_kinematics(motion.skeleton, rotations)
    names = motion.skeleton.names
    keep = np.array(
        [
            not any(k in n.lower() for k in ("thumb", "index", "mid", "ring", "pinky", "finger"))
            for n in names
        ]
    )
    frames = np.linspace(0, clip.num_frames - 1, num_frames + 2).round().astype(int)[1:-1]
    pose = clip.body_pose[frames]
    orient = clip.global_orient[frames]
    betas = torch.zeros(len(frames), body.num_betas, dtype=torch.float64)
    vertices = body(betas, pose, orient).vertices.numpy()
    faces = body.faces.numpy()
    rows = []
    for view, extra in (("front", 0.0), ("right side", 90.0)):
        tiles = []
        for i, frame in enumerate(frames):
            turn = heading_turn(orient[i].numpy(), extra)
            stick = stick_figure(positions[frame].numpy() @ turn.T, motion.skeleton.parents, keep)
            mesh = render(vertices[i] @ turn.T, faces, size=SIZE)
            label(stick, f"BVH f{frame + int(flavour.drop_first_frame)} {view}")
            label(mesh, "SMPL retargeted")
            tiles.append(np.concatenate([stick, mesh], axis=1))
        rows.append(np.concatenate(tiles, axis=1))
    image = np.concatenate(rows, axis=0)
    cv2.putText(
        image, f"{path.name} ({flavour.name})", (8, image.shape[0] - 10),
        cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 160), 1, cv2.LINE_AA,
    )  # fmt: skip
    return image


def mirror_figure(path: Path, body: BodyModel) -> None:
    """Three poses of a clip next to their left/right mirror images (front view)."""
    from hkpd.poses import mirror_pose

    clip = retarget(load_bvh(path))
    frames = torch.tensor([300, 900, 1400])
    pose, orient = clip.body_pose[frames], clip.global_orient[frames]
    mirrored_pose, mirrored_orient = mirror_pose(pose, orient)
    betas = torch.zeros(len(frames), body.num_betas, dtype=torch.float64)
    original = body(betas, pose, orient).vertices.numpy()
    mirrored = body(betas, mirrored_pose, mirrored_orient).vertices.numpy()
    tiles = []
    for i in range(len(frames)):
        # Face the original towards the viewer; the mirror image is shown in the mirrored view.
        turn = heading_turn(orient[i].numpy(), 0.0)
        flip = np.diag([-1.0, 1.0, 1.0])
        tiles.append(label(render(original[i] @ turn.T, body.faces.numpy(), size=SIZE),
                           f"{path.stem} f{int(frames[i]) + 1}"))  # fmt: skip
        tiles.append(label(render(mirrored[i] @ (flip @ turn @ flip).T, body.faces.numpy(),
                                  size=SIZE), "mirrored"))  # fmt: skip
    cv2.imwrite(str(OUT / "poses_mirror.png"), np.concatenate(tiles, axis=1))


def main() -> None:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "/work/shared/data/cmu_mocap")
    OUT.mkdir(exist_ok=True)
    body = BodyModel().double()
    with torch.no_grad():
        for flavour, clips in CLIPS.items():
            parts = [retarget_figure(root / clip, body) for clip in clips]
            cv2.imwrite(str(OUT / f"poses_retarget_{flavour}.png"), np.concatenate(parts, axis=0))
        mirror_figure(root / CLIPS["daz"][1], body)
        from hkpd.poses import ProceduralPosePrior

        prior = ProceduralPosePrior()
        pose, orient = prior.sample(8, torch.Generator().manual_seed(0))
        betas = torch.zeros(8, body.num_betas, dtype=torch.float64)
        vertices = body(betas, pose.double(), orient.double()).vertices.numpy()
        tiles = [label(render(v, body.faces.numpy(), size=SIZE), f"sample {i}")
                 for i, v in enumerate(vertices)]  # fmt: skip
        grid = np.concatenate(
            [np.concatenate(tiles[:4], axis=1), np.concatenate(tiles[4:], axis=1)], axis=0
        )
        cv2.imwrite(str(OUT / "poses_procedural.png"), grid)
    print(f"wrote figures to {OUT}")


if __name__ == "__main__":
    main()
