"""Benchmark the body model's forward pass (blend shapes, kinematics, skinning, keypoints) on CPU.

Prints a markdown table (paste it into docs/benchmarks.md): for B bodies per call, float32,
the time of ``BodyModel.forward`` without autograd (median and best of the timed calls), the
same work done the plain dense way (``tpose`` + ``linear_blend_skinning`` + regressor) for
comparison, forward + backward with gradients to betas and rotations, and ``tpose`` alone.

By default it uses the shipped asset (``hkpd/assets/body/hkpd_body.npz``). ``--synthetic``
builds a body of the same size instead (13,718 vertices, ~27,000 triangles, up to 7 joints per
vertex with most vertices on 1-3), which is also used when the shipped asset is missing.

Usage: python benchmarks/bench_body_model.py [--synthetic] [--threads 2] [--repeats 50]
"""

from __future__ import annotations

import argparse
import platform

import numpy as np
import roma
import torch
from timing import median_and_best

from hkpd.body import BodyAsset, BodyModel
from hkpd.body.body_model import load_shipped_asset
from hkpd.body.linear_blend_skinning import (
    forward_kinematics,
    linear_blend_skinning,
    skinning_transforms,
)
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS

SYNTHETIC_VERTICES = 13_718

# Rough SMPL T-pose joints (metres) and the share of vertices with 1..7 influencing joints in
# the shipped mesh.
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
INFLUENCE_SHARES = np.array([0.635, 0.225, 0.052, 0.048, 0.035, 0.0045, 0.0005])


def _joint_neighbourhoods() -> list[list[int]]:
    """For each joint, itself then the joints nearest to it in the tree (parent, children, ...)."""
    neighbours: list[set[int]] = [set() for _ in SMPL_PARENTS]
    for joint, parent in enumerate(SMPL_PARENTS):
        if parent >= 0:
            neighbours[joint].add(parent)
            neighbours[parent].add(joint)
    orders = []
    for joint in range(len(SMPL_PARENTS)):
        order, frontier = [joint], [joint]
        while len(order) < 7:
            frontier = sorted({n for f in frontier for n in neighbours[f]} - set(order))
            if not frontier:
                break
            order += frontier
        orders.append(order[:7])
    return orders


def synthetic_asset(seed: int = 0) -> BodyAsset:
    """A body the size of the shipped one: one tube of rings per bone, vertices in bone order."""
    rng = np.random.default_rng(seed)
    children = {p: j for j, p in reversed(list(enumerate(SMPL_PARENTS))) if p >= 0}
    ends = np.array(
        [
            T_POSE_JOINTS[children[j]] if j in children else T_POSE_JOINTS[j] + [0.0, 0.08, 0.0]
            for j in range(24)
        ]
    )
    lengths = np.linalg.norm(ends - T_POSE_JOINTS, axis=1)
    ring_size = 24
    rings = np.maximum(2, np.round(lengths / lengths.sum() * SYNTHETIC_VERTICES / ring_size))
    rings[-1] += np.ceil((SYNTHETIC_VERTICES - rings.sum() * ring_size) / ring_size)
    neighbourhoods = _joint_neighbourhoods()
    angles = np.linspace(0, 2 * np.pi, ring_size, endpoint=False)
    vertices, weights, faces = [], [], []
    for joint in range(24):
        start, end = T_POSE_JOINTS[joint], ends[joint]
        axis = (end - start) / np.linalg.norm(end - start)
        side = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        up = np.cross(axis, side)
        count = int(rings[joint])
        first = len(vertices)
        # Vertices near the bone's ends blend more joints: sort influence counts by distance
        # from the middle of the bone.
        influences = np.sort(
            rng.choice(np.arange(1, 8), size=count * ring_size, p=INFLUENCE_SHARES)
        )
        along = np.abs(np.linspace(-1, 1, count * ring_size))
        influences = influences[np.argsort(np.argsort(along))]
        for ring in range(count):
            centre = start + (ring + 0.5) / count * (end - start)
            for k, angle in enumerate(angles):
                vertices.append(centre + 0.05 * (np.cos(angle) * side + np.sin(angle) * up))
                chosen = neighbourhoods[joint][: influences[ring * ring_size + k]]
                row = np.zeros(24)
                row[chosen] = rng.dirichlet(np.ones(len(chosen)))
                row[joint] += 1.0
                weights.append(row / row.sum())
        for ring in range(count - 1):
            for k in range(ring_size):
                a = first + ring * ring_size + k
                b = first + ring * ring_size + (k + 1) % ring_size
                faces += [[a, b, a + ring_size], [b, b + ring_size, a + ring_size]]
    v_template = np.array(vertices)[:SYNTHETIC_VERTICES]
    weights = np.array(weights)[:SYNTHETIC_VERTICES]
    faces = np.array(faces)
    faces = faces[(faces < SYNTHETIC_VERTICES).all(axis=1)]
    shapedirs = 0.01 * np.sin(v_template @ rng.normal(size=(3, 30)) * 3).reshape(-1, 3, 10)
    regressor = rng.uniform(size=(17, len(v_template))) * (
        rng.uniform(size=(17, len(v_template))) < 0.03
    )
    return BodyAsset(
        v_template=v_template,
        faces=faces,
        shapedirs=shapedirs,
        joint_template=T_POSE_JOINTS,
        joint_shapedirs=0.01 * rng.normal(size=(24, 3, 10)),
        skinning_weights=weights,
        parents=np.array(SMPL_PARENTS),
        joint_names=SMPL_JOINT_NAMES,
        part_labels=weights.argmax(axis=1),
        part_names=SMPL_JOINT_NAMES,
        keypoint_regressor=regressor / regressor.sum(axis=1, keepdims=True),
        source="synthetic benchmark body",
    )


def milliseconds(pair: tuple[float, float]) -> str:
    return f"{pair[0] * 1e3:.2f} ({pair[1] * 1e3:.2f})"


def dense_forward(body: BodyModel, betas, body_pose, global_orient, transl) -> torch.Tensor:
    """The same outputs computed the plain way: all rest vertices, then dense ``W @ A``."""
    rest_joints = body.rest_joints(betas)
    rotations = torch.cat((global_orient.unsqueeze(1), body_pose), dim=1)
    global_rotations, posed_joints = forward_kinematics(rest_joints, rotations, body.parents)
    transforms = skinning_transforms(global_rotations, posed_joints, rest_joints, transl)
    vertices = linear_blend_skinning(body.tpose(betas), transforms, body.skinning_weights)
    return body.keypoint_regressor @ vertices


def body_model_table(body: BodyModel, repeats: int) -> list[str]:
    rows = [
        "| B | forward, no grad: median (best) ms | per body | dense baseline ms "
        "| forward + backward ms | tpose ms |",
        "|---|---|---|---|---|---|",
    ]
    generator = torch.Generator().manual_seed(0)
    for batch in (1, 10, 100):
        betas = torch.randn(batch, body.num_betas, generator=generator)
        body_pose = roma.rotvec_to_rotmat(0.5 * torch.randn(batch, 23, 3, generator=generator))
        global_orient = roma.rotvec_to_rotmat(torch.randn(batch, 3, generator=generator))
        transl = torch.randn(batch, 3, generator=generator)
        with torch.no_grad():
            forward = median_and_best(
                lambda b=betas, p=body_pose, g=global_orient, t=transl: body(b, p, g, t),
                repeats,
                warmups=2,
            )
            dense = median_and_best(
                lambda b=betas, p=body_pose, g=global_orient, t=transl: dense_forward(
                    body, b, p, g, t
                ),
                max(5, repeats // 5),
                warmups=2,
            )
            tpose = median_and_best(lambda b=betas: body.tpose(b), repeats, warmups=2)

        def forward_backward(b=betas, p=body_pose, g=global_orient, t=transl) -> None:
            shape = b.clone().requires_grad_(True)
            pose = p.clone().requires_grad_(True)
            output = body(shape, pose, g, t)
            (output.vertices.sum() + output.keypoints.sum()).backward()

        backward = median_and_best(forward_backward, max(5, repeats // 5), warmups=2)
        rows.append(
            f"| {batch} | {milliseconds(forward)} | {forward[0] / batch * 1e3:.3f} ms "
            f"| {milliseconds(dense)} | {milliseconds(backward)} | {milliseconds(tpose)} |"
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--synthetic", action="store_true", help="a same-size synthetic body")
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--repeats", type=int, default=50, help="timed calls per forward cell")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(
        f"Machine: {platform.processor() or platform.machine()}, {args.threads} torch threads, "
        f"torch {torch.__version__}, Python {platform.python_version()}\n"
    )
    if args.synthetic:
        asset, label = synthetic_asset(), "synthetic body"
    else:
        try:
            asset, label = load_shipped_asset(), "shipped hkpd body"
        except FileNotFoundError as missing:
            print(f"({missing})\nFalling back to --synthetic.\n")
            asset, label = synthetic_asset(), "synthetic body"
    body = BodyModel(asset)
    influences = np.bincount((asset.skinning_weights > 0).sum(axis=1), minlength=8)[1:]
    print(
        f"BodyModel forward, float32, CPU, {label}: {body.num_vertices:,} vertices, "
        f"{body.faces.shape[0]:,} triangles, vertices by joint count 1..7: "
        f"{', '.join(str(int(n)) for n in influences)}\n"
    )
    print("\n".join(body_model_table(body, args.repeats)))


if __name__ == "__main__":
    main()
