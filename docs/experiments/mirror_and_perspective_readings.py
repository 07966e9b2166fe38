"""Experiment: three ways of reading the shipped network that need no retraining.

On the fixed synthetic test splits (upright and any orientation, read upright as
``hkpd-eval --upright-reading`` does), this script prints the mean 2D mode error (px at 256) of:

1. **Mirrored reading.** The proxy flipped left to right and read, the reading mapped back
   (:mod:`hkpd.prediction.readings.mirror`: heatmaps of left and right eyes, ears and limb
   keypoints swapped; relative rotations of left and right joints swapped and conjugated by the
   reflection ``diag(-1, 1, 1)``, the global rotation conjugated likewise, the camera's x shift
   negated). A mirror-symmetric network would read both equally well.
2. **Mirror-averaged reading.** The mean of the two readings' matrix-Fisher parameters ``F``
   (the family is closed under it; its mode is a weighted mean rotation), their global
   rotations projected back onto SO(3) and their cameras averaged.
3. **Chosen by fit.** Of the reading as it is and the mirrored one, the one whose most likely
   body projects closest to the keypoints the heatmaps show
   (:func:`hkpd.prediction.readings.lean.mode_keypoint_misfits`; no ground truth is used to
   choose; the predictor's default since 2026-12-04,
   :class:`hkpd.prediction.readings.mirror.MirrorChoosingReader`); and the best of the two in
   hindsight.
4. **Perspective projection.** The network's weak-perspective camera ``[s, tx, ty]`` read as a
   perspective camera at the synthetic crop's known focal length (depth ``2 f / (S s)``,
   principal point at the crop centre), and the floor of each camera model: the *true* body with
   its best camera of that model (L-BFGS on the visible keypoints).

    python docs/experiments/mirror_and_perspective_readings.py assets/models/hkpd_hierarchical.pt \\
        --poses poses.npz --count 1000

Results and what they mean: docs/model_history.md, section 5 ("Readings that need no
retraining").
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import roma
import torch
from experiment_arguments import parse_experiment_arguments

from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import CROP_SIZE, ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.test_set import fixed_batches, network_and_generator
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.lean import mode_keypoint_misfits
from hkpd.prediction.readings.mirror import mirror_proxy, unmirror_output
from hkpd.prediction.readings.proxy_reader import ProxyReader
from hkpd.proxy import NUM_KEYPOINTS
from hkpd.proxy.heatmaps import heatmap_peaks
from hkpd.synthesis.orientation import ANY_ORIENTATION


class MirroredReading(torch.nn.Module):
    """``network`` reading the left-right mirror image of its input, mapped back (``average``:
    the mean of that and the reading as it is)."""

    def __init__(self, network: torch.nn.Module, average: bool) -> None:
        super().__init__()
        self.network, self.config, self.average = network, network.config, average

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        mirrored = unmirror_output(self.network(mirror_proxy(proxy)))
        if not self.average:
            return mirrored
        direct = self.network(proxy)
        return replace(
            direct,
            F=(direct.F + mirrored.F) / 2,
            global_orient=roma.special_procrustes(direct.global_orient + mirrored.global_orient),
            camera=(direct.camera + mirrored.camera) / 2,
        )


def perspective_from_weak(
    points: torch.Tensor, camera: torch.Tensor, focal_px: torch.Tensor, size: int
) -> torch.Tensor:
    """``(B, N, 2)`` NDC of ``(B, N, 3)`` pelvis-relative camera-frame points (metres) through
    a perspective camera of focal ``focal_px (B,)`` at ``size`` px, placed where the
    weak-perspective ``camera (B, 3)`` puts the pelvis (depth ``2 f / (size s)``)."""
    scale, shift = camera[:, None, :1], camera[:, None, 1:]
    depth = 2.0 * focal_px[:, None, None] / (size * scale)
    return scale * (points[..., :2] + shift) * depth / (depth + points[..., 2:])


def _visible_mean(pixels: torch.Tensor, batch, scale: float) -> np.ndarray:
    """``(B,)`` mean distance (px at 256) from ``pixels`` to the batch's visible keypoints."""
    error = (pixels.double() - batch.keypoints2d.double()).norm(dim=-1)
    visible = batch.visible.double()
    return ((error * visible).sum(1) / visible.sum(1).clamp(min=1)).numpy() * scale


def best_camera(points, batch, project, start: torch.Tensor, size: int) -> torch.Tensor:
    """``(B, 3)`` the camera of model ``project`` that puts ``points`` (the true body) closest
    to the batch's visible keypoints (L-BFGS from ``start``)."""
    camera = start.clone().requires_grad_(True)
    optimiser = torch.optim.LBFGS([camera], max_iter=60, line_search_fn="strong_wolfe")
    visible = batch.visible.float()

    def closure() -> torch.Tensor:
        optimiser.zero_grad()
        pixels = ndc_to_pixels(project(points, camera), size)
        loss = ((pixels - batch.keypoints2d).pow(2).sum(-1) * visible).sum()
        loss.backward()
        return loss

    with torch.enable_grad():
        optimiser.step(closure)
    return camera.detach()


def _best_camera_error(points, batch, project, start: torch.Tensor, size: int) -> np.ndarray:
    """The floor of one camera model: ``points`` (the true body) with its best camera."""
    camera = best_camera(points, batch, project, start, size)
    with torch.no_grad():
        return _visible_mean(ndc_to_pixels(project(points, camera), size), batch, CROP_SIZE / size)


def _split_errors(checkpoint: Path, poses: Path | None, count: int, orientation) -> dict:
    network, generator = network_and_generator(checkpoint, poses, "cpu", orientation=orientation)
    network.eval()
    body = generator.body
    readers = {
        "as it is": ProxyReader(network, ReadingConfig(mirror=False), body=body),
        "mirrored": ProxyReader(
            MirroredReading(network, average=False), ReadingConfig(mirror=False), body=body
        ),
        "mirror-averaged": ProxyReader(
            MirroredReading(network, average=True), ReadingConfig(mirror=False), body=body
        ),
    }
    columns: dict[str, list[np.ndarray]] = {}

    def add(name: str, values: np.ndarray) -> None:
        columns.setdefault(name, []).append(values)

    with torch.no_grad():
        for batch in fixed_batches(generator, count):
            size = int(batch.proxy.shape[-1])
            scale = CROP_SIZE / size
            peaks, present = heatmap_peaks(batch.proxy[:, -NUM_KEYPOINTS:])
            shown, observed = peaks.double().numpy(), present.numpy()
            misfits, errors = [], []
            for name, reader in readers.items():
                output = reader(batch.proxy, batch.keypoints2d)
                keypoints, _ = pelvis_relative_body(
                    body, output.shape_mean, output.pose_distribution().mode, output.global_orient
                )
                weak = ndc_to_pixels(weak_perspective_project(keypoints, output.camera), size)
                errors.append(_visible_mean(weak, batch, scale))
                add(name, errors[-1])
                misfits.append(mode_keypoint_misfits(output, body, size, shown, observed))
                if name == "as it is":
                    perspective = perspective_from_weak(
                        keypoints, output.camera, batch.focal_px, size
                    )
                    add("as it is, perspective", _visible_mean(
                        ndc_to_pixels(perspective, size), batch, scale))  # fmt: skip
                    start = output.camera
            pair = np.stack(errors[:2])
            add("chosen by fit (as it is | mirrored)", pair[np.argmin(np.stack(misfits[:2]), 0),
                                                          np.arange(pair.shape[1])])  # fmt: skip
            add("best of the two in hindsight", pair.min(0))
            truth, _ = pelvis_relative_body(body, batch.betas, batch.body_pose, batch.global_orient)

            def perspective(points, camera, focal=batch.focal_px, size=size):
                return perspective_from_weak(points, camera, focal, size)

            for name, project in (("weak perspective", weak_perspective_project),
                                  ("perspective", perspective)):  # fmt: skip
                add(f"floor: true body, {name}",
                    _best_camera_error(truth, batch, project, start, size))  # fmt: skip
    return {name: float(np.concatenate(values).mean()) for name, values in columns.items()}


def main(argv: list[str] | None = None) -> int:
    arguments = parse_experiment_arguments(__doc__.splitlines()[0], argv)
    torch.set_num_threads(1)
    splits = {"upright": None, "any orientation": ANY_ORIENTATION}
    results = {
        name: _split_errors(arguments.checkpoint, arguments.poses, arguments.count, orientation)
        for name, orientation in splits.items()
    }
    print(f"mean 2D mode error (px at 256), {arguments.count} examples per split, read upright")
    print("| reading | " + " | ".join(splits) + " | ratio |")
    print("|---|" + "---|" * (len(splits) + 1))
    for row in results["upright"]:
        upright, turned = results["upright"][row], results["any orientation"][row]
        print(f"| {row} | {upright:.2f} | {turned:.2f} | {turned / upright:.2f}x |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
