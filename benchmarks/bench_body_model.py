"""Benchmark the body model's forward pass (blend shapes, kinematics, skinning, keypoints) on CPU.

Prints a markdown table (paste it into docs/benchmarks.md): for B bodies per call, float32,
the time of ``BodyModel.forward`` without autograd (median and best of the timed calls), the
same work done the plain dense way (``tpose`` + ``linear_blend_skinning`` + regressor) for
comparison, forward + backward with gradients to betas and rotations, and ``tpose`` alone.

It uses the shipped asset (``hkpd/assets/body/hkpd_body.npz``).

Usage: python benchmarks/bench_body_model.py [--threads 2] [--repeats 50]
"""

from __future__ import annotations

import argparse
import platform

import numpy as np
import roma
import torch
from timing import median_and_best

from hkpd.body import BodyModel
from hkpd.body.body_model import load_shipped_asset
from hkpd.body.linear_blend_skinning import (
    forward_kinematics,
    linear_blend_skinning,
    skinning_transforms,
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
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--repeats", type=int, default=50, help="timed calls per forward cell")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(
        f"Machine: {platform.processor() or platform.machine()}, {args.threads} torch threads, "
        f"torch {torch.__version__}, Python {platform.python_version()}\n"
    )
    asset, label = load_shipped_asset(), "shipped hkpd body"
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
