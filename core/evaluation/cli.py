"""``hkpd-eval``: evaluate checkpoints on the fixed synthetic test set and on real photos.

Examples::

    hkpd-eval runs/a/last.pt runs/b/last.pt --poses poses.npz        # synthetic test set
    hkpd-eval runs/a/last.pt --coco ../shared/data/coco_mini --no-synthetic
    hkpd-eval runs/a/last.pt --poses poses.npz --out report.md
    hkpd-eval runs/a/last.pt --poses poses.npz --concentration-scale 0.5 1 2   # calibration
    hkpd-eval runs/a/last.pt --poses poses.npz --coco coco_mini --evidence     # + 2D evidence
    hkpd-eval runs/a/last.pt --poses poses.npz --no-synthetic --multi-view-shape 100  # 5 photos
    hkpd-eval model.pt --poses poses.npz --shape --evidence --coco coco_mini --out run/report.md
    hkpd-eval model.pt --poses poses.npz --no-synthetic --extremities 100 --out run/report.md
    hkpd-eval model.pt --no-synthetic --coco coco_mini --coco-split val2017 --quality  # score

With ``--shape`` (one checkpoint, ``--out`` required) it also scores how well the shape is read
(``docs/shape.md``): on the synthetic test set fed detector-like keypoints and masks, R²
and z² of every shape coefficient, PVE-T, PVE-T-SC (and the mean body's) and the height error;
with ``--coco`` the silhouette IoU of the mode, of the average shape and of BlazePose's mask
against the COCO masks. The numbers go into the report and into ``shape.json`` in the report's
folder (``--out run/report.md`` writes ``run/shape.json``).

With ``--evidence`` every evaluation also scores the keypoint-evidence posterior next to the
network's own (``docs/evidence.md``): on the synthetic test set the evidence is the exact
keypoints with detector-like noise (:mod:`hkpd.synthesis.detector_noise`), on photos it is
BlazePose's, and the occlusion response is measured on photos too (a box around an annotated
forearm or lower leg).

The synthetic test set is 1000 examples (``--count``) rendered from the pose bank's *test*
split (held-out subjects) with a fixed seed, at each network's own input size, so every run of
the command sees exactly the same examples. It prints markdown tables and optionally writes them
to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path

import torch

from hkpd.evaluation.concentration_scaling import ConcentrationScaled
from hkpd.evaluation.report import markdown_table
from hkpd.interrupts import deferred_interrupts, interrupted, raise_if_interrupted

SYNTHETIC_COLUMNS = [
    "mpjpe_sc",
    "mpjpe_pa",
    "pve_t_sc",
    "joint_error_2d_mode",
    "joint_error_2d_samples",
]
EVIDENCE_COLUMNS = [
    "joint_error_2d_mode",
    "joint_error_2d_samples",
    "joint_spread_2d_samples",
    "pose_coverage_50",
    "pose_coverage_90",
    "mpjpe_pa",
    "conditioned",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hkpd-eval", description=__doc__.split("\n\n")[0])
    _add_synthetic_arguments(parser)
    _add_reading_arguments(parser)
    _add_photo_arguments(parser)
    _add_shape_arguments(parser)
    parser.add_argument("--device", default="auto")
    parser.add_argument("--out", type=Path, help="also write the markdown report here")
    parser.add_argument(
        "--figure",
        type=Path,
        help="also draw the synthetic 2D errors (mode vs samples per checkpoint) into this PNG",
    )
    return parser


def _add_synthetic_arguments(parser: argparse.ArgumentParser) -> None:
    """The checkpoints and the synthetic evaluations' arguments."""
    parser.add_argument("checkpoints", nargs="+", type=Path, help="checkpoints to evaluate")
    parser.add_argument("--poses", type=Path, help="pose bank (its test split); else procedural")
    parser.add_argument("--count", type=int, default=1000, help="synthetic test examples")
    parser.add_argument("--samples", type=int, default=25, help="samples per example")
    parser.add_argument(
        "--occlusion-cases",
        type=int,
        default=0,
        help="also measure the occlusion response on this many synthetic images (e.g. 100)",
    )
    parser.add_argument(
        "--concentration-scale",
        type=float,
        nargs="+",
        default=[1.0],
        metavar="FACTOR",
        help="evaluate each checkpoint with every predicted F multiplied by these factors "
        "(post-hoc temperature: < 1 widens the pose distributions, > 1 sharpens them; "
        "synthetic and occlusion evaluations only; default 1, as trained)",
    )
    parser.add_argument(
        "--multi-view-shape",
        type=int,
        default=0,
        metavar="BODIES",
        help="also score shape from 1-5 photos of one person on this many synthetic bodies "
        "(5 renders each: single image, mean and probabilistic combination; e.g. 100; with "
        "--evidence also through the evidence posterior, and with --silhouette-evidence the "
        "person mask too: ~0.3 s a view)",
    )
    parser.add_argument(
        "--extremities",
        type=int,
        default=0,
        metavar="COUNT",
        help="also score the hands and feet on this many synthetic test examples, fitted with "
        "and without BlazePose's hand and foot landmarks (vertex error, uncertainty, 50/90 %% "
        "coverage, wrist/ankle rotations; e.g. 100, ~2 s each; with --out also extremities.json)",
    )
    parser.add_argument("--no-synthetic", action="store_true", help="skip the synthetic set")


def _add_reading_arguments(parser: argparse.ArgumentParser) -> None:
    """Which posteriors and readings are scored."""
    parser.add_argument(
        "--evidence",
        action="store_true",
        help="also evaluate the keypoint-evidence posterior (the predictor's default) next to "
        "the network's own, on every requested set",
    )
    parser.add_argument(
        "--any-orientation",
        action="store_true",
        help="also evaluate on the any-orientation synthetic split (the same test poses, every "
        "view rolled uniformly, 30 %% seen steeply from above or below)",
    )
    parser.add_argument(
        "--upright-reading",
        action="store_true",
        help="also evaluate the network reading people who lean more than 30 degrees from an "
        "upright copy of its input (the predictor's network-only default) on every synthetic "
        "split and on --coco",
    )
    parser.add_argument(
        "--no-mirror-reading",
        action="store_true",
        help="read the photos, the --upright-reading rows and the --evidence rows once, not "
        "also mirrored (by default they are read as the predictor reads them: as they are and "
        "mirrored, keeping the reading whose body fits the shown keypoints better; the plain "
        "synthetic and occlusion rows always read the network once, as the paper does)",
    )
    parser.add_argument(
        "--silhouette-evidence",
        action="store_true",
        help="with --evidence: also score the evidence posterior conditioned on the person mask "
        "too (on --coco photos BlazePose's, Predictor(silhouette_evidence=True); with --shape "
        "the synthetic detector-like masks; docs/shape.md)",
    )


def _add_photo_arguments(parser: argparse.ArgumentParser) -> None:
    """The real-photo evaluations' arguments."""
    parser.add_argument("--coco", type=Path, help="folder with annotations/ and photos (COCO)")
    parser.add_argument(
        "--coco-split",
        help="only the photos of this split (e.g. val2017, when train2017 was used for tuning)",
    )
    parser.add_argument(
        "--coco-turns",
        action="store_true",
        help="with --coco: also score every person on their photo turned by 90, 180 and 270 "
        "degrees (exact quarter turns: people lying on their side and upside down), read as the "
        "predictor reads them (upright copy; with --evidence also the evidence posterior)",
    )
    parser.add_argument(
        "--detector-errors",
        action="store_true",
        help="with --coco: also measure BlazePose against the human keypoints (jitter, misses, "
        "swaps, outliers; the numbers behind the detector-like noise)",
    )
    parser.add_argument(
        "--mask-errors",
        action="store_true",
        help="with --coco: also measure BlazePose's person mask against the COCO masks (IoU, "
        "where it errs, edge offsets; each split apart; docs/shape.md)",
    )
    parser.add_argument(
        "--quality",
        action="store_true",
        help="with --coco: also score the posteriors' quality score against their error (AUROC, "
        "share off among readings scored >= 0.5, reliability table), people read through the "
        "annotated boxes and through the detector's own (docs/prediction.md, 'Quality score')",
    )


def _add_shape_arguments(parser: argparse.ArgumentParser) -> None:
    """The shape evaluation's arguments."""
    parser.add_argument(
        "--shape",
        action="store_true",
        help="also score the shape read (R², z², PVE-T-SC, height; with --coco the silhouette "
        "IoU against the COCO masks) and write shape.json beside --out (one checkpoint)",
    )


def evaluate_synthetic(
    checkpoint: Path,
    poses: Path | None,
    count: int,
    samples: int,
    device,
    concentration_scale: float = 1.0,
    orientation=None,
    upright_reading: bool = False,
    mirror_reading: bool = False,
):
    """Metrics of one checkpoint on the fixed synthetic test set (3D in mm, 2D in px at 256),
    optionally with its F scaled (:mod:`hkpd.evaluation.concentration_scaling`) or on the
    any-orientation split (``orientation``, e.g.
    :data:`hkpd.synthesis.orientation.ANY_ORIENTATION`), optionally reading leaning people from
    an upright copy and reading every view mirrored too (the reading stage:
    :class:`hkpd.prediction.readings.proxy_reader.ProxyReader`)."""
    from hkpd.evaluation.synthetic import evaluate_batches
    from hkpd.evaluation.test_set import fixed_batches, network_and_generator
    from hkpd.prediction.readings import ReadingConfig
    from hkpd.prediction.readings.proxy_reader import ProxyReader

    network, generator = network_and_generator(checkpoint, poses, device, orientation=orientation)
    network = ProxyReader(
        ConcentrationScaled(network, concentration_scale),
        ReadingConfig(mirror=mirror_reading),
        upright=upright_reading,  # its copies framed like the test crops, on all 17 keypoints
        body=generator.body,
    )
    batches = fixed_batches(generator, count)
    size = generator.config.image_size
    metrics = evaluate_batches(
        network, batches, generator.body, samples, pass_crop_keypoints=upright_reading
    )
    return metrics | {"image_size": size}


def _metric_order(name: str) -> tuple[str, int]:
    base, _, count = name.partition("_min_of_")
    return base, int(count) if count else 0


def main(argv: list[str] | None = None) -> int:
    arguments = build_parser().parse_args(argv)
    from hkpd.devices import resolve_device

    try:
        device = resolve_device(arguments.device)
        for checkpoint in arguments.checkpoints:
            if not checkpoint.is_file():
                raise FileNotFoundError(f"checkpoint {checkpoint} does not exist")
        if arguments.poses is not None and not arguments.poses.is_file():
            raise FileNotFoundError(f"pose bank {arguments.poses} does not exist")
        if arguments.figure is not None and arguments.no_synthetic:
            raise ValueError("--figure draws the synthetic results: drop --no-synthetic")
        if arguments.coco_turns and arguments.coco is None:
            raise ValueError("--coco-turns turns the --coco photos: give --coco too")
        if arguments.mask_errors and arguments.coco is None:
            raise ValueError("--mask-errors compares with the --coco masks: give --coco too")
        if arguments.quality and arguments.coco is None:
            raise ValueError("--quality scores the --coco people: give --coco too")
        if arguments.coco is not None and not arguments.coco.is_dir():
            raise FileNotFoundError(f"COCO folder {arguments.coco} does not exist")
        for name in ("count", "samples"):
            if getattr(arguments, name) < 1:
                raise ValueError(f"--{name} must be at least 1, got {getattr(arguments, name)}")
        if arguments.occlusion_cases < 0:
            raise ValueError("--occlusion-cases must be >= 0")
        if arguments.multi_view_shape < 0:
            raise ValueError("--multi-view-shape must be >= 0")
        if arguments.extremities < 0:
            raise ValueError("--extremities must be >= 0")
        for flag, path in (("--out", arguments.out), ("--figure", arguments.figure)):
            if path is not None:
                _check_writable(flag, path)
        if any(not (0 < factor < float("inf")) for factor in arguments.concentration_scale):
            raise ValueError("--concentration-scale factors must be positive numbers")
        if arguments.evidence and arguments.concentration_scale != [1.0]:
            raise ValueError("--evidence and --concentration-scale: use one of them per run")
        if arguments.coco is not None and arguments.concentration_scale != [1.0]:
            raise ValueError(
                "--concentration-scale applies to the synthetic and occlusion evaluations: "
                "evaluate --coco in a separate run without it"
            )
        if arguments.shape:
            _check_shape_arguments(arguments)
    except (FileNotFoundError, ValueError) as error:
        print(f"hkpd-eval: error: {error}", file=sys.stderr)
        return 2
    try:
        with torch.no_grad():
            text, shape = _evaluate(arguments, device)
        raise_if_interrupted()  # a Ctrl-C some library caught during the evaluation
        with deferred_interrupts():  # Ctrl-C waits for the report and shape.json
            print(text)
            if arguments.out:
                _write_atomically(arguments.out, text)
            if shape is not None:
                _write_atomically(shape_json_path(arguments.out), json_text_with_nulls(shape))
    except (OSError, ValueError) as error:  # CheckpointError is a ValueError
        print(f"hkpd-eval: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # during the evaluation; once writing, that finishes first
        return interrupted("hkpd-eval")
    return 0


def _check_writable(flag: str, path: Path) -> None:
    """Fail before a long evaluation, not after it, when ``path`` cannot be written."""
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"{flag} {path} is a folder; give a file name")
    if not folder.is_dir():
        raise FileNotFoundError(f"{flag} {path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise PermissionError(f"{flag} {path} is not writable")


def _write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then rename it (no half files)."""
    partial = path.with_name(path.name + ".partial")
    try:
        partial.write_text(text)
        partial.replace(path)
    except BaseException:  # also Ctrl-C: no half file stays behind
        partial.unlink(missing_ok=True)
        raise


def _check_shape_arguments(arguments: argparse.Namespace) -> None:
    """``--shape`` needs ``--out`` (for ``shape.json``), one checkpoint and F as trained."""
    if arguments.out is None:
        raise ValueError("--shape writes shape.json beside the report: give --out REPORT.md")
    if len(arguments.checkpoints) != 1:
        raise ValueError("--shape scores one checkpoint per run (shape.json holds one model)")
    if arguments.concentration_scale != [1.0]:
        raise ValueError("--shape and --concentration-scale: use one of them per run")
    if arguments.no_synthetic and arguments.coco is None:
        raise ValueError("--shape with --no-synthetic needs --coco (nothing to score)")
    if arguments.out.name == shape_json_path(arguments.out).name:
        raise ValueError("--shape writes shape.json beside --out: name the report otherwise")
    _check_writable("--shape", shape_json_path(arguments.out))


def shape_json_path(report: Path) -> Path:
    """Where ``--shape`` writes its record: ``shape.json`` in the report's folder."""
    return report.with_name("shape.json")


def json_text_with_nulls(record: dict) -> str:
    """``record`` as JSON (shape.json, extremities.json), NaN and infinities (no finite
    value) written as null."""

    def clean(value):
        if isinstance(value, float) and not math.isfinite(value):
            return None
        if isinstance(value, dict):
            return {key: clean(item) for key, item in value.items()}
        if isinstance(value, list):
            return [clean(item) for item in value]
        return value

    return json.dumps(clean(record), indent=2) + "\n"


def _shape_evaluation(arguments: argparse.Namespace, device: torch.device) -> tuple[str, dict]:
    """The ``--shape`` tables and ``shape.json`` record (:mod:`hkpd.evaluation.shape_eval`,
    :mod:`hkpd.evaluation.coco_silhouettes`)."""
    from hkpd.body import BodyModel
    from hkpd.evaluation import shape_report
    from hkpd.evaluation.shape_eval import evaluate_shape_synthetic, silhouette_terms_for
    from hkpd.synthesis.mask_noise import MaskNoise

    checkpoint, mask_noise = arguments.checkpoints[0], MaskNoise()
    mirror, read = _mirror_reading(arguments)
    record: dict = {}
    parts = []
    if not arguments.no_synthetic:
        more_evidence = (
            {"evidence_silhouette": silhouette_terms_for(BodyModel())}
            if arguments.evidence and arguments.silhouette_evidence
            else None
        )
        scores = evaluate_shape_synthetic(
            checkpoint, arguments.poses, arguments.count, device, arguments.evidence,
            mirror_reading=mirror, mask_noise=mask_noise, more_evidence=more_evidence,
        )  # fmt: skip
        record |= {name: score.as_dict() for name, score in scores.items()}
        source = f"pose bank {arguments.poses} (test split)" if arguments.poses else "procedural"
        parts.append(shape_report.shape_markdown(
            scores, f"Shape read on the synthetic test set: {checkpoint}, {arguments.count} "
            f"examples, {source}, detector-like keypoints and masks{read}",
        ))  # fmt: skip
        # The product's posterior (both sexes fitted to detector-like keypoints), whether or
        # not --evidence also asks for the single-prior evidence rows above.
        sexed = _sex_shape_record(arguments, device, mirror)
        record |= sexed
        if sexed:
            parts.append(shape_report.sex_markdown(
                sexed, f"Sex, measurements and stated values: {checkpoint}, {arguments.count} "
                f"bodies drawn half from each sex's prior, {source}, detector-like keypoints",
            ))  # fmt: skip
    if arguments.coco is not None:
        record["coco"] = _coco_silhouette_record(arguments, device)
        parts.append(shape_report.coco_markdown(
            record["coco"], f"Silhouette IoU against the COCO masks: {checkpoint}, "
            f"{arguments.coco}{read}",
        ))  # fmt: skip
    record["settings"] = {
        "checkpoint": str(checkpoint), "count": arguments.count,
        "poses": None if arguments.poses is None else str(arguments.poses),
        "mirror_reading": mirror, "mask_noise": asdict(mask_noise),
    }  # fmt: skip
    return "\n".join(parts), record


def _sex_shape_record(arguments: argparse.Namespace, device: torch.device, mirror: bool) -> dict:
    """:func:`hkpd.evaluation.sex_shape_eval.evaluate_sex_shape` of the checkpoint on
    ``--count`` sex-labelled synthetic bodies (the keys ``sex``, ``measurements``,
    ``stated`` of ``shape.json``)."""
    from hkpd.evaluation.sex_shape_eval import evaluate_sex_shape
    from hkpd.evaluation.test_set import network_and_generator, stored_evidence_settings
    from hkpd.prediction.predictor import float64_body
    from hkpd.prediction.readings import ReadingConfig
    from hkpd.prediction.readings.proxy_reader import ProxyReader

    checkpoint = arguments.checkpoints[0]
    network, generator = network_and_generator(checkpoint, arguments.poses, device)
    if not generator.body.has_sex_priors:
        return {}
    reader = ProxyReader(network, ReadingConfig(mirror=mirror), upright=False, body=generator.body)
    return evaluate_sex_shape(
        reader,
        generator,
        float64_body(generator.body),
        arguments.count,
        stored_evidence_settings(checkpoint),
    )


def _coco_silhouette_record(arguments: argparse.Namespace, device: torch.device) -> dict:
    """:func:`hkpd.evaluation.coco_silhouettes.coco_record` of the checkpoint's posteriors on
    the ``--coco`` people (``--coco-split`` only, when given)."""
    from hkpd.evaluation.coco_silhouettes import coco_record, evaluate_coco_silhouettes
    from hkpd.evaluation.real_photos import load_coco_people
    from hkpd.prediction.predictor import Predictor
    from hkpd.prediction.readings import ReadingConfig

    people = load_coco_people(arguments.coco)
    if arguments.coco_split:
        people = [p for p in people if p.image_path.parent.name == arguments.coco_split]
    mirror, _ = _mirror_reading(arguments)
    predictor = Predictor.from_pretrained(
        arguments.checkpoints[0], device=str(device), reading_config=ReadingConfig(mirror=mirror)
    )
    try:
        posteriors = {"network": False} | ({"evidence": True} if arguments.evidence else {})
        by_posterior = {
            name: evaluate_coco_silhouettes(predictor, people, evidence)
            for name, evidence in posteriors.items()
        }
        if arguments.evidence and arguments.silhouette_evidence:
            predictor.silhouette_evidence = True
            by_posterior["evidence_silhouette"] = evaluate_coco_silhouettes(predictor, people, True)
    finally:
        predictor.close()
    return coco_record(by_posterior)


def _evaluate(arguments: argparse.Namespace, device: torch.device) -> tuple[str, dict | None]:
    """Run the requested evaluations; the markdown report and (``--shape``) the shape record."""
    report = []
    shape = None
    if not arguments.no_synthetic:
        report += _synthetic_report(arguments, device)
        if arguments.evidence:
            report.append(_evidence_synthetic_report(arguments, device))
    if arguments.coco is not None:
        report += _photo_report(arguments, device)
    if arguments.occlusion_cases > 0:
        report.append(_occlusion_report(arguments, device))
    if arguments.multi_view_shape > 0:
        report.append(_multi_view_shape_report(arguments, device))
    if arguments.extremities > 0:
        report.append(_extremity_report(arguments, device))
    if arguments.shape:
        text, shape = _shape_evaluation(arguments, device)
        report.append(text)
    return "\n".join(report), shape


def _synthetic_report(arguments: argparse.Namespace, device: torch.device) -> list[str]:
    """The synthetic tables: every checkpoint (and concentration scale), split and reading."""
    from hkpd.evaluation.test_set import TEST_SET_SEED
    from hkpd.synthesis.orientation import ANY_ORIENTATION

    rows = {
        _row_name(checkpoint, factor, arguments.concentration_scale): evaluate_synthetic(
            checkpoint, arguments.poses, arguments.count, arguments.samples, device, factor
        )
        for checkpoint in arguments.checkpoints
        for factor in arguments.concentration_scale
    }
    splits = {"": None} | ({" (any orientation)": ANY_ORIENTATION}
                           if arguments.any_orientation else {})  # fmt: skip
    readings = [False, True] if arguments.upright_reading else [False]
    for checkpoint in arguments.checkpoints:
        for split, orientation in splits.items():
            for upright in readings:
                if not split and not upright:
                    continue  # the rows above
                mirror = upright and not arguments.no_mirror_reading
                reading = " (upright + mirror reading)" if mirror else " (upright reading)"
                name = f"{checkpoint}{split}" + (reading if upright else "")
                rows[name] = evaluate_synthetic(
                    checkpoint, arguments.poses, arguments.count, arguments.samples,
                    device, orientation=orientation, upright_reading=upright,
                    mirror_reading=mirror,
                )  # fmt: skip
    source = f"pose bank {arguments.poses} (test split)" if arguments.poses else "procedural"
    every = sorted(
        {key for row in rows.values() for key in row} - {"image_size"}, key=_metric_order
    )
    if arguments.figure is not None:
        from hkpd.evaluation.figures import plot_2d_errors

        plot_2d_errors(rows, arguments.figure)
    return [
        f"### Synthetic test set: {arguments.count} examples, {source}, seed "
        f"{TEST_SET_SEED}\n\n" + markdown_table(rows, SYNTHETIC_COLUMNS),
        "All synthetic metrics:\n\n" + markdown_table(rows, every),
    ]


def _evidence_synthetic_report(arguments: argparse.Namespace, device: torch.device) -> str:
    """The network-vs-evidence table on the synthetic test set with detector-like noise."""
    rows = {}
    mirror, read = _mirror_reading(arguments)
    for checkpoint in arguments.checkpoints:
        both = evaluate_evidence_synthetic(
            checkpoint, arguments.poses, arguments.count, arguments.samples, device,
            mirror_reading=mirror,
        )  # fmt: skip
        rows[f"{checkpoint} (network only{read})"] = both["network"]
        rows[f"{checkpoint} (2D evidence{read})"] = both["evidence"]
    return (
        "### Synthetic test set with detector-like keypoint noise: network vs 2D "
        "evidence (calibrated coverage 0.50 / "
        f"{0.885 if arguments.samples == 25 else 0.9})\n\n" + markdown_table(rows, EVIDENCE_COLUMNS)
    )


def _photo_report(arguments: argparse.Namespace, device: torch.device) -> list[str]:
    """The real-photo tables (and the detector's errors, the photos' occlusion response)."""
    from hkpd.evaluation.real_photos import load_coco_people

    people = load_coco_people(arguments.coco)
    if arguments.coco_split:
        people = [p for p in people if p.image_path.parent.name == arguments.coco_split]
        if not people:
            raise SystemExit(f"hkpd-eval: error: no annotated people in split "
                             f"{arguments.coco_split!r} of {arguments.coco}")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="hkpd_turned_") as folder:
        turned = _turned_people(people, Path(folder)) if arguments.coco_turns else {}
        rows, occlusion_rows = _photo_rows(arguments, people, turned, device)
    report = []
    if arguments.detector_errors:
        report.append(_detector_error_table(load_coco_people(arguments.coco, 6), arguments))
    if arguments.mask_errors:
        report.append(_mask_error_report(arguments))
    if arguments.quality:
        report.append(_quality_report(arguments, device))
    columns = list(next(iter(rows.values())))
    report.append(
        f"### Real photos: {arguments.coco} ({len(people)} people with >= 12 visible "
        "keypoints; 2D errors on visible keypoints)\n\n" + markdown_table(rows, columns)
    )
    if occlusion_rows:
        report.append(
            "### Occlusion response on the photos: a box around one annotated forearm or "
            "lower leg\n\n"
            + markdown_table(occlusion_rows, list(next(iter(occlusion_rows.values()))))
        )
    return report


def _quality_report(arguments: argparse.Namespace, device: torch.device) -> str:
    """The quality score against the error on the --coco people, per checkpoint
    (:func:`hkpd.evaluation.quality_data.coco_quality_report`)."""
    from hkpd.evaluation.quality_data import coco_quality_report
    from hkpd.prediction.predictor import Predictor

    parts = []
    for checkpoint in arguments.checkpoints:
        predictor = Predictor.from_pretrained(checkpoint, device=str(device))
        parts.append(coco_quality_report(predictor, arguments.coco, arguments.coco_split))
        predictor.close()
    return "\n\n".join(parts)


def _occlusion_report(arguments: argparse.Namespace, device: torch.device) -> str:
    """The synthetic occlusion-response table of every checkpoint (and evidence posterior)."""
    rows = {
        _row_name(checkpoint, factor, arguments.concentration_scale): occlusion_summary(
            checkpoint, arguments.poses, arguments.occlusion_cases, device, factor
        )
        for checkpoint in arguments.checkpoints
        for factor in arguments.concentration_scale
    }
    if arguments.evidence:
        mirror, read = _mirror_reading(arguments)
        for checkpoint in arguments.checkpoints:
            rows[f"{checkpoint} (2D evidence{read})"] = occlusion_summary(
                checkpoint, arguments.poses, arguments.occlusion_cases, device,
                evidence=True, mirror_reading=mirror,
            )  # fmt: skip
    return (
        f"### Occlusion response: {arguments.occlusion_cases} synthetic test images, one "
        "forearm or lower leg covered by a black box\n\n"
        + markdown_table(rows, list(next(iter(rows.values()))))
    )


def _extremity_report(arguments: argparse.Namespace, device: torch.device) -> str:
    """Hands and feet with and without the landmark term (:mod:`hkpd.evaluation.extremity_eval`)
    for every checkpoint; with ``--out`` the records go to ``extremities.json`` beside it."""
    from hkpd.evaluation import extremity_eval

    mirror, read = _mirror_reading(arguments)
    records, parts = {}, []
    for checkpoint in arguments.checkpoints:
        record = extremity_eval.evaluate_extremity_synthetic(
            checkpoint, arguments.poses, arguments.extremities, arguments.samples, device, mirror
        )
        records[str(checkpoint)] = record
        parts.append(extremity_eval.extremity_markdown(
            record, f"Hands and feet on the synthetic test set: {checkpoint}, keypoints alone "
            f"vs keypoints + hand and foot landmarks (detector-like noise on both{read})",
        ))  # fmt: skip
    if arguments.out is not None:
        written = arguments.out.with_name("extremities.json")
        _write_atomically(written, json_text_with_nulls(records))
    return "\n".join(parts)


def _mirror_reading(arguments: argparse.Namespace) -> tuple[bool, str]:
    """Whether the predictor-like rows read every view mirrored too, and their label suffix."""
    mirror = not arguments.no_mirror_reading
    return mirror, ", mirror reading" if mirror else ""


def _photo_rows(
    arguments: argparse.Namespace, people: list, turned: dict[int, list], device: torch.device
) -> tuple[dict[str, dict[str, float]], dict[str, dict[str, float]]]:
    """The real-photo rows (and occlusion rows, with ``--evidence``) of every checkpoint on
    ``people`` and on the ``turned`` copies of them."""
    from hkpd.evaluation.real_photos import evaluate_photos
    from hkpd.prediction.predictor import Predictor
    from hkpd.prediction.readings import ReadingConfig

    rows, occlusion_rows = {}, {}
    mirror, read = _mirror_reading(arguments)
    for checkpoint in arguments.checkpoints:
        predictor = Predictor.from_pretrained(
            checkpoint, device=str(device), reading_config=ReadingConfig(mirror=mirror)
        )
        if not arguments.evidence:
            rows[f"{checkpoint} (as cropped{read})"] = evaluate_photos(predictor, people)
            if arguments.upright_reading or turned:
                rows[f"{checkpoint} (upright reading{read})"] = evaluate_photos(
                    predictor, people, upright=True
                )
        else:
            from hkpd.evaluation.photo_occlusion import photo_occlusion_response

            kinds = [(False, False, "network only"), (True, False, "2D evidence")]
            if arguments.silhouette_evidence:
                kinds.append((True, True, "2D evidence + person mask"))
            for evidence, silhouette, label in kinds:
                name = f"{checkpoint} ({label}{read})"
                predictor.silhouette_evidence = silhouette
                rows[name] = evaluate_photos(predictor, people, evidence=evidence)
                occlusion_rows[name] = photo_occlusion_response(predictor, people, evidence)
            predictor.silhouette_evidence = False
        for degrees, turned_people in turned.items():
            for evidence in (False, True) if arguments.evidence else (False,):
                label = "2D evidence" if evidence else "network only, read upright"
                rows[f"{checkpoint} (turned {degrees}°, {label}{read})"] = evaluate_photos(
                    predictor, turned_people, evidence=evidence, upright=True
                )
        predictor.close()
    return rows, occlusion_rows


def _turned_people(people: list, folder: Path) -> dict[int, list]:
    """``{degrees: people on their photos turned by it}`` for every quarter turn
    (:mod:`hkpd.evaluation.turned_photos`), the turned photos written to ``folder``."""
    from hkpd.evaluation.turned_photos import QUARTER_TURNS, turned_person

    return {
        degrees: [turned_person(person, degrees, folder) for person in people]
        for degrees in QUARTER_TURNS
    }


def _multi_view_shape_report(arguments: argparse.Namespace, device: torch.device) -> str:
    """The multi-photo shape table of every checkpoint (:mod:`hkpd.evaluation.multi_view_shape`)
    and, with ``--evidence``, the evidence posteriors' tables
    (:mod:`hkpd.evaluation.multi_view_evidence`)."""
    from hkpd.evaluation import multi_view_shape as multi
    from hkpd.evaluation.test_set import network_and_generator

    parts = []
    for checkpoint in arguments.checkpoints:
        network, generator = network_and_generator(checkpoint, arguments.poses, device)
        predictions = multi.predict_multi_view_shapes(
            network.eval(), generator, arguments.multi_view_shape, views=5
        )
        rows = multi.labelled(multi.multi_view_shape_table(predictions, generator.body))
        parts.append(
            f"### Shape from 1-5 photos of one person: {checkpoint}, "
            f"{arguments.multi_view_shape} synthetic bodies x 5 views (test poses, seed "
            f"{multi.MULTI_VIEW_SEED}; every subset of n views)\n\n"
            + markdown_table(rows, list(next(iter(rows.values()))))
        )
        if arguments.evidence:
            parts.append(_multi_view_evidence_report(arguments, checkpoint, network, generator))
    return "\n\n".join(parts)


def _multi_view_evidence_report(
    arguments: argparse.Namespace, checkpoint: Path, network: torch.nn.Module, generator
) -> str:
    """The multi-photo shape tables of the evidence posteriors of one checkpoint (keypoints;
    with ``--silhouette-evidence`` the keypoints and the mask too), the network read as the
    predictor reads."""
    from hkpd.evaluation import multi_view_shape as multi
    from hkpd.evaluation.multi_view_evidence import predict_multi_view_evidence_shapes
    from hkpd.evaluation.shape_eval import no_extra_terms, silhouette_terms_for
    from hkpd.evaluation.test_set import stored_evidence_settings
    from hkpd.prediction.readings import ReadingConfig
    from hkpd.prediction.readings.proxy_reader import ProxyReader

    mirror, read = _mirror_reading(arguments)
    posteriors = {"evidence": no_extra_terms}
    if arguments.silhouette_evidence:
        posteriors["evidence_silhouette"] = silhouette_terms_for(generator.body)
    reader = ProxyReader(
        network.eval(), ReadingConfig(mirror=mirror), upright=False, body=generator.body
    )
    predictions = predict_multi_view_evidence_shapes(
        reader, generator, posteriors, stored_evidence_settings(checkpoint),
        bodies=arguments.multi_view_shape, views=5,
    )  # fmt: skip
    parts = []
    for name, prediction in predictions.items():
        rows = multi.labelled(multi.multi_view_shape_table(prediction, generator.body))
        parts.append(
            f"### Shape from 1-5 photos of one person, {name} posterior: {checkpoint}, "
            f"{arguments.multi_view_shape} synthetic bodies x 5 views, detector-like keypoints "
            f"and masks{read}\n\n" + markdown_table(rows, list(next(iter(rows.values()))))
        )
    return "\n\n".join(parts)


def _detector_error_table(people: list, arguments: argparse.Namespace) -> str:
    """BlazePose against the human keypoints (people with >= 6 visible keypoints)."""
    from hkpd.evaluation.detector_errors import detector_errors
    from hkpd.prediction.detection.keypoint_detector import KeypointDetector

    if arguments.coco_split:
        people = [p for p in people if p.image_path.parent.name == arguments.coco_split]
    detector = KeypointDetector()
    try:
        stats = detector_errors(detector, people)
    finally:
        detector.close()
    summary = {
        "jitter sigma (person size)": stats.sigma,
        "misses": stats.miss_rate,
        "left/right swaps": stats.swap_rate,
        "outliers (> 20 %)": stats.outlier_rate,
        "people": float(stats.people),
        "keypoints": float(stats.keypoints),
    }
    medians = {"median error (person size)": stats.per_keypoint_median}
    return (
        f"### BlazePose against the human keypoints ({arguments.coco_split or 'all splits'})\n\n"
        + markdown_table({"BlazePose": summary}, list(summary))
        + "\n\n"
        + markdown_table(medians, list(stats.per_keypoint_median))
    )


def _mask_error_report(arguments: argparse.Namespace) -> str:
    """BlazePose's mask against the COCO masks, people with >= 6 visible keypoints, each split
    apart (only ``--coco-split`` when given)."""
    from hkpd.evaluation.mask_errors import mask_error_table, split_mask_errors
    from hkpd.evaluation.real_photos import load_coco_people
    from hkpd.prediction.detection.keypoint_detector import KeypointDetector

    everyone = load_coco_people(arguments.coco, 0)
    people = load_coco_people(arguments.coco, 6)
    if arguments.coco_split:
        people = [p for p in people if p.image_path.parent.name == arguments.coco_split]
    with KeypointDetector(segmentation=True) as detector:
        results = split_mask_errors(detector, people, everyone)
    return "### BlazePose's person mask against the COCO masks\n\n" + mask_error_table(results)


def _row_name(checkpoint: Path, factor: float, scales: list[float]) -> str:
    """The checkpoint, plus its concentration scale when more than "as trained" is asked for."""
    if scales == [1.0]:
        return str(checkpoint)
    return f"{checkpoint} (F x {factor:g})"


def occlusion_summary(
    checkpoint: Path,
    poses: Path | None,
    cases: int,
    device,
    concentration_scale: float = 1.0,
    evidence: bool = False,
    mirror_reading: bool = False,
) -> dict:
    """:func:`hkpd.evaluation.occlusion_response.summarise` for one checkpoint (F optionally
    scaled; or the keypoint-evidence posterior, conditioned on the present input keypoints;
    optionally the network reading every view mirrored too, as the predictor does:
    :class:`hkpd.prediction.readings.mirror.MirrorChoosingReader`)."""
    from hkpd.evaluation.occlusion_response import occlusion_response, summarise
    from hkpd.evaluation.test_set import network_and_generator
    from hkpd.prediction.readings import ReadingConfig
    from hkpd.prediction.readings.proxy_reader import ProxyReader
    from hkpd.synthesis.augmentations import AugmentationConfig

    network, generator = network_and_generator(
        checkpoint, poses, device, augmentation=AugmentationConfig.disabled()
    )
    if network.config.image_proxy != "edges":
        raise ValueError(
            f"--occlusion-cases covers limbs in edge images; {checkpoint} reads "
            f"{network.config.image_proxy!r} (evaluate it without --occlusion-cases)"
        )
    scaled = ProxyReader(
        ConcentrationScaled(network, concentration_scale),
        ReadingConfig(mirror=mirror_reading),
        upright=False,
        body=generator.body,
    )
    condition = None
    if evidence:
        from hkpd.evaluation.evidence_synthetic import condition_batch
        from hkpd.evaluation.test_set import stored_evidence_settings
        from hkpd.prediction.predictor import float64_body

        body64 = float64_body(generator.body)
        config = stored_evidence_settings(checkpoint)
        size = generator.config.image_size

        def condition(output, keypoints, present):
            return condition_batch(output, keypoints, present, size, body64, config)[0]

    return summarise(occlusion_response(scaled, generator, cases, condition=condition))


def evaluate_evidence_synthetic(
    checkpoint: Path,
    poses: Path | None,
    count: int,
    samples: int,
    device,
    mirror_reading: bool = False,
) -> dict[str, dict[str, float]]:
    """Network-only and evidence posteriors on the fixed synthetic test set with detector-like
    keypoint noise (:func:`hkpd.evaluation.evidence_synthetic.evaluate_evidence_batches`),
    optionally with the network reading every view mirrored too (the predictor's default)."""
    from hkpd.evaluation.evidence_synthetic import evaluate_evidence_batches
    from hkpd.evaluation.test_set import (
        fixed_batches,
        network_and_generator,
        stored_evidence_settings,
    )
    from hkpd.prediction.readings import ReadingConfig
    from hkpd.prediction.readings.proxy_reader import ProxyReader

    network, generator = network_and_generator(checkpoint, poses, device)
    reader = ProxyReader(
        network, ReadingConfig(mirror=mirror_reading), upright=False, body=generator.body
    )
    batches = fixed_batches(generator, count)
    config = stored_evidence_settings(checkpoint)
    return evaluate_evidence_batches(
        reader, batches, generator.body, config=config, num_samples=samples
    )


if __name__ == "__main__":
    raise SystemExit(main())
