"""Experiment: where the any-orientation split's 2D error comes from, against the camera's floor.

Reads the fixed synthetic test splits (upright and any orientation) as the predictor reads them
(upright copy for leaning people, mirror reading) and splits the examples by how far the true
torso (hips' midpoint to shoulders' midpoint) points out of the picture: seen from the front or
side (0-20°), at a slant (20-45°), or nearly end-on, from high above or below (45-90°). For each
group it prints the network's mean 2D mode error (px at 256) and the two floors of
``docs/experiments/mirror_and_perspective_readings.py``: the *true* body at its best
weak-perspective camera, and at its best perspective camera (the crop's focal length known).

    python docs/experiments/any_orientation_breakdown.py assets/models/hkpd_hierarchical.pt \\
        --poses poses.npz --count 1000

Results: docs/model_history.md, section 5 ("Where the any-orientation error is").
"""

from __future__ import annotations

import numpy as np
import torch
from experiment_arguments import parse_experiment_arguments
from mirror_and_perspective_readings import _best_camera_error, perspective_from_weak

from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import weak_perspective_project
from hkpd.evaluation.prediction_metrics import evaluate_prediction
from hkpd.evaluation.synthetic import targets_of
from hkpd.evaluation.test_set import fixed_batches, network_and_generator
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader
from hkpd.synthesis.orientation import ANY_ORIENTATION

GROUPS = ((0.0, 20.0), (20.0, 45.0), (45.0, 90.01))
"""Bands of the true torso's angle out of the picture plane, degrees."""


def _split_columns(checkpoint, poses, count: int, orientation) -> dict[str, np.ndarray]:
    """Per example: the network's error, both floors and the torso's out-of-picture angle."""
    network, generator = network_and_generator(checkpoint, poses, "cpu", orientation=orientation)
    network.eval()
    body = generator.body
    reader = ProxyReader(network, ReadingConfig(), body=body)
    columns: dict[str, list[np.ndarray]] = {"network": [], "weak": [], "perspective": [], "out": []}
    with torch.no_grad():
        for batch in fixed_batches(generator, count):
            size = int(batch.proxy.shape[-1])
            output = reader(batch.proxy, batch.keypoints2d)
            metrics = evaluate_prediction(output, body, targets_of(batch), 0, size)
            columns["network"].append(metrics["joint_error_2d_mode"].numpy() * 256.0 / size)
            truth, _ = pelvis_relative_body(body, batch.betas, batch.body_pose, batch.global_orient)
            torso = truth[:, [5, 6]].mean(1) - truth[:, [11, 12]].mean(1)
            out = torch.rad2deg(torch.asin(torso[:, 2].abs() / torso.norm(dim=-1)))
            columns["out"].append(out.numpy())
            columns["weak"].append(
                _best_camera_error(truth, batch, weak_perspective_project, output.camera, size)
            )

            def perspective(points, camera, focal=batch.focal_px, size=size):
                return perspective_from_weak(points, camera, focal, size)

            columns["perspective"].append(
                _best_camera_error(truth, batch, perspective, output.camera, size)
            )
    return {name: np.concatenate(values) for name, values in columns.items()}


def main(argv: list[str] | None = None) -> int:
    arguments = parse_experiment_arguments(__doc__.splitlines()[0], argv)
    torch.set_num_threads(1)
    splits = {"upright": None, "any orientation": ANY_ORIENTATION}
    print(f"mean 2D mode error (px at 256), {arguments.count} examples per split, read as the "
          "predictor reads (upright copy, mirror reading)")  # fmt: skip
    print("| split | true torso out of the picture | examples | network | floor: weak "
          "perspective | floor: perspective | network / weak floor |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for split, orientation in splits.items():
        columns = _split_columns(
            arguments.checkpoint, arguments.poses, arguments.count, orientation
        )
        out = columns["out"]
        bands = [(f"{low:g}-{min(high, 90.0):g}°", (out >= low) & (out < high))
                 for low, high in GROUPS]  # fmt: skip
        for label, chosen in [("all", np.ones_like(out, dtype=bool)), *bands]:
            if not chosen.any():
                continue
            network, weak, perspective = (
                float(columns[name][chosen].mean()) for name in ("network", "weak", "perspective")
            )
            print(f"| {split} | {label} | {int(chosen.sum())} | {network:.2f} | {weak:.2f} | "
                  f"{perspective:.2f} | {network / weak:.2f}x |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
