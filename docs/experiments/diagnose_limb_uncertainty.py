"""Why does covering a limb raise its uncertainty so little? Print docs/model_history.md's
diagnosis (section 3).

For synthetic test images with one limb covered (the occlusion-response protocol of
``hkpd-eval``), two tables, clean vs covered:

1. *Where the limb's spread comes from*: the limb's mean per-vertex uncertainty when only one
   joint along its kinematic chain is sampled (the others held at the mode, mean shape), and
   with every joint sampled. Centimetres, median over images.
2. *Is the spread honest?*: for the limb's two joints (shoulder and elbow, or hip and knee), the
   mode's angular error against the true rotation and the samples' mean angle from the mode.
   Degrees, mean over images. A calibrated model has samples about as far from the mode as the
   truth is. For scale, the last rows give how far the images' true rotations lie from their
   own mean rotation: what a model that knew only the test poses' average would be off by.
3. *How much less concentrated would the hidden limb have to be?*: the covered limb's
   uncertainty ratio (covered / clean, every joint sampled, median over images) when the
   covered image's distributions for the limb's own joints (elbow, wrist, hand or knee, ankle,
   foot) are scaled by a factor (F -> factor * F; 0.25 doubles their angular spread) and its
   ancestors are left as predicted.
4. *Would honest concentrations reach the target?*: for each view (clean, covered) and each
   joint, the factor that maximises the likelihood of the true rotations over these images
   (F -> factor * F, a grid from 0.1 to 2), and the uncertainty ratio when both views use their
   own fitted factors. A diagnosis fitted on the images it reports, not a recipe.

    python docs/experiments/diagnose_limb_uncertainty.py \\
        --model assets/models/hkpd_hierarchical.pt --poses poses.npz --limb left_forearm \\
        [--split val]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import roma
import torch

from hkpd.body import BodyModel
from hkpd.distributions import BodyDistribution
from hkpd.distributions.matrix_fisher import MatrixFisher
from hkpd.evaluation.occlusion_response import (
    LIMB_PARTS,
    OCCLUDED_LIMBS,
    cover_limb,
    limb_vertex_masks,
    sampled_vertex_uncertainty,
)
from hkpd.kinematic_tree import BODY_JOINT_NAMES, BODY_PARENTS
from hkpd.network.checkpoint import load_network
from hkpd.poses import pose_source
from hkpd.proxy import build_proxy_batch
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator, batch_seed

CENTIMETRES_PER_METRE = 100.0
CONCENTRATION_FACTORS = (1.0, 0.5, 0.25, 0.1)
LIKELIHOOD_GRID = (2.0, 1.5, 1.0, 0.7, 0.5, 0.35, 0.25, 0.18, 0.13, 0.1)


def chain_to(joint: str) -> list[str]:
    """The body joints from the first below the pelvis down to ``joint``, root first."""
    chain, index = [], BODY_JOINT_NAMES.index(joint)
    while index >= 0:
        chain.append(BODY_JOINT_NAMES[index])
        index = BODY_PARENTS[index]
    return chain[::-1]


def limb_spread(
    output: BodyDistribution, poses: torch.Tensor, body: BodyModel, mask: torch.Tensor
) -> torch.Tensor:
    """``(B,)`` mean per-vertex uncertainty of the ``mask`` vertices, metres.

    Args:
        output: the network's prediction for B images (mean shape and mode orientation used).
        poses: ``(S, B, 23, 3, 3)`` sampled relative rotations.
        mask: ``(V,)`` bool, the limb's vertices.
    """
    mean_shape = output.shape_mean.expand(poses.shape[0], -1, -1)
    return sampled_vertex_uncertainty(output, poses, mean_shape, body)[:, mask].mean(-1)


def likelihood_factors(F: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """``(J,)`` per joint, the :data:`LIKELIHOOD_GRID` factor k maximising the summed log
    density of the true rotations under ``MatrixFisher(k F)``.

    Args:
        F: ``(B, J, 3, 3)`` predicted parameters.
        truth: ``(B, J, 3, 3)`` true relative rotations.
    """
    grid = torch.tensor(LIKELIHOOD_GRID, dtype=torch.float64)
    log_density = torch.stack(
        [MatrixFisher(k * F.double()).log_prob(truth.double()).sum(0) for k in grid]
    )  # (grid, J)
    return grid[log_density.argmax(0)].to(F.dtype)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=Path("assets/models/hkpd_hierarchical.pt"))
    parser.add_argument("--poses", type=Path, help="pose bank (--split picks subjects)")
    parser.add_argument("--limb", choices=OCCLUDED_LIMBS, default="left_forearm")
    parser.add_argument("--batches", type=int, default=4, help="batches of 16 images")
    parser.add_argument(
        "--split",
        choices=("test", "val"),
        default="test",
        help="the pose bank's subjects to render: test (hkpd-eval's) or val (more varied motion)",
    )
    parser.add_argument("--samples", type=int, default=50)
    args = parser.parse_args()
    torch.set_grad_enabled(False)

    network, _ = load_network(args.model, "cpu")
    config = SyntheticDataConfig(
        image_size=int(network.config.image_size), augmentation=AugmentationConfig.disabled()
    )
    body = BodyModel()
    poses = pose_source(args.poses, args.split)
    generator = SyntheticDataGenerator(poses, config, "cpu", body=body)
    mask = limb_vertex_masks(body)[args.limb]
    side, kind = args.limb.split("_", 1)
    lower_joint = f"{side}_elbow" if kind == "forearm" else f"{side}_knee"
    chain = chain_to(lower_joint)
    own_joints = [BODY_JOINT_NAMES.index(part) for part in LIMB_PARTS[args.limb]]
    scaled_ratios: dict[float, list[torch.Tensor]] = {}
    spreads: dict[tuple[str, str], list[torch.Tensor]] = {}
    angles: dict[tuple[str, str], list[torch.Tensor]] = {}
    truths: list[torch.Tensor] = []
    predicted: dict[str, list[BodyDistribution]] = {"clean": [], "covered": []}
    for batch_index in range(args.batches):
        rendered = generator.generate(16, batch_seed(505, batch_index))
        covered = {item: cover_limb(rendered, item, args.limb) for item in range(16)}
        items = [item for item, result in covered.items() if result is not None]
        proxies = {
            "clean": rendered.batch.proxy[items],
            "covered": build_proxy_batch(
                np.stack([covered[item][0] for item in items]),
                rendered.input_keypoints[items],
                torch.stack([covered[item][1] for item in items]),
                "cpu",
            ),
        }
        truth = rendered.batch.body_pose[items]
        truths.append(truth)
        outputs: dict[str, BodyDistribution] = {}
        for view, proxy in proxies.items():
            output = outputs[view] = network(proxy)
            predicted[view].append(output)
            distribution = output.pose_distribution()
            mode = distribution.mode
            random = torch.Generator().manual_seed(batch_index)
            samples = distribution.sample(args.samples, generator=random)
            spreads.setdefault((view, "all joints"), []).append(
                limb_spread(output, samples, body, mask)
            )
            for joint in chain:
                index = BODY_JOINT_NAMES.index(joint)
                only = mode.expand(args.samples, *mode.shape).clone()
                only[:, :, index] = samples[:, :, index]
                spreads.setdefault((view, joint), []).append(limb_spread(output, only, body, mask))
            for joint in chain[-2:]:
                index = BODY_JOINT_NAMES.index(joint)
                error = roma.rotmat_geodesic_distance(mode[:, index], truth[:, index])
                spread = roma.rotmat_geodesic_distance(
                    samples[:, :, index], mode[None, :, index]
                ).mean(0)
                angles.setdefault((view, f"{joint} mode error"), []).append(error)
                angles.setdefault((view, f"{joint} sample spread"), []).append(spread)
        clean_spread = spreads[("clean", "all joints")][-1]
        covered_pose = outputs["covered"].pose_distribution()
        for factor in CONCENTRATION_FACTORS:
            scaled = covered_pose.scale_concentration(own_joints, factor)
            random = torch.Generator().manual_seed(batch_index)
            samples = scaled.sample(args.samples, generator=random)
            covered_spread = limb_spread(outputs["covered"], samples, body, mask)
            scaled_ratios.setdefault(factor, []).append(covered_spread / clean_spread)

    count = len(torch.cat(spreads[("clean", "all joints")]))
    print(f"{args.limb}, {count} {args.split} images, {args.samples} samples, model {args.model}\n")
    print("| sampled joints | clean (cm) | covered (cm) |\n|---|---|---|")
    for joint in [*chain, "all joints"]:
        clean, hidden = (
            float(torch.cat(spreads[(view, joint)]).median()) * CENTIMETRES_PER_METRE
            for view in ("clean", "covered")
        )
        print(f"| {joint} | {clean:.1f} | {hidden:.1f} |")
    print("\n| joint: measure | clean (deg) | covered (deg) |\n|---|---|---|")
    for name in dict.fromkeys(name for _, name in angles):
        clean, hidden = (
            float(torch.rad2deg(torch.cat(angles[(view, name)])).mean())
            for view in ("clean", "covered")
        )
        print(f"| {name} | {clean:.1f} | {hidden:.1f} |")
    every_truth = torch.cat(truths)
    for joint in chain[-2:]:
        rotations = every_truth[:, BODY_JOINT_NAMES.index(joint)]
        mean_rotation = roma.special_procrustes(rotations.mean(0))
        distance = torch.rad2deg(roma.rotmat_geodesic_distance(rotations, mean_rotation)).mean()
        print(f"| {joint}: true rotations about their mean | {distance:.1f} | (same) |")
    print("\n| covered limb's own joints: F scaled by | uncertainty ratio, median |\n|---|---|")
    for factor, ratios in scaled_ratios.items():
        print(f"| {factor:g} | {float(torch.cat(ratios).median()):.2f} |")

    fitted = {
        view: likelihood_factors(torch.cat([o.F for o in outs]), every_truth)
        for view, outs in predicted.items()
    }
    spread_fitted: dict[str, list[torch.Tensor]] = {"clean": [], "covered": []}
    every_joint = torch.ones(len(BODY_PARENTS), dtype=torch.bool)
    for view, outs in predicted.items():
        for batch_index, output in enumerate(outs):
            factor = fitted[view].expand(len(output.F), -1)
            scaled = output.pose_distribution().scale_concentration(every_joint, factor)
            random = torch.Generator().manual_seed(batch_index)
            samples = scaled.sample(args.samples, generator=random)
            spread_fitted[view].append(limb_spread(output, samples, body, mask))
    ratio = torch.cat(spread_fitted["covered"]) / torch.cat(spread_fitted["clean"])
    print("\n| likelihood-fitted factor | clean | covered |\n|---|---|---|")
    for joint in [*chain, *LIMB_PARTS[args.limb][1:]]:
        index = BODY_JOINT_NAMES.index(joint)
        print(f"| {joint} | {fitted['clean'][index]:g} | {fitted['covered'][index]:g} |")
    print("\n| concentrations | uncertainty ratio, median |\n|---|---|")
    print(f"| as predicted | {float(torch.cat(scaled_ratios[1.0]).median()):.2f} |")
    print(f"| likelihood-fitted, each view its own | {float(ratio.median()):.2f} |")


if __name__ == "__main__":
    main()
