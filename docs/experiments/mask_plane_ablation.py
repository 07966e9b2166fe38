"""Does an edges+mask network read its mask plane? (issue 41, item 3; docs/shape.md, section 4)

On the fixed synthetic test set (``hkpd-eval``'s, seed 2021, the pose bank's test subjects), the
network alone (one reading per view, no mirror) reads each example three ways:

- **as trained**: the mask plane the generator makes (the rendered silhouette degraded by
  ``MaskNoise``, unknown where the occlusion augmentations hid the body);
- **blank**: the mask plane all zero (what it reads when no mask is known);
- **exact**: the rendered silhouette itself (known pixels only), no degradation: how much a
  perfect segmenter would give.

For each it prints the shape scores (``hkpd.evaluation.shape_metrics``: R² per coefficient,
PVE-T-SC, height error; the pose is scored by ``hkpd-eval``). If blanking the plane changes
nothing, the network does not read it.

    python docs/experiments/mask_plane_ablation.py RUN/last.pt --poses poses.npz --count 300
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from hkpd.evaluation.shape_eval import rendered_test_set
from hkpd.evaluation.shape_metrics import shape_scores
from hkpd.evaluation.test_set import network_and_generator

MASK_CHANNEL = 1
"""The ``"edges+mask"`` proxy's person-probability plane (after the edges, before the heatmaps)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--poses", type=Path, required=True)
    parser.add_argument("--count", type=int, default=300)
    args = parser.parse_args()
    torch.set_num_threads(2)
    network, generator = network_and_generator(args.checkpoint, args.poses, "cpu")
    if network.config.image_proxy != "edges+mask":
        raise SystemExit(f"{args.checkpoint} reads {network.config.image_proxy!r}, no mask plane")
    readings = ("as trained", "blank", "exact")
    means: dict[str, list[torch.Tensor]] = {name: [] for name in readings}
    stds: dict[str, list[torch.Tensor]] = {name: [] for name in readings}
    truth = []
    for rendered in rendered_test_set(generator, args.count):
        batch = rendered.batch
        exact = ((rendered.part_map >= 0) & ~rendered.occluded).to(batch.proxy.dtype)
        planes = {
            "as trained": batch.proxy[:, MASK_CHANNEL],
            "blank": torch.zeros_like(batch.proxy[:, MASK_CHANNEL]),
            "exact": exact,
        }
        for name, plane in planes.items():
            proxy = batch.proxy.clone()
            proxy[:, MASK_CHANNEL] = plane
            with torch.no_grad():
                output = network(proxy)
            shape = output.shape_distribution()
            means[name].append(shape.mean.double())
            stds[name].append(shape.stddev.double())
        truth.append(batch.betas.double())
    true = torch.cat(truth)
    body = generator.body.double()
    print(f"{true.shape[0]} test examples, {args.checkpoint}")
    print("| mask plane | R² β₀ | mean R² β₁…β₉ | R² β₁, β₂, β₃ | PVE-T-SC mm | mean body mm "
          "| height error mm |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for name in readings:
        scores = shape_scores(body, torch.cat(means[name]), torch.cat(stds[name]), true)
        r2 = np.array(scores.r2)
        print(f"| {name} | {r2[0]:.3f} | {r2[1:].mean():.3f} | {np.round(r2[1:4], 3).tolist()} "
              f"| {scores.pve_t_sc_mm:.2f} | {scores.mean_body_pve_t_sc_mm:.2f} "
              f"| {scores.height_error_mm:.1f} |")  # fmt: skip


if __name__ == "__main__":
    main()
