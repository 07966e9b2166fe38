"""``hkpd-predict``: 3D body distributions from photos, written to files.

Usage::

    hkpd-predict IMAGE_OR_DIR... --out DIR [--model PATH] [--samples 10]
                 [--format ply|glb|obj|npz ...] [--bbox X0 Y0 X1 Y1] [--device auto] [--seed 0]
                 [--uncertainty-samples 100] [--same-person] [--silhouette-evidence] [--overwrite]
                 [--sex female|male] [--height M [STD]] [--mass KG [STD]] [--chest M [STD]]
                 [--waist M [STD]] [--hip M [STD]] [--shoulder-width M [STD]] [--resume] [-v]
    torchrun --standalone --nproc_per_node N --no-python hkpd-predict PHOTOS... --out DIR

``--sex`` and the measurement flags state what is known of the person
(:mod:`hkpd.body_flags`); they condition the shape of every photo (and so of the
combined shape) and need the evidence posterior.

Folders are searched recursively for images (by extension), in sorted order. For every photo
it writes into ``DIR/<image stem>/``:

- ``mode.<fmt>``: the most likely body, one per mesh format asked for;
- ``samples/sample_000.<fmt>`` ...: ``--samples`` bodies drawn from the posterior;
- ``mode_uncertainty.<fmt>``: the mode with per-vertex uncertainty as vertex colours;
- ``prediction.npz`` (with ``npz`` in ``--format``): distribution parameters and all vertices;
- ``summary.json``: image, detected person, crop, keypoints, uncertainty, the reading's
  ``"quality": {"score": s, "flags": [...]}`` (:mod:`hkpd.prediction.quality`), the sex's
  probabilities, the measurements with stds and what was stated
  (:mod:`hkpd.prediction.exports.body_summary`), files, timings;
- ``overview.png``: photo with keypoints and skeletons, the outlines of the person mask and of
  the mode's silhouette, uncertainty renders and colour bar, and a warning line when the
  quality score is low or a quality flag is set;
- ``person_mask.png``: BlazePose's segmentation of the person, 8-bit grayscale in original
  photo pixels (255 × the probability that the pixel shows the person).

With ``--same-person`` the photos show one person, and ``DIR/same_person_shape/`` also gets
the shape combined from all photos that succeeded (the precision-weighted product of their shape
Gaussians, per sex with sex as a latent, a stated value counted once:
:mod:`hkpd.prediction.same_person`; :mod:`hkpd.prediction.exports.combined_shape` lists its
files): the T-pose mesh, the same mesh coloured by shape uncertainty, ``shape.npz`` and
``shape.json``.

Mesh files are in a Y-up display frame (``(x, -y, -z)`` of the camera-aligned body frame; see
:mod:`hkpd.prediction.exports.writers`). A photo that fails (missing, not an image, no person) is
reported on one line and skipped; the exit status is 1 when any failed, 2 for a usage error or
a model that cannot be loaded.

``DIR/index.jsonl`` gets one line per photo (per person with ``--all-people``): its folder,
status, quality score and flags, sex probabilities and time. Under ``torchrun`` the photos are
split among the processes; ``--resume`` finishes a run that was stopped or killed
(:mod:`hkpd.prediction.dataset_run`, which also says why every process then exits 0).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np
import torch
from PIL import Image

from hkpd.body_flags import MEASUREMENT_FLAGS, add_body_arguments, stated_body
from hkpd.interrupts import deferred_interrupts, interrupted, raise_if_interrupted
from hkpd.prediction.dataset_run import (
    INDEX_FILE,
    REPLACED_SUFFIX,
    DatasetRun,
    RunCounts,
    RunProgress,
    Shard,
    add_dataset_arguments,
    is_complete,
    photo_labels,
)
from hkpd.prediction.detection.keypoint_detector import people_by_size, reading_box
from hkpd.prediction.exports.body_summary import body_arrays, body_summary, posterior_caption
from hkpd.prediction.exports.combined_shape import CombinedBody, write_combined_shape
from hkpd.prediction.exports.uncertainty_colours import UncertaintyColourScale
from hkpd.prediction.exports.writers import (
    ARRAY_FORMAT,
    DISPLAY_FRAME_NOTE,
    MESH_FORMATS,
    OUTPUT_FORMATS,
    PERSON_MASK_FILE,
    distribution_arrays,
    write_distribution_npz,
    write_json,
    write_mesh,
    write_person_mask,
)
from hkpd.prediction.image_input import IMAGE_SUFFIXES
from hkpd.prediction.reader_agreement import second_reader_outline, second_reading_summary
from hkpd.prediction.same_person import PhotoShape, combine_photo_shapes, combined_measurements

if TYPE_CHECKING:
    from hkpd.conditioning import StatedBody
    from hkpd.prediction.posterior import BodyMeshes, BodyPosterior
from hkpd.prediction.predictor import Predictor

_Written = TypeVar("_Written")

IMAGE_EXTENSIONS = IMAGE_SUFFIXES
"""Files with these extensions (any case) are taken from folders."""

DEFAULT_FORMATS = ("ply", "npz")
UNCERTAINTY_SAMPLES = 100
"""Default number of posterior samples behind the per-vertex uncertainty (independent of
``--samples``, which only sets how many sample meshes are written)."""

PROG = "hkpd-predict"
SAME_PERSON_FOLDER = "same_person_shape"
"""Folder of the combined shape under ``--out`` (a suffix is added if a photo has that name)."""


class UsageError(ValueError):
    """A command-line argument is unusable; the message says what to pass instead."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Predict 3D body shape and pose distributions from photos and write meshes, "
        "the distribution parameters, a JSON summary and an overview picture per photo.",
    )
    parser.add_argument("inputs", nargs="+", metavar="IMAGE_OR_DIR", help="photos or folders")
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a photo's existing results in --out (they are removed first); without "
        "it (or --resume), an existing non-empty result folder is an error",
    )
    parser.add_argument("--model", default=None, help="checkpoint (default: the shipped model)")
    parser.add_argument(
        "--samples", type=int, default=10, help="sample meshes to write per photo (default 10)"
    )
    parser.add_argument(
        "--format",
        dest="formats",
        nargs="+",
        action="extend",
        metavar="FMT",
        help=f"output formats among {', '.join(OUTPUT_FORMATS)} (several allowed; default "
        f"{' '.join(DEFAULT_FORMATS)})",
    )
    parser.add_argument(
        "--bbox",
        nargs="+",
        metavar="COORD",
        help="look for the person only inside this box, original-photo pixels (to pick one of "
        "several people); four numbers, spaces or commas",
    )
    parser.add_argument(
        "--uncertainty-samples",
        type=int,
        default=UNCERTAINTY_SAMPLES,
        metavar="N",
        help=f"posterior samples behind the per-vertex uncertainty (default {UNCERTAINTY_SAMPLES})",
    )
    parser.add_argument(
        "--same-person",
        action="store_true",
        help=f"the photos show one person: also write the shape combined from all of them "
        f"(T-pose mesh, betas mean/std, shape uncertainty) into --out/{SAME_PERSON_FOLDER}",
    )
    parser.add_argument(
        "--turn-around",
        action="store_true",
        help="write the turned-around reading: the same keypoints fitted by a body facing the "
        "other way, left and right swapped (people seen from behind whom the detector labelled "
        "as facing the camera; docs/evidence.md)",
    )
    parser.add_argument(
        "--all-people",
        action="store_true",
        help="predict every person the detector finds in each photo, larger people first, "
        "into one folder per person (--out/PHOTO/person_1, person_2, ...)",
    )
    parser.add_argument("--device", default="auto", help="auto (CUDA when available), cpu, cuda")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the samples")
    add_evidence_arguments(parser)
    add_body_arguments(parser)
    add_dataset_arguments(parser)
    return parser


def add_evidence_arguments(parser: argparse.ArgumentParser) -> None:
    """The switches of what the photo's evidence is: ``--no-evidence``, ``--no-face``,
    ``--silhouette-evidence``."""
    parser.add_argument(
        "--no-evidence",
        action="store_true",
        help="return the network's own distribution instead of conditioning it on the detected "
        "2D keypoints (the paper's method; docs/evidence.md)",
    )
    parser.add_argument(
        "--no-face",
        action="store_true",
        help="do not let the face tell the sex (by default HSE FaceRes reads the face, on this "
        "machine, and its calibrated word weighs the sexes beside the body's proportions; "
        "summary.json's sex_evidence keeps each apart; docs/shape.md)",
    )
    parser.add_argument(
        "--silhouette-evidence",
        action="store_true",
        help="also condition on BlazePose's person mask: the body's outline is fitted to the "
        "mask as well as to the keypoints (off by default: it helps people alone in the photo "
        "in close-fitting clothes; loose clothing or a second person in the mask pulls the "
        "body wider; docs/shape.md)",
    )


def parse_bbox(values: Sequence[str] | None) -> tuple[float, float, float, float] | None:
    """``--bbox`` values (``X0 Y0 X1 Y1`` or ``X0,Y0,X1,Y1``) as four floats."""
    if values is None:
        return None
    parts = [part for value in values for part in value.replace(",", " ").split()]
    try:
        numbers = [float(part) for part in parts]
    except ValueError:
        raise UsageError(f"--bbox needs four numbers x0 y0 x1 y1, got {' '.join(values)}") from None
    if len(numbers) != 4 or not np.isfinite(numbers).all():
        raise UsageError(f"--bbox needs four numbers x0 y0 x1 y1, got {' '.join(values)}")
    x0, y0, x1, y1 = numbers
    if x1 <= x0 or y1 <= y0:
        raise UsageError(f"--bbox needs x1 > x0 and y1 > y0, got {' '.join(values)}")
    return x0, y0, x1, y1


def parse_formats(values: Sequence[str] | None) -> tuple[str, ...]:
    """``--format`` values, lower-cased, deduplicated in order; the default when None."""
    if not values:
        return DEFAULT_FORMATS
    formats: list[str] = []
    for value in values:
        for name in value.replace(",", " ").lower().split():
            if name not in OUTPUT_FORMATS:
                raise UsageError(
                    f"--format {name!r} is not supported; choose among {', '.join(OUTPUT_FORMATS)}"
                )
            if name not in formats:
                formats.append(name)
    return tuple(formats)


def collect_images(inputs: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """Files as given, plus the images (by extension) under folders, recursively and sorted.

    Missing paths are kept, so that they are reported like any other failed photo.
    """
    images: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            found = sorted(
                (
                    p
                    for p in path.rglob("*")
                    if p.suffix.lower() in IMAGE_EXTENSIONS and p.is_file()
                ),
                key=lambda p: p.as_posix(),
            )
            images.extend(found)
        else:
            images.append(path)
    return images


def output_names(images: Sequence[Path]) -> list[str]:
    """A distinct output folder name per image: its stem, made unique when stems repeat."""
    names: list[str] = []
    used: set[str] = set()
    for image in images:
        name = image.stem or "image"
        if name in used:
            name = f"{image.stem}_{image.suffix.lstrip('.').lower()}"
        candidate, count = name, 2
        while candidate in used:
            candidate, count = f"{name}_{count}", count + 1
        used.add(candidate)
        names.append(candidate)
    return names


def load_predictor(model: str | None, device: str) -> Predictor:
    """The :class:`~hkpd.prediction.predictor.Predictor` (tests replace this function)."""
    from hkpd.prediction.predictor import Predictor, refuse_silhouette_model

    predictor = Predictor.from_pretrained(model, device=device)
    refuse_silhouette_model(predictor, PROG)
    return predictor


@dataclass
class PhotoResult:
    """What happened to one photo."""

    image: Path
    folder: Path | None = None
    error: str | None = None
    files: list[str] = field(default_factory=list)
    seconds: float = 0.0
    person_box: tuple[float, ...] | None = None
    note: str | None = None
    shape: PhotoShape | None = None
    no_person: bool = False
    """The photo failed because no person was found in it."""


def _timed(timings: dict[str, float], name: str, start: float) -> float:
    now = time.perf_counter()
    timings[name] = round(now - start, 4)
    return now


def predict_photo(
    predictor: Predictor,
    image: Path,
    folder: Path,
    *,
    samples: int,
    formats: Sequence[str],
    bbox: Sequence[float] | None,
    seed: int,
    model_path: str,
    scale: UncertaintyColourScale,
    uncertainty_samples: int = UNCERTAINTY_SAMPLES,
    evidence: bool = True,
    stated: StatedBody | None = None,
    turn_around: bool = False,
    read_face: bool = True,
) -> PhotoResult:
    """Predict one photo and write its files into ``folder`` (``turn_around``: its
    turned-around reading, :meth:`BodyPosterior.turned_around`).

    ``stated``: what is known of the person (``--sex``, ``--height`` ...), passed to
    :meth:`Predictor.predict` as ``sex=`` and ``measurements=``.

    Raises:
        ImageInputError, NoPersonFoundError, ValueError, OSError: the photo failed.
    """
    started = time.perf_counter()
    timings: dict[str, float] = {}
    posterior = predictor.predict(
        image, bbox=bbox, evidence=evidence, read_face=read_face, **_stated_arguments(stated)
    )
    if turn_around:
        posterior = posterior.turned_around()
    clock = _timed(timings, "predict_s", started)
    mode = posterior.mode()
    drawn = posterior.sample(samples, seed=seed) if samples > 0 else None
    clock = _timed(timings, "sample_s", clock)
    uncertainty = posterior.vertex_uncertainty(n=uncertainty_samples, seed=seed)
    clock = _timed(timings, "uncertainty_s", clock)
    measurements = posterior.measurements()
    clock = _timed(timings, "measurements_s", clock)

    uncertainty_np = uncertainty.detach().cpu().double().numpy()
    folder.mkdir(parents=True, exist_ok=True)
    written = _write_meshes(
        folder, formats, mode, drawn, posterior.body.faces, scale.colours_uint8(uncertainty_np)
    )
    if ARRAY_FORMAT in formats:
        arrays = distribution_arrays(posterior, mode, drawn, uncertainty)
        arrays |= body_arrays(posterior, measurements)
        written.append(write_distribution_npz(folder / "prediction.npz", arrays))
    clock = _timed(timings, "export_s", clock)
    captions = (
        f"{samples} samples, model {Path(model_path).name}",
        posterior_caption(posterior, measurements),
    )
    overview = (posterior, mode, drawn, uncertainty_np, scale, captions)
    written += _write_pictures(folder, overview, timings, clock)
    timings["total_s"] = round(time.perf_counter() - started, 4)

    summary_path = folder / "summary.json"
    files = [path.relative_to(folder).as_posix() for path in written] + [summary_path.name]
    silhouette = bool(getattr(predictor, "silhouette_evidence", False)) and evidence
    summary = _photo_summary(
        image, posterior, mode, uncertainty_np, uncertainty_samples, scale, evidence, silhouette
    )
    summary |= body_summary(posterior, measurements) | {
        "samples": samples, "seed": seed, "formats": list(formats), "frames": DISPLAY_FRAME_NOTE,
        "files": files, "timings": timings, "model": model_path,
    }  # fmt: skip
    write_json(summary_path, summary)
    return PhotoResult(
        image=image,
        folder=folder,
        files=files,
        seconds=timings["total_s"],
        person_box=tuple(float(v) for v in posterior.network_input.detection.person_box),
        note=_photo_note(posterior, silhouette),
        shape=PhotoShape.of(posterior),
    )


def _write_pictures(
    folder: Path, overview: tuple, timings: dict[str, float], clock: float
) -> list[Path]:
    """The overview (``overview``: :func:`_write_overview`'s arguments after the path) and the
    person mask, when the detector gave one, into ``folder``; their times go into
    ``timings``."""
    written = [_write_overview(folder / "overview.png", *overview)]
    clock = _timed(timings, "overview_s", clock)
    mask = overview[0].network_input.detection.person_mask
    if mask is not None:
        written.append(write_person_mask(folder / PERSON_MASK_FILE, mask))
        _timed(timings, "mask_s", clock)
    return written


def _stated_arguments(stated: StatedBody | None) -> dict[str, object]:
    """``sex=`` and ``measurements=`` for :meth:`Predictor.predict` (None for nothing stated)."""
    if stated is None:
        return {"sex": None, "measurements": None}
    return {"sex": stated.sex, "measurements": dict(stated.measurements) or None}


def _photo_note(posterior: BodyPosterior, silhouette: bool) -> str | None:
    """The photo's console note: why the evidence fit fell back, or that a requested person
    mask was missing (the fit then used the keypoints alone), and the quality warning of a
    reading to check (:meth:`hkpd.prediction.quality.ReadingQuality.warning`); None when all
    went as asked."""
    notes = []
    fit = posterior.evidence_fit
    if posterior.fallback_reason:
        notes.append(f"network posterior ({posterior.fallback_reason})")
    elif silhouette and fit is not None and "silhouette" not in fit.terms:
        notes.append("no person mask: keypoints only")
    warning = posterior.quality.warning()
    if warning:
        notes.append(f"check this reading: {warning}")
    return "; ".join(notes) or None


def _write_meshes(
    folder: Path,
    formats: Sequence[str],
    mode: BodyMeshes,
    drawn: BodyMeshes | None,
    faces: torch.Tensor,
    colours: np.ndarray,
) -> list[Path]:
    """The mode, the mode coloured by ``(V, 3)`` uint8 ``colours`` and the samples, in every
    mesh format of ``formats``; returns the files written."""
    written: list[Path] = []
    for fmt in formats:
        if fmt not in MESH_FORMATS:
            continue
        written.append(write_mesh(folder / f"mode.{fmt}", mode.vertices[0], faces))
        written.append(
            write_mesh(folder / f"mode_uncertainty.{fmt}", mode.vertices[0], faces, colours)
        )
        if drawn is not None:
            for index, vertices in enumerate(drawn.vertices):
                path = folder / "samples" / f"sample_{index:03d}.{fmt}"
                written.append(write_mesh(path, vertices, faces))
    return written


def _write_overview(
    path: Path,
    posterior: BodyPosterior,
    mode: BodyMeshes,
    drawn: BodyMeshes | None,
    uncertainty: np.ndarray,
    scale: UncertaintyColourScale,
    captions: tuple[str, str],
) -> Path:
    """Write the overview picture (:func:`hkpd.prediction.exports.overview.make_overview`) to
    ``path``; ``captions``: the run's line and the body's line (its sex and measurements)."""
    from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
    from hkpd.prediction.exports.overview import Outlines, make_overview

    prepared = posterior.network_input
    detection = prepared.detection
    ndc = weak_perspective_project(mode.vertices, posterior.camera.expand(1, 3))
    vertices2d = posterior.crop.crop_to_image(ndc_to_pixels(ndc, posterior.crop.size))
    outlines = Outlines(
        person_mask=detection.person_mask,
        mode_vertices2d=torch.as_tensor(vertices2d)[0].detach().cpu().double().numpy(),
        faces=torch.as_tensor(posterior.body.faces).cpu().numpy(),
        detected_extremities=detection.extremities,
        extremity_shown=prepared.extremity_evidence,
        mode_extremities2d=mode.extremity_keypoints2d[0].cpu().numpy(),
        **second_reader_outline(detection),
    )
    overview = make_overview(
        prepared.image,
        posterior.crop,
        detection.keypoints,
        detection.confidences,
        mode.keypoints2d[0].cpu().numpy(),
        None if drawn is None else drawn.keypoints2d.cpu().numpy(),
        mode.vertices[0],
        posterior.body.faces,
        uncertainty,
        scale,
        caption=captions[0],
        outlines=outlines,
        body_caption=captions[1],
        warning=posterior.quality.warning(),
    )
    Image.fromarray(overview).save(path)
    return path


def _photo_summary(
    image: Path,
    posterior: BodyPosterior,
    mode: BodyMeshes,
    uncertainty: np.ndarray,
    uncertainty_samples: int,
    scale: UncertaintyColourScale,
    evidence: bool,
    silhouette: bool = False,
) -> dict[str, object]:
    """What ``summary.json`` says about the photo, the person, the crop, the keypoints and the
    ``(V,)`` uncertainty (metres, from ``uncertainty_samples`` samples); :func:`predict_photo`
    adds the run's settings and files."""
    detection = posterior.network_input.detection
    crop = posterior.crop
    return {
        "image": str(image),
        "image_absolute": str(Path(image).resolve()),
        "image_size": {"width": detection.image_size[0], "height": detection.image_size[1]},
        "person": {
            "detected_bbox": detection.person_box,
            "search_bbox": detection.search_box,
            "note": "BlazePose takes one person (usually the largest, most central); pass "
            "--bbox x0 y0 x1 y1 to pick another",
        },
        "posterior": _posterior_summary(posterior, evidence, silhouette),
        "quality": posterior.quality.as_dict(),
        "crop": {
            "centre": crop.centre,
            "side": crop.side,
            "size": crop.size,
            "box": crop.box,
        },
        "keypoints": {
            "format": "COCO-17, original-photo pixels (u right, v down, pixel centres at integers)",
            "detected": detection.keypoints,
            "confidences": detection.confidences,
            "mode_reprojected": mode.keypoints2d[0],
            "second_reader": second_reading_summary(detection),
        },
        "uncertainty": {
            "mean_m": float(uncertainty.mean()),
            "max_m": float(uncertainty.max()),
            "samples": uncertainty_samples,
            "colour_scale": scale.describe(),
        },
    }


def _posterior_summary(
    posterior: BodyPosterior, evidence: bool, silhouette: bool = False
) -> dict[str, object]:
    """What ``summary.json`` says about where the distribution comes from (``silhouette``: the
    person mask was asked for as evidence, ``--silhouette-evidence``)."""
    fit = posterior.evidence_fit
    summary: dict[str, object] = {
        "source": posterior.source,
        "evidence_requested": evidence,
        "silhouette_requested": silhouette,
        "fallback_reason": posterior.fallback_reason,
        "upright_tilt_degrees": posterior.upright_tilt_degrees,
        "mirror_read": posterior.mirror_read,
        "turned_around": posterior.turned,
    }
    if posterior.evidence is not None:
        summary["evidence_keypoints"] = [int(i) for i in posterior.evidence.nonzero().flatten()]
    if fit is not None and fit.conditioned is not None:
        summary["fit"] = {
            "start": "upright copy" if fit.start == 1 else "crop",
            "turned": fit.turned,
            "iterations": fit.iterations,
            "converged": fit.converged,
            "cost": fit.cost,
            "seconds": round(fit.seconds, 4),
            "keypoint_weights": [round(float(w), 4) for w in fit.keypoint_weights],
            "terms": list(fit.terms),
        }
        if silhouette and "silhouette" not in fit.terms:
            summary["silhouette_note"] = (
                "the detector gave no person mask for this photo: the fit used the keypoints alone"
            )
    return summary


def _expected_errors() -> tuple[type[BaseException], ...]:
    from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
    from hkpd.prediction.image_input import ImageInputError

    return ImageInputError, NoPersonFoundError, ValueError, OSError


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``hkpd-predict``; returns the exit status (0 all done, 1 some photo failed, 2 usage
    error or unusable model)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        formats, bbox = _checked_options(args)
        stated = _checked_stated(args)
        shard = _checked_shard(args)
    except UsageError as error:
        parser.print_usage(sys.stderr)
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return 2
    images = collect_images(args.inputs)
    if not images:
        print(f"{PROG}: error: no images found in {' '.join(args.inputs)}", file=sys.stderr)
        return 2
    names = output_names(images)
    combined_name = _free_name(SAME_PERSON_FOLDER, names)
    own = shard.own(images)  # this process's photos (all of them without torchrun)
    if _refused_existing(args, [names[i] for i in own] + [combined_name] * args.same_person):
        return 2
    created_out = not args.out.exists()
    try:
        predictor = _loaded_or_reported(args)
    except KeyboardInterrupt:
        return interrupted(PROG, " while loading the model; no photo was predicted")
    if predictor is None or not _body_can_take(predictor, stated):
        return 2
    if args.silhouette_evidence:
        predictor.silhouette_evidence = True
    model_path = args.model or "shipped model (hkpd.assets/models/hkpd_hierarchical.pt)"

    grad_was_enabled = torch.is_grad_enabled()
    torch.set_grad_enabled(False)  # restored below: main() may be called from Python
    scale = UncertaintyColourScale()
    results: list[PhotoResult] | None = [] if args.same_person else None  # only what is used
    run = DatasetRun(args.out, shard, names, photo_labels(args.inputs, images), args.resume)

    def predict_into(folder: Path, image: Path, box: Sequence[float] | None = bbox) -> PhotoResult:
        return _predict_into(
            folder,
            predictor,
            image,
            samples=args.samples,
            formats=formats,
            bbox=box,
            seed=args.seed,
            model_path=str(model_path),
            scale=scale,
            uncertainty_samples=args.uncertainty_samples,
            evidence=not args.no_evidence,
            stated=stated,
            turn_around=args.turn_around,
            read_face=not args.no_face,
        )

    try:
        jobs = [(images[i], names[i], bbox) for i in own]
        people = predictor if args.all_people else None
        counts = _predict_all(predict_into, jobs, args.out, results, run, people, args.verbose)
        combined = None
        if results is not None:  # --same-person
            combined = _combine_into(
                args.out / combined_name, predictor, results, formats, scale, stated
            )
    except KeyboardInterrupt:
        run.interrupted()
        if created_out and args.out.is_dir() and not any(args.out.iterdir()):
            args.out.rmdir()  # nothing was written: leave no empty folder behind
        return interrupted(PROG, f" after {run.photos_finished} of {len(own)} photos; the "
                           "folders written so far are complete, nothing is half-written (--resume "
                           "finishes the run)")  # fmt: skip
    finally:
        torch.set_grad_enabled(grad_was_enabled)
        closer = getattr(predictor, "close", None)
        if closer is not None:
            closer()
    return _final_report(args.out, counts, combined, shard.world_size)


def _checked_options(
    args: argparse.Namespace,
) -> tuple[tuple[str, ...], tuple[float, float, float, float] | None]:
    """The parsed ``--format`` and ``--bbox``, or a UsageError for any unusable option."""
    formats = parse_formats(args.formats)
    bbox = parse_bbox(args.bbox)
    if args.samples < 0:
        raise UsageError(f"--samples must be >= 0, got {args.samples}")
    if args.turn_around and args.no_evidence:
        raise UsageError(
            "--turn-around refits the keypoints facing the other way, which --no-evidence turns "
            "off; give one of them"
        )
    if args.silhouette_evidence and args.no_evidence:
        raise UsageError(
            "--silhouette-evidence weighs the person mask in the evidence fit, which "
            "--no-evidence turns off; give one of them"
        )
    if args.uncertainty_samples < 2:
        raise UsageError(f"--uncertainty-samples must be >= 2, got {args.uncertainty_samples}")
    if args.all_people and (bbox is not None or args.same_person):
        raise UsageError(
            "--all-people predicts every person in their own box: it goes with neither --bbox "
            "(one person) nor --same-person (one person in every photo)"
        )
    if args.resume and (args.overwrite or args.same_person):
        raise UsageError(
            "--resume keeps the complete results of an earlier run: it goes with neither "
            "--overwrite (which replaces them) nor --same-person (which combines one run's photos)"
        )
    check_out_folder(args.out)
    return formats, bbox


def _checked_shard(args: argparse.Namespace) -> Shard:
    """This process's share of the photos (:class:`~hkpd.prediction.dataset_run.Shard`: all of
    them without torchrun), checked against the options that need every photo in one process;
    under torchrun ``args.device`` becomes the rank's own and torch gets its share of threads.

    Raises:
        UsageError: torchrun's variables do not fit, or ``--same-person`` under torchrun.
    """
    try:
        shard = Shard.from_environment()
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.same_person and shard.world_size > 1:
        raise UsageError(
            "--same-person combines every photo's shape in one process: run it without "
            "torchrun (or predict under torchrun first, then combine in one process)"
        )
    args.device = shard.device(args.device)
    shard.configure_threads(args.device)
    return shard


def _checked_stated(args: argparse.Namespace) -> StatedBody:
    """What ``--sex`` and the measurement flags state, checked before the model loads.

    Raises:
        UsageError: a value that is not a plausible number (the message names the flag), or
            something stated together with ``--no-evidence``.
    """
    try:
        stated = stated_body(args)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if not stated.empty and args.no_evidence:
        given = (["--sex"] if stated.sex is not None else []) + [
            MEASUREMENT_FLAGS[name] for name in stated.measurements
        ]
        raise UsageError(
            f"{' '.join(given)} condition the body shape in the evidence fit, which "
            "--no-evidence turns off; give one or the other"
        )
    return stated


def _body_can_take(predictor: Predictor, stated: StatedBody) -> bool:
    """Whether the model's body can be conditioned on ``stated`` (True when nothing is
    stated); prints why not."""
    if stated.empty or getattr(predictor.body, "has_sex_priors", False):
        return True
    print(
        f"{PROG}: error: the model's body has no sex-specific shape priors, so --sex and the "
        "measurement flags cannot be used with it; use the shipped body model or drop them",
        file=sys.stderr,
    )
    closer = getattr(predictor, "close", None)
    if closer is not None:
        closer()
    return False


def check_out_folder(out: Path) -> None:
    """Refuse an ``--out`` that cannot become a writable folder, before the model loads.

    Raises:
        UsageError: ``out`` (or a folder above it) is a file, or the nearest existing folder
            above it cannot be written.
    """
    existing = out
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        where = "is a file" if existing == out else f"is below the file {existing}"
        raise UsageError(f"--out {out} {where}; give the path of a folder (new or existing)")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UsageError(
            f"--out {out}: cannot write in {existing} (permission denied); choose a folder "
            "you can write to"
        )


def _loaded_or_reported(args: argparse.Namespace) -> Predictor | None:
    """The predictor of ``--model`` on ``--device``, or None once the reason is printed."""
    from hkpd.network.checkpoint import CheckpointError

    try:
        return load_predictor(args.model, args.device)
    except (FileNotFoundError, CheckpointError, ValueError, RuntimeError, KeyError) as error:
        hint = "" if args.model else " (choose a checkpoint with --model PATH)"
        print(f"{PROG}: error: cannot load the model: {_one_line(error)}{hint}", file=sys.stderr)
        return None


def _photo_jobs(
    people_finder: Predictor | None,
    image: Path,
    name: str,
    box: Sequence[float] | None,
    run: DatasetRun,
    progress: RunProgress,
) -> list[tuple[Path, str, Sequence[float] | None]]:
    """The ``(image, folder name, bbox)`` jobs of one photo: itself, or with ``--all-people``
    (``people_finder``: the predictor whose detector looks) one per person the detector
    finds, larger people first (the Person menu's order), into ``NAME/person_K``. A photo
    whose people cannot be looked for, or where nobody is found, is recorded as failed."""
    if people_finder is None:
        return [(image, name, box)]
    started = time.perf_counter()
    try:
        people = people_by_size(people_finder.detector.detect_all(image))
    except _expected_errors() as error:
        failure = _failure(image, error)
    else:
        if people:
            return [
                (image, f"{name}/person_{index}", tuple(float(v) for v in reading_box(person)))
                for index, person in enumerate(people, start=1)
            ]
        failure = PhotoResult(image=image, error="no person was found", no_person=True)
    run.record(name, failure.error, failure.no_person, time.perf_counter() - started)
    progress.say(f"{PROG}: FAILED {image}: {failure.error}", failed=True)
    return []


def _predict_all(
    predict_into: Callable[[Path, Path, Sequence[float] | None], PhotoResult],
    photos: Sequence[tuple[Path, str, Sequence[float] | None]],
    out: Path,
    results: list[PhotoResult] | None,
    run: DatasetRun,
    people_finder: Predictor | None = None,
    verbose: bool = False,
) -> RunCounts | None:
    """After :meth:`DatasetRun.begin`, ``predict_into(out / name, image, bbox)`` for every
    ``(image, name, bbox)`` (every person of it with ``people_finder``, :func:`_photo_jobs`)
    whose results are not complete already (``--resume``), recording each in ``run``'s index,
    appending it to ``results`` (when given) and reporting it on one line (a photo that fails
    is reported and skipped). Then :meth:`DatasetRun.finish`: the run's counts (rank 0), None
    on the other ranks. The progress bar counts photos, not people."""
    progress = None
    run.begin([name for _, name, _ in photos])
    try:
        with deferred_interrupts():  # a Ctrl-C while the bar is first drawn waits for it
            progress = RunProgress(run, len(photos), PROG, verbose)
        for image, name, box in photos:
            raise_if_interrupted()  # a Ctrl-C some library caught during the last photo
            for person_image, folder, person_box in _photo_jobs(
                people_finder, image, name, box, run, progress
            ):
                if run.complete(folder):
                    continue
                result = _predicted(predict_into, out / folder, person_image, person_box)
                run.record(folder, result.error, result.no_person, result.seconds)
                if results is not None:
                    results.append(result)
                progress.say(_result_line(result), failed=result.error is not None)
            progress.photo_done()
        return run.finish(progress, all_people=people_finder is not None)
    finally:
        if progress is not None:  # the bar's line ends, also on a Ctrl-C: its line follows
            progress.close()


def _predicted(
    predict_into: Callable[[Path, Path, Sequence[float] | None], PhotoResult],
    folder: Path,
    image: Path,
    box: Sequence[float] | None,
) -> PhotoResult:
    """``predict_into(folder, image, box)``, or the result saying in one line why it failed."""
    started = time.perf_counter()
    try:
        return predict_into(folder, image, box)
    except Exception as error:  # unexpected ones too: still one line, and go on
        result = _failure(image, error)
    result.seconds = time.perf_counter() - started
    return result


def _failure(image: Path, error: Exception) -> PhotoResult:
    """The result of a photo that failed with ``error``, said in one line (the photo's path
    once, in front of it; the error's type for an unexpected one)."""
    from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError

    expected = isinstance(error, _expected_errors())
    message = _one_line(error) if expected else f"{type(error).__name__}: {error}"
    if message.startswith(f"{image}: "):
        message = message[len(f"{image}: ") :]
    return PhotoResult(image=image, error=message, no_person=isinstance(error, NoPersonFoundError))


def _result_line(result: PhotoResult) -> str:
    """The console line of one photo (or person): where the results went, or why it failed."""
    if result.error is not None:
        return f"{PROG}: FAILED {result.image}: {result.error}"
    box = ", ".join(f"{value:.0f}" for value in result.person_box or ())
    note = f" [{result.note}]" if result.note else ""
    return (
        f"{result.image}: person at bbox ({box}) -> {result.folder} ({result.seconds:.1f} s){note}"
    )


def _final_report(
    out: Path, counts: RunCounts | None, combined: str | None, world_size: int = 1
) -> int:
    """Print the closing line (rank 0: photos, and people with ``--all-people``, over all
    ranks); the exit status: 1 when a photo or the combined shape failed; under torchrun 0
    once the run is complete (failures are in the index: a non-zero status would make
    torchrun report the whole launch as failed)."""
    if counts is None:  # another rank: rank 0 reports for all
        return 0
    folders = counts.photos_done if counts.people_done is None else counts.people_done
    wrote = "" if counts.skipped else "wrote "  # --resume: some folders were there before
    written = (
        f"{wrote}{counts.files} files in {folders} folder(s) under {out}; index {out / INDEX_FILE}"
        if folders
        else "nothing written"
    )
    if combined is not None:
        written += f"; {combined}"
    print(f"{PROG}: {counts.describe()}; {written}")
    failed = counts.photos_failed or (combined or "").startswith("combined shape FAILED")
    return 1 if failed and world_size == 1 else 0


def _existing_results(folders: Sequence[Path], resume: bool = False) -> list[Path]:
    """The folders that already hold something (a previous run's results); with ``resume``
    only those that are not complete results (complete ones are skipped, not replaced)."""
    return [
        folder
        for folder in folders
        if folder.exists() and any(folder.iterdir()) and not (resume and is_complete(folder))
    ]


def _refused_existing(args: argparse.Namespace, names: Sequence[str]) -> bool:
    """Whether this process's result folders ``names`` under ``--out`` hold something it may
    not replace (said on stderr): results, without ``--overwrite`` or ``--resume``; with
    ``--resume``, a non-empty folder that is not a complete result (with ``--all-people`` a
    photo's folder holds its people's folders: those are checked as they come)."""
    if args.overwrite or (args.resume and args.all_people):
        return False
    taken = _existing_results([args.out / name for name in names], args.resume)
    if not taken:
        return False
    shown = ", ".join(str(folder) for folder in taken[:3]) + (" ..." if len(taken) > 3 else "")
    if args.resume:
        print(f"{PROG}: error: {len(taken)} folder(s) in --out are not complete results "
              f"({shown}); move them away, or pass --overwrite", file=sys.stderr)  # fmt: skip
    else:
        print(f"{PROG}: error: {len(taken)} result folder(s) already exist ({shown}); pass "
              "--resume to keep them and predict the rest, --overwrite to replace them, or "
              "choose another --out", file=sys.stderr)  # fmt: skip
    return True


def _free_name(name: str, taken: Sequence[str]) -> str:
    """``name``, or ``name_2``, ``name_3`` ... when a photo's folder already has it."""
    candidate, count = name, 2
    while candidate in taken:
        candidate, count = f"{name}_{count}", count + 1
    return candidate


def _written_atomically(folder: Path, write: Callable[[Path], _Written]) -> _Written:
    """``write(partial)`` into a temporary folder beside ``folder``, renamed to it once
    everything is written, so results never mix with older ones and a failure leaves nothing
    half-written (an existing ``folder`` is only replaced on success)."""
    partial = folder.with_name(f".{folder.name}.partial")
    shutil.rmtree(partial, ignore_errors=True)
    try:
        written = write(partial)
        raise_if_interrupted()  # a Ctrl-C swallowed while writing: the partial folder goes
        with deferred_interrupts():  # Ctrl-C now waits: never half-replaced
            replaced = folder.with_name(f".{folder.name}{REPLACED_SUFFIX}")
            if folder.exists():  # moved aside whole first: a kill leaves no half folder
                shutil.rmtree(replaced, ignore_errors=True)
                folder.rename(replaced)
            partial.rename(folder)
            shutil.rmtree(replaced, ignore_errors=True)
    finally:
        with deferred_interrupts():  # nor a half-removed partial folder
            shutil.rmtree(partial, ignore_errors=True)
    return written


def _predict_into(folder: Path, *args: object, **kwargs: object) -> PhotoResult:
    """:func:`predict_photo` into ``folder``, atomically (:func:`_written_atomically`)."""

    def write(partial: Path) -> PhotoResult:
        return predict_photo(*args, folder=partial, **kwargs)

    result = _written_atomically(folder, write)
    result.folder = folder
    return result


def _combine_into(
    folder: Path,
    predictor: Predictor,
    results: Sequence[PhotoResult],
    formats: Sequence[str],
    scale: UncertaintyColourScale,
    stated: StatedBody | None = None,
) -> str:
    """Write the shape combined from the photos that succeeded into ``folder`` (atomically)
    and say what was written, for the final line (a failure is also printed to stderr).

    With sex as a latent the photos are combined per sex, a stated value counted once
    (:func:`hkpd.prediction.same_person.combine_photo_shapes`); ``stated`` is said in
    ``shape.json``."""
    done = [result for result in results if result.error is None and result.shape is not None]
    if not done:
        return "no combined shape (no photo succeeded)"
    shapes = [result.shape for result in done if result.shape is not None]
    means = torch.stack([shape.shape_mean for shape in shapes])
    stds = torch.stack([shape.shape_std for shape in shapes])
    try:
        combined = combine_photo_shapes(shapes, predictor.body, "product")
        baseline = combine_photo_shapes(shapes, predictor.body, "mean")
        about = CombinedBody(
            measurements=combined_measurements(combined, predictor.body),
            photo_sex_probabilities=tuple(shape.sex_probabilities for shape in shapes),
            stated=stated,
        )
        files = _written_atomically(
            folder,
            lambda partial: write_combined_shape(
                partial, combined, baseline, [r.image for r in done], means, stds, formats,
                scale, about,
            ),
        )  # fmt: skip
    except (ValueError, OSError) as error:
        failure = f"combined shape FAILED: {_one_line(error)}"
        print(f"{PROG}: {failure}", file=sys.stderr)
        return failure
    return (
        f"combined shape of {len(done)} photo(s) (mean std {combined.mean_std:.3f}, one photo "
        f"{float(stds.mean()):.3f}): {len(files)} files in {folder}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
