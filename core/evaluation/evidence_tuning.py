"""``hkpd-tune-evidence``: score settings of the evidence posterior on *tuning* data only.

The evidence posterior (``docs/evidence.md``) has a few numbers (:class:`EvidenceConfig`) that
depend on how over- or under-confident a network is: the prior weight ``w``, the keypoint
``sigma`` and the per-joint ``spread``. After retraining they should be chosen again, on data
that is not reported: photos of one COCO split (``--coco-split train2017``; report on another)
and the pose bank's *validation* subjects (the reported synthetic numbers use the *test*
subjects). Each setting gets one row:

- ``mode / detector``: the evidence mode's 2D error over the detector's own on the photos
  (what a user sees: how far the drawn body is from the person's joints);
- ``samples / mode``: the photos' samples error over the mode error (how much the drawn samples
  scatter; 1 means they all sit on the mode);
- ``covered limb``: median uncertainty ratio of a forearm or lower leg covered by a box on the
  photos (:func:`photo_occlusion_response`; it should rise well above 1);
- ``photos: 2D coverage 50 / 90``: share of the photos' annotated keypoints inside the disc
  about the mode's projection that holds 50 % / 90 % of 25 samples' projections (calibrated:
  0.50 / 0.885; below that the drawn samples claim more certainty than the photos bear out);
- ``coverage 50 / 90``: share of true joint rotations inside the posterior's 50 % / 90 %
  regions on synthetic validation images with detector-like keypoint noise (calibrated:
  0.50 / 0.885 at 25 samples), and the synthetic mode error.

Example::

    hkpd-tune-evidence assets/models/hkpd_hierarchical.pt --poses poses.npz \\
        --coco ../shared/data/coco_mini --coco-split train2017 \\
        --setting w=0.2,sigma=0.03 --setting w=0.3,sigma=0.03,spread=marginal
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import torch

from hkpd.conditioning import EvidenceConfig
from hkpd.evaluation.report import markdown_table

VALIDATION_SET_SEED = 1234
"""Seed of the synthetic validation images (the test set's is ``hkpd-eval``'s 2021)."""

SETTING_KEYS = {
    "w": "prior_weight",
    "prior_weight": "prior_weight",
    "sigma": "keypoint_sigma",
    "keypoint_sigma": "keypoint_sigma",
    "robust": "robust_scale",
    "robust_scale": "robust_scale",
    "spread": "joint_spread",
    "joint_spread": "joint_spread",
}
"""Names accepted in ``--setting`` and the :class:`EvidenceConfig` field each one sets."""

TUNING_COLUMNS = {
    "mode_over_detector": "photos: mode / detector",
    "samples_over_mode": "photos: samples / mode",
    "covered_limb_ratio": "photos: covered limb ratio (median)",
    "photo_coverage_50": "photos: 2D coverage 50 %",
    "photo_coverage_90": "photos: 2D coverage 90 %",
    "coverage_50": "synthetic val: coverage 50 %",
    "coverage_90": "synthetic val: coverage 90 %",
    "synthetic_mode_px": "synthetic val: mode (px)",
}
"""The row's columns and their headers."""


def parse_setting(text: str) -> EvidenceConfig:
    """``"w=0.2,sigma=0.03,spread=conditional"`` -> that :class:`EvidenceConfig` (the defaults
    for what is not named).

    Raises:
        ValueError: an unknown name, a malformed pair, or a value the config refuses.
    """
    values: dict[str, float | str] = {}
    for pair in filter(None, (part.strip() for part in text.split(","))):
        name, separator, value = pair.partition("=")
        field = SETTING_KEYS.get(name.strip())
        if not separator or field is None:
            raise ValueError(
                f"setting {text!r}: expected name=value pairs with names among "
                f"{', '.join(sorted(set(SETTING_KEYS)))}; got {pair!r}"
            )
        if field == "joint_spread":
            values[field] = value.strip()
        else:
            try:
                values[field] = float(value)
            except ValueError as error:
                message = f"setting {text!r}: {name} must be a number, got {value!r}"
                raise ValueError(message) from error
    return replace(EvidenceConfig(), **values)


def describe(config: EvidenceConfig) -> str:
    """A row name: the tuned numbers of ``config``."""
    return (
        f"w {config.prior_weight:g}, sigma {config.keypoint_sigma:g}, "
        f"robust {config.robust_scale:g}, {config.joint_spread}"
    )


def score_setting(
    predictor,
    people: list,
    network: torch.nn.Module,
    validation_batches: list,
    body,
    config: EvidenceConfig | None,
    samples: int = 25,
) -> dict[str, float]:
    """One row of the tuning table.

    Args:
        predictor: a :class:`hkpd.prediction.Predictor` of the checkpoint (its
            ``evidence_config`` is set to ``config`` and left so).
        people: the tuning photos' annotated people
            (:func:`hkpd.evaluation.real_photos.load_coco_people`).
        network: the same checkpoint's network (eval mode), for the synthetic images.
        validation_batches: synthetic batches of the validation subjects.
        body: the body model on the network's device (float32).
        config: the evidence setting; None scores the network's own posterior (read upright
            when the person leans, the predictor's network-only default).
        samples: samples per synthetic example (25: calibrated coverage 0.50 / 0.885).

    Returns:
        The :data:`TUNING_COLUMNS` values (NaN where nothing could be scored).
    """
    from hkpd.evaluation.evidence_synthetic import evaluate_evidence_batches
    from hkpd.evaluation.photo_occlusion import photo_occlusion_response
    from hkpd.evaluation.real_photos import evaluate_photos

    evidence = config is not None
    if evidence:
        predictor.evidence_config = config
    photos = evaluate_photos(
        predictor, people, evidence=evidence, upright=True, show_progress=False
    )
    occlusion = photo_occlusion_response(predictor, people, evidence, show_progress=False)
    synthetic = evaluate_evidence_batches(
        network, validation_batches, body, config, num_samples=samples
    )["evidence" if evidence else "network"]
    mode = photos["joint_error_2d_mode"]
    return {
        "mode_over_detector": mode / photos["joint_error_2d_detector"],
        "samples_over_mode": photos["joint_error_2d_samples"] / mode,
        "covered_limb_ratio": occlusion.get("occlusion_ratio_median", math.nan),
        "photo_coverage_50": photos["keypoint_coverage_2d_50"],
        "photo_coverage_90": photos["keypoint_coverage_2d_90"],
        "coverage_50": synthetic["pose_coverage_50"],
        "coverage_90": synthetic["pose_coverage_90"],
        "synthetic_mode_px": synthetic["joint_error_2d_mode"],
    }


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hkpd-tune-evidence", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("checkpoint", type=Path, help="the network whose evidence is tuned")
    parser.add_argument("--coco", type=Path, required=True, help="COCO folder of tuning photos")
    parser.add_argument(
        "--coco-split",
        help="only this split's photos (e.g. train2017; keep the split you report out)",
    )
    parser.add_argument(
        "--poses", type=Path, help="pose bank (its validation split); else procedural"
    )
    parser.add_argument("--count", type=int, default=100, help="synthetic validation images")
    parser.add_argument("--samples", type=int, default=25, help="samples per synthetic image")
    parser.add_argument(
        "--setting",
        action="append",
        default=[],
        metavar="NAME=VALUE,...",
        help="one evidence setting to score (repeat; names: w, sigma, robust, spread; "
        "the defaults for what is not named); default: the shipped defaults",
    )
    parser.add_argument(
        "--no-network-row", action="store_true", help="leave out the network-only row"
    )
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, help="also write the markdown table here")
    parser.add_argument(
        "--write-to",
        type=Path,
        metavar="CHECKPOINT",
        help="store the one --setting given in a copy of the checkpoint written here (may be "
        "the checkpoint itself): Predictor.from_pretrained then uses it",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    arguments = parser.parse_args(argv)
    try:
        configs = [parse_setting(text) for text in arguments.setting] or [EvidenceConfig()]
        for path, what in ((arguments.checkpoint, "checkpoint"), (arguments.poses, "pose bank")):
            if path is not None and not path.is_file():
                raise FileNotFoundError(f"{what} {path} does not exist")
        if not arguments.coco.is_dir():
            raise FileNotFoundError(f"COCO folder {arguments.coco} does not exist")
        if arguments.count < 1 or arguments.samples < 2:
            raise ValueError("--count must be >= 1 and --samples >= 2")
        if arguments.write_to is not None and len(arguments.setting) != 1:
            raise ValueError("--write-to stores one setting: give exactly one --setting")
        table = run_tuning(arguments, configs)
        if arguments.write_to is not None:
            from hkpd.network.checkpoint import store_evidence_config

            store_evidence_config(arguments.checkpoint, arguments.write_to, configs[0].to_dict())
            table += f"\n\nStored {describe(configs[0])} in {arguments.write_to}."
    except (FileNotFoundError, ValueError) as error:
        print(f"hkpd-tune-evidence: error: {error}", file=sys.stderr)
        return 2
    print(table)
    if arguments.out is not None:
        arguments.out.parent.mkdir(parents=True, exist_ok=True)
        arguments.out.write_text(table + "\n")
    return 0


def run_tuning(arguments: argparse.Namespace, configs: list[EvidenceConfig]) -> str:
    """The markdown tuning table of every setting (and the network's own, first)."""
    from tqdm import tqdm

    from hkpd.devices import resolve_device
    from hkpd.evaluation.real_photos import load_coco_people
    from hkpd.evaluation.test_set import fixed_batches, network_and_generator
    from hkpd.prediction.predictor import Predictor

    people = load_coco_people(arguments.coco)
    if arguments.coco_split:
        people = [p for p in people if p.image_path.parent.name == arguments.coco_split]
    if not people:
        raise ValueError(
            f"no annotated people (>= 12 visible keypoints) in {arguments.coco}"
            + (f", split {arguments.coco_split!r}" if arguments.coco_split else "")
        )
    device = resolve_device(arguments.device)
    network, generator = network_and_generator(
        arguments.checkpoint, arguments.poses, device, split="val"
    )
    body = generator.body
    batches = list(fixed_batches(generator, arguments.count, VALIDATION_SET_SEED))
    predictor = Predictor(network, device, body=body)
    rows: dict[str, dict[str, float]] = {}
    settings: list[EvidenceConfig | None] = list(configs)
    if not arguments.no_network_row:
        settings.insert(0, None)
    try:
        for setting in tqdm(settings, unit="setting", desc="hkpd-tune-evidence"):
            name = "network only" if setting is None else describe(setting)
            row = score_setting(
                predictor, people, network, batches, body, setting, arguments.samples
            )
            rows[name] = {TUNING_COLUMNS[key]: value for key, value in row.items()}
    finally:
        predictor.close()
    header = (
        f"### Evidence settings of {arguments.checkpoint} on tuning data: {len(people)} people "
        f"of {arguments.coco} ({arguments.coco_split or 'all splits'}), {arguments.count} "
        f"synthetic images of the validation subjects ({arguments.samples} samples each)\n\n"
    )
    return header + markdown_table(rows, list(TUNING_COLUMNS.values()))


if __name__ == "__main__":
    raise SystemExit(main())
