"""``hkpd-explore``'s scene options: the command line's settings as one :class:`SceneFile`
(so that a page exported from the command line and one exported from a saved scene go the same
way), ``--save-scene``, ``--scene`` and the photo of a scene.

Imported by :mod:`hkpd.explorer.cli` only once the arguments are checked (it pulls in numpy,
OpenCV and the compare module).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from hkpd.body_flags import stated_body
from hkpd.explorer.compare import parse_compare
from hkpd.explorer.demo_photo import shipped_photo
from hkpd.explorer.scene_file import (
    DisplaySettings,
    OccluderEntry,
    PhotoRef,
    SceneFile,
    SceneFileError,
    load_scene,
)
from hkpd.explorer.upload import UploadError, decode_upload
from hkpd.kinematic_tree import BODY_JOINT_NAMES

Box = tuple[float, float, float, float]


def scene_from_arguments(
    args: argparse.Namespace, photo_name: str, person_box: Box | None, occluders: list[Box]
) -> SceneFile:
    """The scene the command line describes (photo, boxes, switches, display, seed, model,
    compare).

    Raises:
        SystemExit: a bad ``--concentration``, ``--compare`` or photo.
    """
    stated = stated_body(args)
    return SceneFile(
        sex=stated.sex,
        measurements={name: [value, std] for name, (value, std) in stated.measurements.items()},
        photo=_photo_of(args, photo_name),
        person_box=person_box,
        occluders=tuple(OccluderEntry(box) for box in occluders),
        joint_factors=_joint_factors(args.concentration),
        evidence=not args.no_evidence,
        person_mask=args.silhouette_evidence,
        display=DisplaySettings(
            colouring=args.colouring, num_samples=args.samples, num_displayed=args.meshes
        ),
        seed=args.seed,
        model=args.model,
        compare=None if args.compare is None else _compare_text(args.compare),
        turned_around=bool(getattr(args, "turn_around", False)),
    )


def open_scene_file(path: str) -> tuple[SceneFile, np.ndarray | None]:
    """``--scene FILE``: the scene and its photo ``(H, W, 3)`` uint8 RGB (None for the
    synthetic demo scene, which the caller renders).

    Raises:
        SystemExit: the scene or its photo cannot be used (the message says why).
    """
    try:
        scene = load_scene(path)
        if scene.photo.demo == "synthetic":
            return scene, None
        content = scene.photo.read(Path(path).resolve().parent)
        return scene, decode_upload(scene.photo.file_name(content), content)
    except (SceneFileError, UploadError) as error:
        raise SystemExit(f"hkpd-explore: --scene {path}: {error}") from None


def save_scene_file(scene: SceneFile, path: str, force: bool) -> int:
    """``--save-scene FILE``: write ``scene``; an existing file is kept unless ``force``."""
    try:
        written = scene.save(path, force=force)
    except SceneFileError as error:
        raise SystemExit(f"hkpd-explore: no scene written: {error}") from None
    print(f"wrote {written}: {scene.photo.name}, {len(scene.occluders)} occluder(s)")
    return 0


def _photo_of(args: argparse.Namespace, name: str) -> PhotoRef:
    if args.image is None and args.demo == "synthetic":
        return PhotoRef(name, demo="synthetic")
    path = args.image if args.image is not None else shipped_photo()
    try:  # the shipped photo's bytes are named as the shipped photo, not by this path
        return PhotoRef.of_file(path, name=name, embed=args.embed_photo)
    except OSError as error:
        raise SystemExit(f"hkpd-explore: cannot read {path}: {error}") from None


def _joint_factors(pairs: list[list[str]]) -> dict[str, float]:
    factors: dict[str, float] = {}
    for joint, text in pairs:
        name = joint.replace(" ", "_").replace("-", "_")
        if name not in BODY_JOINT_NAMES:
            raise SystemExit(
                f"hkpd-explore: --concentration: unknown joint {joint!r}; joints: "
                f"{', '.join(BODY_JOINT_NAMES)}"
            )
        try:
            factor = float(text.rstrip("x×"))
        except ValueError:
            factor = math.nan
        if not 0.1 <= factor <= 10.0:
            raise SystemExit(
                f"hkpd-explore: --concentration {joint} {text}: the factor must be a number "
                "from 0.1 to 10 (1: as predicted)"
            )
        factors[name] = factor
    return factors


def _compare_text(text: str) -> str:
    try:
        return parse_compare(text).text
    except ValueError as error:
        raise SystemExit(f"hkpd-explore: {error}") from None
