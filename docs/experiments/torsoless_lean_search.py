"""Experiment: on views whose heatmaps show no torso, choose the lean to read at by how well the
reading fits the keypoints shown.

The upright reading (:mod:`hkpd.prediction.readings`) turns a view with no torso in its
heatmaps by the lean of the network's own reading, read again twice
(:mod:`hkpd.prediction.readings.lean`). On the any-orientation synthetic test split those views
(5 %) stay far off. This script reads each of them at twelve candidate leans (every 30°, 0° =
as it is), maps every reading back to the crop's frame, and keeps the one whose most likely
body projects closest to the observed heatmap peaks (mean pixel distance over the observed
keypoints; no ground truth is used to choose). It prints the mean 2D mode error (px at 256) of:
today's reading, the reading turned by the true lean, the best of the twelve in hindsight, and
the one chosen by fit. The upright reading and the predictor now choose so
(:mod:`hkpd.prediction.readings.lean`; docs/model_history.md, section 5).

    python docs/experiments/torsoless_lean_search.py assets/models/hkpd_hierarchical.pt \\
        --poses poses.npz
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import torch
from experiment_arguments import parse_experiment_arguments

from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import CROP_SIZE, ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.prediction_metrics import evaluate_prediction
from hkpd.evaluation.synthetic import targets_of
from hkpd.evaluation.test_set import fixed_batches, network_and_generator
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader, proxy_reading_input
from hkpd.prediction.readings.upright_view import torso_tilt
from hkpd.proxy import NUM_KEYPOINTS
from hkpd.proxy.heatmaps import heatmap_peaks
from hkpd.synthesis.orientation import ANY_ORIENTATION

CANDIDATE_DEGREES = tuple(range(0, 360, 30))


def _rows_of(targets, rows: list[int]):
    """The targets of ``rows`` only (tensor fields indexed, others kept)."""
    fields = {}
    for field in dataclasses.fields(targets):
        value = getattr(targets, field.name)
        fields[field.name] = value[rows] if torch.is_tensor(value) else value
    return type(targets)(**fields)


def _torsoless_errors(reader: ProxyReader, body, batch) -> tuple[np.ndarray, ...]:
    """``(V,)`` 2D mode errors (px at 256) of the batch's torso-less views: today's reading,
    turned by the true lean, best candidate in hindsight, candidate chosen by fit."""
    peaks, present = heatmap_peaks(batch.proxy[:, -NUM_KEYPOINTS:])
    points, observed = peaks.double().numpy(), present.numpy()
    rows = [i for i in range(len(points)) if torso_tilt(points[i], observed[i]) is None]
    proxy, size = batch.proxy[rows], batch.proxy.shape[-1]
    targets = _rows_of(targets_of(batch), rows)
    scale = CROP_SIZE / size

    def errors_and_misfits(output: BodyDistribution) -> tuple[np.ndarray, np.ndarray]:
        error = evaluate_prediction(output, body, targets, 0, size)["joint_error_2d_mode"]
        keypoints, _ = pelvis_relative_body(
            body, output.shape_mean, output.pose_distribution().mode, output.global_orient
        )
        pixels = ndc_to_pixels(weak_perspective_project(keypoints, output.camera), size).double()
        misfit = [
            float(
                (pixels[k][observed[row]] - peaks[row][observed[row]].double()).norm(dim=-1).mean()
            )
            for k, row in enumerate(rows)
        ]
        return error.double().numpy() * scale, np.array(misfit) * scale

    def read_at(leans: list[float | None]) -> BodyDistribution:
        torsoless = proxy_reading_input(proxy, batch.keypoints2d[rows])
        views = [torsoless.view(k, lean) if lean else None for k, lean in enumerate(leans)]
        return reader.stage.read_views(torsoless, views).chosen()

    if not rows:
        return tuple(np.empty(0) for _ in range(4))
    today = errors_and_misfits(reader(proxy, batch.keypoints2d[rows]))[0]
    truth = [torso_tilt(batch.keypoints2d[row].double().numpy(), np.ones(17, bool)) for row in rows]
    true_lean = errors_and_misfits(read_at(truth))[0]
    scored = [errors_and_misfits(read_at([math.radians(c)] * len(rows))) for c in CANDIDATE_DEGREES]
    errors = np.stack([error for error, _ in scored])
    misfits = np.stack([misfit for _, misfit in scored])
    by_fit = errors[misfits.argmin(0), np.arange(len(rows))]
    return today, true_lean, errors.min(0), by_fit


def main(argv: list[str] | None = None) -> int:
    arguments = parse_experiment_arguments(__doc__.splitlines()[0], argv)
    network, generator = network_and_generator(
        arguments.checkpoint, arguments.poses, "cpu", orientation=ANY_ORIENTATION
    )
    reader, body = (
        ProxyReader(network.eval(), ReadingConfig(mirror=False), body=generator.body),
        generator.body,
    )
    columns: list[list[np.ndarray]] = [[], [], [], []]
    with torch.no_grad():
        for batch in fixed_batches(generator, arguments.count):
            for column, values in zip(columns, _torsoless_errors(reader, body, batch), strict=True):
                column.append(values)
    today = columns[0]
    print(f"{sum(map(len, today))} torso-less views of {arguments.count}; mean 2D mode error (px)")
    print("| today's reading | turned by the true lean | best of 12 leans in hindsight "
          "| the lean that fits the shown keypoints best |")  # fmt: skip
    print("|---|---|---|---|")
    means = [np.concatenate(values).mean() for values in columns]
    print("| " + " | ".join(f"{value:.2f}" for value in means) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
