"""Time the distribution-prediction network and its training losses on the CPU.

Prints markdown tables (copied into ``docs/network.md``):

1. per-image time of inference (eval mode, no autograd) and of a full training step (forward,
   every loss term with K samples, backward) for backbone widths and both pose heads;
2. where a training step's time goes (backbone, head, losses);
3. the hierarchical head evaluated per depth level (the implementation) versus a plain Python
   loop over the 23 joints with one FC stream each (a reference written here);
4. the body model's cost in the samples loss: the full forward pass (vertices too) versus a
   keypoints-only path built from the public skinning functions.

Usage: ``python benchmarks/bench_network.py [--threads 2] [--repeats 3] [--quick]``.
Timings are the median (and best) of ``--repeats`` calls after one warm-up call.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
from pathlib import Path

import roma
import torch
from torch import nn

from hkpd.body import BodyModel
from hkpd.body.linear_blend_skinning import (
    apply_skinned_readout,
    fold_readout_through_skinning,
    forward_kinematics,
    skinning_transforms,
)
from hkpd.kinematic_tree import BODY_PARENTS, ancestors
from hkpd.network import DistributionNetwork, HierarchicalHead, NetworkConfig
from hkpd.network.hierarchical_head import ancestor_features
from hkpd.network.output_decoding import decode_pose
from hkpd.training.losses import compute_losses
from hkpd.training.schedule import LossWeights

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_network_helpers import make_training_batch
from timing import median_best_and_cpu


def model_table(widths, batches, repeats, samples, body) -> list[str]:
    rows = [
        "| backbone | head | params (M) | B | inference ms/img: wall median (best), CPU "
        "| train step ms/img: wall median (best), CPU |",
        "|---|---|---|---|---|---|",
    ]
    for width in widths:
        for head in ("independent", "hierarchical"):
            torch.manual_seed(0)
            network = DistributionNetwork(NetworkConfig(backbone_base_width=width, pose_head=head))
            params = sum(p.numel() for p in network.parameters()) / 1e6
            for batch_size in batches:
                batch = make_training_batch(body, batch_size, 256, seed=batch_size)

                def infer(network=network, batch=batch):
                    network.eval()
                    with torch.no_grad():
                        network(batch.proxy)

                def train(network=network, batch=batch):
                    network.train()
                    output = network(batch.proxy)
                    terms = compute_losses(output, batch, body, LossWeights(), samples)
                    network.zero_grad(set_to_none=True)
                    terms["total"].backward()

                inference = median_best_and_cpu(infer, repeats)
                training = median_best_and_cpu(train, repeats)
                per = 1e3 / batch_size
                name = "ResNet-18" if width == 64 else f"ResNet-18 × {width / 64:g}"
                rows.append(
                    f"| {name} (base {width}) | {head} | {params:.1f} | {batch_size} "
                    f"| {inference[0] * per:.0f} ({inference[1] * per:.0f}), "
                    f"{inference[2] * per:.0f} "
                    f"| {training[0] * per:.0f} ({training[1] * per:.0f}), "
                    f"{training[2] * per:.0f} |"
                )
                print(rows[-1], file=sys.stderr, flush=True)
    return rows


def breakdown_table(width, batch_size, repeats, samples, body) -> list[str]:
    torch.manual_seed(0)
    network = DistributionNetwork(NetworkConfig(backbone_base_width=width)).train()
    batch = make_training_batch(body, batch_size, 256, seed=1)
    features = network.backbone(batch.proxy).detach()
    output = network.head(features)
    detached = output.detach()

    def backbone():
        network.backbone(batch.proxy).sum().backward()

    def head():
        out = network.head(features)
        (out.F.sum() + out.camera.sum() + out.shape_mean.sum()).backward()

    def losses(weights):
        def run():
            for tensor in detached.tensors():
                tensor.requires_grad_(True)
            compute_losses(detached, batch, body, weights, samples)["total"].backward()

        return run

    stage1 = LossWeights(joints2d_samples=0.0, joints3d_mode=0.0)
    parts = [
        ("backbone forward + backward", backbone),
        ("hierarchical head forward + backward", head),
        ("losses, stage 1 (NLLs, global, 2D mode)", losses(stage1)),
        (f"losses, all terms (2D on K = {samples} samples, 3D)", losses(LossWeights())),
    ]
    rows = [
        f"| part (base {width}, B = {batch_size}) | ms per step: wall median (best) | CPU ms |",
        "|---|---|---|",
    ]
    for name, function in parts:
        median, best, cpu = median_best_and_cpu(function, repeats)
        rows.append(f"| {name} | {median * 1e3:.0f} ({best * 1e3:.0f}) | {cpu * 1e3:.0f} |")
        print(rows[-1], file=sys.stderr, flush=True)
    return rows


class PerJointLoopHead(nn.Module):
    """Reference: the hierarchical pose head with one FC stream per joint, looped in Python."""

    def __init__(self, shared: int, hidden: int) -> None:
        super().__init__()
        self.chains = [list(reversed(ancestors(BODY_PARENTS, j))) for j in range(23)]
        self.streams = nn.ModuleList(
            nn.Sequential(
                nn.Linear(shared + 21 * len(chain), hidden), nn.ReLU(), nn.Linear(hidden, 9)
            )
            for chain in self.chains
        )

    def forward(self, shared: torch.Tensor) -> torch.Tensor:
        F: list[torch.Tensor] = []
        features: list[torch.Tensor] = []
        for joint, stream in enumerate(self.streams):
            inputs = [shared] + [features[a] for a in self.chains[joint]]
            F.append(decode_pose(stream(torch.cat(inputs, dim=-1)), 1.0))
            features.append(ancestor_features(F[-1]))
        return torch.stack(F, dim=1)


def head_table(batch_size, repeats) -> list[str]:
    torch.manual_seed(0)
    hidden, joint_hidden = 512, 256
    head = HierarchicalHead(512, hidden, (joint_hidden,), 10, BODY_PARENTS, 1.0, 1.0, 1.0)
    shared = torch.randn(batch_size, hidden + 32)
    loop = PerJointLoopHead(hidden + 32, joint_hidden)

    def batched():
        head.pose_parameters(shared).square().sum().backward()

    def looped():
        loop(shared).square().sum().backward()

    rows = [
        f"| pose streams, B = {batch_size}, forward + backward | ms: wall median (best) | CPU ms |",
        "|---|---|---|",
    ]
    for name, function in (
        ("per depth level (implementation)", batched),
        ("per joint loop", looped),
    ):
        median, best, cpu = median_best_and_cpu(function, repeats)
        rows.append(f"| {name} | {median * 1e3:.1f} ({best * 1e3:.1f}) | {cpu * 1e3:.1f} |")
        print(rows[-1], file=sys.stderr, flush=True)
    return rows


def keypoints_only(body: BodyModel, folded, betas, body_pose, global_orient) -> torch.Tensor:
    """COCO keypoints without vertices (no pose correctives: the shipped body has none)."""
    rest = body.rest_joints(betas)
    rotations = torch.cat((global_orient.unsqueeze(1), body_pose), dim=1)
    global_rotations, posed = forward_kinematics(rest, rotations, body.parents)
    transforms = skinning_transforms(global_rotations, posed, rest)
    return apply_skinned_readout(folded, betas, transforms)


def body_table(counts, repeats, body) -> list[str]:
    folded = fold_readout_through_skinning(
        body.keypoint_regressor, body.v_template, body.shapedirs, body.skinning_weights
    )
    rows = [
        "| bodies (B × K) | full forward, fwd + bwd: wall ms median (best), CPU ms "
        "| keypoints only, fwd + bwd: wall ms median (best), CPU ms "
        "| max keypoint difference (m) |",
        "|---|---|---|---|",
    ]
    for count in counts:
        generator = torch.Generator().manual_seed(count)
        betas = torch.randn(count, 10, generator=generator).requires_grad_(True)
        rotvecs = torch.randn(count, 23, 3, generator=generator) * 0.3
        pose = roma.rotvec_to_rotmat(rotvecs).requires_grad_(True)
        orient = torch.eye(3).expand(count, 3, 3)

        def full(betas=betas, pose=pose, orient=orient):
            body(betas, pose, orient).keypoints.sum().backward()

        def light(betas=betas, pose=pose, orient=orient):
            keypoints_only(body, folded, betas, pose, orient).sum().backward()

        with torch.no_grad():
            difference = (
                (
                    body(betas, pose, orient).keypoints
                    - keypoints_only(body, folded, betas, pose, orient)
                )
                .abs()
                .max()
                .item()
            )
        full_time = median_best_and_cpu(full, repeats)
        light_time = median_best_and_cpu(light, repeats)
        rows.append(
            f"| {count} | {full_time[0] * 1e3:.1f} ({full_time[1] * 1e3:.1f}), "
            f"{full_time[2] * 1e3:.1f} | {light_time[0] * 1e3:.1f} ({light_time[1] * 1e3:.1f}), "
            f"{light_time[2] * 1e3:.1f} | {difference:.1e} |"
        )
        print(rows[-1], file=sys.stderr, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--samples", type=int, default=8, help="K for the samples loss")
    parser.add_argument("--widths", type=int, nargs="+", default=[64, 32, 16])
    parser.add_argument("--batches", type=int, nargs="+", default=[16, 32])
    parser.add_argument("--quick", action="store_true", help="small widths, B = 16 only")
    args = parser.parse_args()
    if args.quick:
        args.widths, args.batches = [32, 16], [16]
    torch.set_num_threads(args.threads)
    body = BodyModel()
    print(
        f"Machine: {platform.processor() or platform.machine()}, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads, Python {platform.python_version()}, "
        f"{datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC, "
        f"256-px inputs, K = {args.samples}, load average at start "
        f"{os.getloadavg()[0]:.1f}.\n"
    )
    tables = [
        model_table(args.widths, args.batches, args.repeats, args.samples, body),
        breakdown_table(32, 16, args.repeats, args.samples, body),
        head_table(32, max(args.repeats, 5)),
        body_table((16 * args.samples, 32 * args.samples), max(args.repeats, 5), body),
    ]
    for table in tables:
        print("\n".join(table) + "\n")
    print(f"Load average at the end: {os.getloadavg()[0]:.1f}.")


if __name__ == "__main__":
    main()
