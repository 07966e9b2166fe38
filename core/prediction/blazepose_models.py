"""BlazePose's two TFLite models (shipped in ``hkpd.assets/blazepose``), run with LiteRT.

LiteRT (``ai-edge-litert``, Google's TensorFlow Lite runtime on PyPI) executes the ``.tflite``
files as they are; nothing is converted or downloaded. Each :class:`TfliteModel` holds one
interpreter and is not thread-safe (the caller serialises calls).
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

import numpy as np

DETECTOR_MODEL = ("blazepose", "pose_detection.tflite")
"""The person detector, 224×224 RGB input in [-1, 1] -> per-anchor boxes and scores."""

LANDMARK_MODEL = ("blazepose", "pose_landmark_full.tflite")
"""The "full" landmark model, 256×256 RGB input in [0, 1] -> 39 landmarks, heatmaps, mask."""

DEFAULT_THREADS = 2
"""Interpreter threads; BlazePose's small convolutions gain little beyond two."""


def shipped_model_path(parts: tuple[str, str]) -> Path:
    """Path of a model file inside ``hkpd.assets``.

    Raises:
        FileNotFoundError: the file is missing (a broken install).
    """
    resource = importlib.resources.files("hkpd.assets").joinpath(*parts)
    if not resource.is_file():
        raise FileNotFoundError(
            f"BlazePose model {'/'.join(parts)} is missing from hkpd.assets; reinstall hkpd "
            "(pip install -e . from a full clone)"
        )
    return Path(str(resource))


class TfliteModel:
    """One ``.tflite`` model with a float32 NHWC input.

    Args:
        path: the model file.
        threads: interpreter threads.

    Attributes:
        input_size: side of the square input, pixels.
    """

    def __init__(self, path: Path, threads: int = DEFAULT_THREADS) -> None:
        self._interpreter = _interpreter_class()(model_path=str(path), num_threads=threads)
        self._interpreter.allocate_tensors()
        (details,) = self._interpreter.get_input_details()
        self._input_index = details["index"]
        self.input_size = int(details["shape"][1])
        outputs = sorted(self._interpreter.get_output_details(), key=lambda d: d["name"])
        self._output_indices = [d["index"] for d in outputs]

    def __call__(self, image: np.ndarray) -> list[np.ndarray]:
        """Run on ``(S, S, 3)`` float32 input; returns the outputs (batch axis dropped) in the
        order of their tensor names (``Identity``, ``Identity_1``, ...)."""
        self._interpreter.set_tensor(self._input_index, image[None].astype(np.float32))
        self._interpreter.invoke()
        return [self._interpreter.get_tensor(i)[0] for i in self._output_indices]


def _interpreter_class() -> type:
    """LiteRT's ``Interpreter``, imported on first use: ``import hkpd.prediction`` keeps working
    in an environment that lacks the runtime (only running the detector needs it).

    Raises:
        ModuleNotFoundError: ``ai-edge-litert`` is not installed, with the fix.
    """
    try:
        from ai_edge_litert.interpreter import Interpreter
    except ModuleNotFoundError as error:
        raise ModuleNotFoundError(
            "hkpd's BlazePose runner needs the LiteRT runtime: pip install ai-edge-litert "
            "(or reinstall hkpd: pip install -e .)"
        ) from error
    return Interpreter
