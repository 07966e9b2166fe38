"""How much of the synthetic 2D error no weak-perspective network can remove, by kind of view.

The synthetic crops are rendered through a perspective camera (``SYNTHETIC_FOCAL_PX`` = 300 px
at a 256 crop, a person about 2.5 m away), while the network answers with a weak-perspective
camera. For every view of ``hkpd-eval``'s fixed test sets (upright and any orientation), this
poses the *true* body with its true rotation, fits the best weak-perspective scale and shift to
the visible keypoints (least squares), and reports that floor next to the network's own mode
error (read upright, as ``hkpd-eval --upright-reading`` does), per kind of view: no torso in the
heatmaps, body axis more than 40° out of the picture (steep), the rest. docs/model_history.md,
section 5.

    python docs/experiments/weak_perspective_floor.py assets/models/hkpd_hierarchical.pt \\
        --poses poses.npz
"""

from __future__ import annotations

import math

import numpy as np
import torch
from experiment_arguments import parse_experiment_arguments

from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import CROP_SIZE, pixels_to_ndc
from hkpd.evaluation.prediction_metrics import evaluate_prediction
from hkpd.evaluation.synthetic import targets_of
from hkpd.evaluation.test_set import fixed_batches, network_and_generator
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader
from hkpd.prediction.readings.upright_view import torso_tilt
from hkpd.proxy import NUM_KEYPOINTS
from hkpd.proxy.heatmaps import heatmap_peaks
from hkpd.synthesis.batch import TrainingBatch
from hkpd.synthesis.orientation import ANY_ORIENTATION

STEEP_DEGREES = 40.0
"""A view is steep when the body's up axis leaves the picture plane by more than this."""


def weak_perspective_floor(batch: TrainingBatch, body) -> torch.Tensor:
    """``(B,)`` mean 2D error (px at 256) of the true body under its best weak-perspective
    camera (scale and shift fitted to the visible keypoints); NaN with fewer than 3 visible."""
    keypoints, _ = pelvis_relative_body(body, batch.betas, batch.body_pose, batch.global_orient)
    points = keypoints[..., :2].double()
    targets = pixels_to_ndc(batch.keypoints2d, batch.proxy.shape[-1]).double()
    floors = torch.full((len(points),), float("nan"), dtype=torch.float64)
    for index, visible in enumerate(batch.visible):
        if int(visible.sum()) < 3:
            continue
        seen, wanted = points[index][visible], targets[index][visible]
        design = torch.zeros(2 * len(seen), 3, dtype=torch.float64)
        design[0::2, 0], design[0::2, 1] = seen[:, 0], 1.0
        design[1::2, 0], design[1::2, 2] = seen[:, 1], 1.0
        scale, shift_u, shift_v = torch.linalg.lstsq(design, wanted.reshape(-1, 1)).solution[:, 0]
        fitted = seen * scale + torch.stack((shift_u, shift_v))
        floors[index] = (fitted - wanted).norm(dim=-1).mean() * (CROP_SIZE / 2)
    return floors


def view_kinds(batch: TrainingBatch) -> list[str]:
    """Per example: ``"no torso"`` (the reading has no lean from the heatmaps), ``"steep"`` or
    ``"rest"``."""
    peaks, present = heatmap_peaks(batch.proxy[:, -NUM_KEYPOINTS:])
    out_of_plane = torch.rad2deg(torch.asin(batch.global_orient[:, 2, 1].abs().clamp(max=1.0)))
    kinds = []
    for index in range(len(peaks)):
        if torso_tilt(peaks[index].double().numpy(), present[index].numpy()) is None:
            kinds.append("no torso")
        elif float(out_of_plane[index]) > STEEP_DEGREES:
            kinds.append("steep")
        else:
            kinds.append("rest")
    return kinds


def main(argv: list[str] | None = None) -> int:
    arguments = parse_experiment_arguments(__doc__.splitlines()[0], argv)
    torch.manual_seed(0)
    print("| split | views | share | floor: true body, best weak-perspective camera (px) "
          "| network, read upright (px) | network's own part (px, in quadrature) |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for split, orientation in (("upright", None), ("any orientation", ANY_ORIENTATION)):
        network, generator = network_and_generator(
            arguments.checkpoint, arguments.poses, "cpu", orientation=orientation
        )
        reader = ProxyReader(network.eval(), ReadingConfig(mirror=False), body=generator.body)
        floors, errors, kinds = [], [], []
        with torch.no_grad():
            for batch in fixed_batches(generator, arguments.count):
                output = reader(batch.proxy, crop_keypoints=batch.keypoints2d)
                size = batch.proxy.shape[-1]
                mode_error = evaluate_prediction(
                    output, generator.body, targets_of(batch), 0, size
                )["joint_error_2d_mode"]
                errors.append(mode_error.double() * (CROP_SIZE / size))
                floors.append(weak_perspective_floor(batch, generator.body))
                kinds += view_kinds(batch)
        floor, error = torch.cat(floors).numpy(), torch.cat(errors).numpy()
        labels = np.array(kinds)
        for kind in ("all", "no torso", "steep", "rest"):
            chosen = np.ones(len(labels), bool) if kind == "all" else labels == kind
            if not chosen.any():
                continue
            mean_floor, mean_error = np.nanmean(floor[chosen]), np.nanmean(error[chosen])
            own = math.sqrt(max(mean_error**2 - mean_floor**2, 0.0))
            print(f"| {split} | {kind} | {chosen.mean():.1%} | {mean_floor:.2f} | "
                  f"{mean_error:.2f} | {own:.1f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
