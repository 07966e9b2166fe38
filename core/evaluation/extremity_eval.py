"""Hands and feet on synthetic views, fitted with and without BlazePose's hand and foot landmarks.

Each synthetic example's exact COCO keypoints get detector-like noise
(:func:`hkpd.synthesis.detector_noise.detector_like_keypoints`) and its exact hand and foot
landmarks (the body model's regressors, :mod:`hkpd.body.extremity_landmarks`, projected as the
example's keypoints are) get the landmarks' own (:func:`detector_like_extremities`); a hand's
landmarks count as shown when its wrist keypoint is visible, a foot's with its ankle. Each
example is fitted as the predictor fits a photo (:func:`condition_on_keypoints` from the
network's reading, the stored evidence settings), once with the keypoints alone and once with
the :class:`~hkpd.conditioning.landmark_term.LandmarkTerm` too.

Scored per body part (``hand``, ``fingers``, ``foot``, ``toes``: the body model's ``*_wrist``,
``*_hand``, ``*_ankle``, ``*_foot`` segments) and side, root-aligned in the camera frame
(metres in, centimetres out):

- ``mode_error_cm``: the mode's mean vertex distance to the truth;
- ``uncertainty_cm``: the samples' mean per-vertex distance from their mean;
- ``local_uncertainty_cm``: the same with each sample's wrist (hand, fingers) or ankle (foot,
  toes) joint subtracted first: the spread the hand's or foot's own turn leaves, without where
  the forearm or shin puts the joint;
- ``coverage_50`` / ``coverage_90``: the share of vertices whose truth lies within the samples'
  50 % / 90 % distance from their mean (calibrated: 0.5 / 0.9);

and per wrist and ankle joint: ``rotation_error_deg`` (the mode's relative rotation against the
truth's) and ``rotation_spread_deg`` (the samples' mean angle from the mode). Every number is
given over all sides (``all``) and over the sides whose landmarks were shown (``shown``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator

import torch

from hkpd.body import BodyModel
from hkpd.body.extremity_landmarks import (
    BLAZEPOSE_EXTREMITY_NAMES,
    ExtremityLandmarks,
    extremity_landmarks,
)
from hkpd.conditioning import EvidenceConfig, KeypointEvidence, condition_on_keypoints
from hkpd.conditioning.landmark_term import LandmarkConfig, LandmarkEvidence, LandmarkTerm
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.test_set import fixed_batches, network_and_generator, stored_evidence_settings
from hkpd.kinematic_tree import BODY_JOINT_NAMES, rotation_angle
from hkpd.prediction.predictor import float64_body
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader
from hkpd.synthesis.batch import TrainingBatch
from hkpd.synthesis.detector_noise import (
    DetectorNoise,
    detector_like_extremities,
    detector_like_keypoints,
)

PARTS = {"hand": "wrist", "fingers": "hand", "foot": "ankle", "toes": "foot"}
"""Column -> the body model's part label (``{side}_{label}``)."""

PART_JOINT = {"hand": "wrist", "fingers": "wrist", "foot": "ankle", "toes": "ankle"}
"""Column -> the joint its local uncertainty is measured about (``{side}_{joint}``)."""

JOINTS = ("wrist", "ankle")
SHOWN_BY = (9, 10, 9, 10, 9, 10, 15, 16, 15, 16)
"""COCO keypoint whose visibility stands for each extremity landmark's (wrist, ankle)."""

SIDE_KEYPOINT = {("left", "wrist"): 9, ("right", "wrist"): 10,
                 ("left", "ankle"): 15, ("right", "ankle"): 16}  # fmt: skip
PART_METRICS = ("mode_error_cm", "uncertainty_cm", "local_uncertainty_cm",
                "coverage_50", "coverage_90")  # fmt: skip
JOINT_METRICS = ("rotation_error_deg", "rotation_spread_deg")
EVIDENCE = ("keypoints", "keypoints + landmarks")


def exact_extremity_landmarks(
    body: BodyModel, batch: TrainingBatch, regressor: ExtremityLandmarks
) -> tuple[torch.Tensor, torch.Tensor]:
    """The examples' exact landmarks in the keypoints' crop pixels.

    The true mesh is projected by the example's perspective camera, then mapped into the crop by
    the 2D similarity (scale, rotation, offset; least squares) that takes its projected COCO
    keypoints onto ``batch.keypoints2d``.

    Returns:
        ``(B, L, 2)`` landmarks (``regressor``'s rows) and ``(B,)`` the worst keypoint misfit of
        that mapping, pixels (a check: ~0 when the crop is such a similarity).
    """
    posed = body(batch.betas, batch.body_pose, batch.global_orient)
    origin = posed.joints[:, :1] - batch.joints3d[:, :1]
    points = torch.cat((posed.keypoints, regressor.of_mesh(posed.vertices)), 1) - origin
    plane = (batch.focal_px[:, None, None] * points[..., :2] / points[..., 2:]).double()
    projected = torch.complex(plane[..., 0], plane[..., 1])  # (B, 17 + L)
    target = batch.keypoints2d.double()
    target = torch.complex(target[..., 0], target[..., 1])  # (B, 17)
    keypoints = projected[:, :17]
    centred = keypoints - keypoints.mean(1, keepdim=True)
    scale = (centred.conj() * (target - target.mean(1, keepdim=True))).sum(1) / (
        centred.abs().square().sum(1)
    )
    offset = target.mean(1) - scale * keypoints.mean(1)
    mapped = scale[:, None] * projected + offset[:, None]
    misfit = (mapped[:, :17] - target).abs().amax(1)
    landmarks = torch.stack((mapped.real, mapped.imag), -1)[:, 17:]
    return landmarks.to(batch.keypoints2d.dtype), misfit


def part_vertices(body: BodyModel) -> dict[tuple[str, str], torch.Tensor]:
    """``{(column, side): (n,) long}`` the vertices of each tracked part on each side."""
    return {
        (column, side): torch.nonzero(
            body.part_labels == body.part_names.index(f"{side}_{label}")
        ).flatten()
        for column, label in PARTS.items()
        for side in ("left", "right")
    }


def rotation_angle_deg(first: torch.Tensor, second: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` x2 rotations -> ``(...)`` the angle between them, degrees."""
    return torch.rad2deg(rotation_angle(first, second))


def _centred(body: BodyModel, betas, pose, orient) -> tuple[torch.Tensor, torch.Tensor]:
    """Posed ``(N, V, 3)`` vertices and ``(N, 24, 3)`` joints, the root joint at the origin."""
    out = body(betas, pose, orient.expand(betas.shape[0], 3, 3))
    root = out.joints[:, :1]
    return out.vertices - root, out.joints - root


def example_scores(
    body: BodyModel,
    fitted: BodyDistribution,
    truth: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    samples: int,
    generator: torch.Generator,
) -> dict[tuple[str, str], torch.Tensor]:
    """One example's scores (module docstring) per part and side and per joint and side.

    Args:
        body: float32 body model (any device).
        fitted: one example's posterior (batch of 1 or none; any dtype, CPU).
        truth: the example's ``betas (K,)``, ``body_pose (23, 3, 3)``, ``global_orient (3, 3)``.
        samples: posterior samples drawn (>= 2).
        generator: a CPU generator for the samples.

    Returns:
        ``{(part, side): (5,)}`` in :data:`PART_METRICS` order and ``{(joint, side): (2,)}`` in
        :data:`JOINT_METRICS` order, float32 on the CPU.
    """
    device = body.part_labels.device
    pose_distribution = fitted.pose_distribution()
    drawn_pose = pose_distribution.sample(samples, generator=generator).reshape(samples, 23, 3, 3)
    betas = fitted.sample_betas(samples, generator).reshape(samples, -1)
    mode_pose = pose_distribution.mode.reshape(1, 23, 3, 3)

    def moved(tensor: torch.Tensor) -> torch.Tensor:
        return tensor.to(device=device, dtype=torch.float32)

    orient = moved(fitted.global_orient.reshape(1, 3, 3))
    mode, _ = _centred(body, moved(fitted.shape_mean.reshape(1, -1)), moved(mode_pose), orient)
    drawn, drawn_joints = _centred(body, moved(betas), moved(drawn_pose), orient)
    true_betas, true_pose, true_orient = (moved(t)[None] for t in truth)
    true_vertices, _ = _centred(body, true_betas, true_pose, true_orient)
    scores = {}
    for (column, side), rows in part_vertices(body).items():
        rows = rows.to(device)
        cloud = drawn[:, rows]  # (S, n, 3)
        mean = cloud.mean(0)
        spread = (cloud - mean).norm(dim=-1)  # (S, n)
        radii = spread.quantile(torch.tensor([0.5, 0.9], device=device), dim=0)  # (2, n)
        off = (true_vertices[0, rows] - mean).norm(dim=-1)
        joint = body.joint_names.index(f"{side}_{PART_JOINT[column]}")
        local = cloud - drawn_joints[:, joint, None]
        scores[(column, side)] = torch.stack((
            100 * (mode[0, rows] - true_vertices[0, rows]).norm(dim=-1).mean(),
            100 * spread.mean(),
            100 * (local - local.mean(0)).norm(dim=-1).mean(),
            (off <= radii[0]).float().mean(),
            (off <= radii[1]).float().mean(),
        )).cpu()  # fmt: skip
    for name in JOINTS:
        for side in ("left", "right"):
            joint = BODY_JOINT_NAMES.index(f"{side}_{name}")
            scores[(name, side)] = torch.stack((
                rotation_angle_deg(mode_pose[0, joint], truth[1][joint].to(mode_pose)),
                rotation_angle_deg(drawn_pose[:, joint], mode_pose[0, joint]).mean(),
            )).float().cpu()  # fmt: skip
    return scores


def shown_sides(visible: torch.Tensor) -> dict[tuple[str, str], bool]:
    """``(17,)`` one example's keypoint visibility -> ``{(name, side): shown}`` for every part
    and joint name (a hand's parts and its wrist go with the wrist keypoint, a foot's with the
    ankle)."""
    by_joint = {key: bool(visible[index]) for key, index in SIDE_KEYPOINT.items()}
    names = {**PART_JOINT, **{joint: joint for joint in JOINTS}}
    return {(name, side): by_joint[(side, joint)] for name, joint in names.items()
            for side in ("left", "right")}  # fmt: skip


@torch.no_grad()
def evaluate_extremity_batches(
    network: torch.nn.Module,
    batches: Iterable[TrainingBatch],
    body: BodyModel,
    config: EvidenceConfig | None = None,
    landmark_config: LandmarkConfig | None = None,
    samples: int = 50,
    seed: int = 0,
) -> dict:
    """Hand and foot scores of the evidence posterior without and with the landmark term.

    Args:
        network: reads ``batch.proxy`` into a :class:`BodyDistribution` (eval mode).
        batches: synthetic batches with ground truth.
        body: float32 body model on the network's device.
        config: the evidence settings (the keypoints' sigma and robust scale too).
        landmark_config: the landmark term's sigma scales.
        samples: posterior samples per example (>= 2).
        seed: seeds the detector noise and the samples (the same draws for both fits).

    Returns:
        The record (:func:`summarise`): per evidence (:data:`EVIDENCE`), per subset (``all``,
        ``shown``), per part or joint, each metric's mean; and ``examples``,
        ``landmark_misfit_px``.
    """
    if samples < 2:
        raise ValueError(f"samples must be at least 2 (a spread needs two), got {samples}")
    config = config or EvidenceConfig()
    landmark_config = landmark_config or LandmarkConfig()
    body64 = float64_body(body)
    regressor = extremity_landmarks(body).rows(BLAZEPOSE_EXTREMITY_NAMES)
    regressor64 = extremity_landmarks(body64).rows(BLAZEPOSE_EXTREMITY_NAMES)
    noise = torch.Generator().manual_seed(seed)
    scored: dict[str, list] = {name: [] for name in EVIDENCE}
    misfits, count = [], 0
    for batch in batches:
        size = batch.proxy.shape[-1]
        output = network(batch.proxy)
        detected, reported = detector_like_keypoints(
            batch.keypoints2d.cpu(), batch.visible.cpu(), size, DetectorNoise(), noise
        )
        exact, misfit = exact_extremity_landmarks(body, batch, regressor)
        misfits.append(misfit.cpu())
        shown = batch.visible.cpu()[:, list(SHOWN_BY)]
        landmarks, landmark_reported = detector_like_extremities(exact.cpu(), shown, size, noise)
        for item in range(batch.batch_size):
            start = output.rows(slice(item, item + 1)).detach().to("cpu", torch.float64)
            evidence = KeypointEvidence(detected[item].double(), reported[item], size)
            term = LandmarkTerm(
                LandmarkEvidence(landmarks[item].double(), landmark_reported[item], size),
                regressor64, config.keypoint_sigma, config.robust_scale, landmark_config,
            )  # fmt: skip
            truth = (batch.betas[item], batch.body_pose[item], batch.global_orient[item])
            sides = shown_sides(batch.visible[item].cpu())
            for name, terms in zip(EVIDENCE, ([], [term]), strict=True):
                fit = condition_on_keypoints(body64, start, evidence, config, terms)
                fitted = start if fit.conditioned is None else fit.conditioned
                draws = torch.Generator().manual_seed(seed * 1_000_003 + count)
                scores = example_scores(body, fitted, truth, samples, draws)
                scored[name].append((scores, sides, fit.conditioned is not None))
            count += 1
    record = summarise(scored)
    record["examples"] = count
    record["landmark_misfit_px"] = float(torch.cat(misfits).max()) if misfits else math.nan
    return record


def summarise(scored: dict[str, list]) -> dict:
    """Means of :func:`example_scores` over examples and sides: ``record[evidence][subset]
    [name][metric]`` (NaN where a subset holds no side), and ``record[evidence]["conditioned"]``
    (the share of fits that succeeded)."""
    record: dict = {}
    for evidence, examples in scored.items():
        record[evidence] = {"conditioned": _mean([float(ok) for _, _, ok in examples])}
        for subset in ("all", "shown"):
            table: dict[str, dict[str, float]] = {}
            for name in (*PARTS, *JOINTS):
                metrics = PART_METRICS if name in PARTS else JOINT_METRICS
                rows = [scores[(name, side)] for scores, sides, _ in examples
                        for side in ("left", "right")
                        if subset == "all" or sides[(name, side)]]  # fmt: skip
                values = torch.stack(rows).mean(0).tolist() if rows else [math.nan] * len(metrics)
                table[name] = dict(zip(metrics, values, strict=True)) | {"sides": len(rows)}
            record[evidence][subset] = table
    return record


def _mean(values: list[float]) -> float:
    return sum(values) / len(values) if values else math.nan


def extremity_markdown(record: dict, title: str) -> str:
    """The record as two markdown tables (parts; wrist and ankle rotations) under ``title``."""
    lines = [f"### {title}", "",
             f"{record['examples']} examples; coverage is calibrated at 0.50 / 0.90.", "",
             "| evidence | sides | part | mode error cm | uncertainty cm | about its joint cm "
             "| within 50 % | within 90 % |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for head, row in _table_rows(record, PARTS):
        lines.append(
            f"{head}{row['mode_error_cm']:.1f} | {row['uncertainty_cm']:.1f} | "
            f"{row['local_uncertainty_cm']:.1f} | {row['coverage_50']:.2f} | "
            f"{row['coverage_90']:.2f} |"
        )
    lines += ["", "| evidence | sides | joint | mode rotation error deg | rotation spread deg |",
              "|---|---|---|---|---|"]  # fmt: skip
    for head, row in _table_rows(record, JOINTS):
        lines.append(f"{head}{row['rotation_error_deg']:.1f} | {row['rotation_spread_deg']:.1f} |")
    return "\n".join(lines) + "\n"


def _table_rows(record: dict, names: Iterable[str]) -> Iterator[tuple[str, dict]]:
    """Each table row of ``names`` in ``record``, evidence then subset then name: its first
    three cells (``"| evidence | subset (sides) | name | "``) and its metrics."""
    for evidence in EVIDENCE:
        for subset in ("all", "shown"):
            for name in names:
                row = record[evidence][subset][name]
                yield f"| {evidence} | {subset} ({row['sides']}) | {name} | ", row


def evaluate_extremity_synthetic(
    checkpoint,
    poses,
    count: int,
    samples: int,
    device,
    mirror_reading: bool = False,
    landmark_config: LandmarkConfig | None = None,
) -> dict:
    """:func:`evaluate_extremity_batches` of one checkpoint on the first ``count`` examples of
    the fixed synthetic test set (``hkpd-eval``'s), read as the predictor reads (mirrored too
    when asked), with the checkpoint's stored evidence settings."""
    network, generator = network_and_generator(checkpoint, poses, device)
    reader = ProxyReader(
        network.eval(), ReadingConfig(mirror=mirror_reading), upright=False, body=generator.body
    )
    record = evaluate_extremity_batches(
        reader, fixed_batches(generator, count), generator.body,
        stored_evidence_settings(checkpoint), landmark_config, samples,
    )  # fmt: skip
    record["settings"] = {
        "checkpoint": str(checkpoint), "count": count, "samples": samples,
        "poses": None if poses is None else str(poses), "mirror_reading": mirror_reading,
        "landmark_config": vars(landmark_config or LandmarkConfig()),
    }  # fmt: skip
    return record
