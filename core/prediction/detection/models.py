"""BlazePose's two TFLite models (shipped in ``hkpd.assets/blazepose``), run with LiteRT.

LiteRT (``ai-edge-litert``, Google's TensorFlow Lite runtime on PyPI) executes the ``.tflite``
files; nothing is converted or downloaded. :func:`drop_output` can remove an unused output and
the operators only it needs while loading (the landmark model's 256×256 segmentation head is
37 % of its time). Each :class:`TfliteModel` holds one interpreter and is not thread-safe (the
caller serialises calls).
"""

from __future__ import annotations

from pathlib import Path

import flatbuffers
import numpy as np

from hkpd.assets import shipped_file

DETECTOR_MODEL = ("blazepose", "pose_detection.tflite")
"""The person detector, 224×224 RGB input in [-1, 1] -> per-anchor boxes and scores."""

LANDMARK_MODEL = ("blazepose", "pose_landmark_full.tflite")
"""The "full" landmark model, 256×256 RGB input in [0, 1] -> 39 landmarks, heatmaps, mask."""

SEGMENTATION_OUTPUT = "Identity_2"
"""The landmark model's ``(1, 256, 256, 1)`` segmentation logits."""

DEFAULT_THREADS = 1
"""Interpreter threads. A second thread did not shorten a call of either model on the 2-core
development machine (11.1 vs 12.8 ms for the detector, 11.2 vs 11.6 ms for the landmark model)
and costs CPU time that the rest of hkpd can use."""


def blazepose_model_path(parts: tuple[str, str]) -> Path:
    """Path of one of BlazePose's model files inside ``hkpd.assets`` (:data:`DETECTOR_MODEL`,
    :data:`LANDMARK_MODEL`).

    Raises:
        FileNotFoundError: the file is missing (a broken install).
    """
    return shipped_file(
        parts, "BlazePose model", "reinstall hkpd (pip install -e . from a full clone)"
    )


class TfliteModel:
    """One ``.tflite`` model with a float32 NHWC input.

    Args:
        content: the model file's bytes.
        threads: interpreter threads.

    Attributes:
        input_size: side of the square input, pixels.
    """

    def __init__(self, content: bytes, threads: int = DEFAULT_THREADS) -> None:
        self._interpreter = _interpreter_class()(model_content=content, num_threads=threads)
        self._interpreter.allocate_tensors()
        (details,) = self._interpreter.get_input_details()
        self._input_index = details["index"]
        self.input_size = int(details["shape"][1])
        self._outputs = {d["name"]: d["index"] for d in self._interpreter.get_output_details()}

    def __call__(self, image: np.ndarray) -> dict[str, np.ndarray]:
        """Run on ``(S, S, 3)`` float32 input; returns ``{output tensor name: output}`` with the
        batch axis dropped (names ``Identity``, ``Identity_1``, ...)."""
        self._interpreter.set_tensor(self._input_index, image[None].astype(np.float32))
        self._interpreter.invoke()
        return {name: self._interpreter.get_tensor(i)[0] for name, i in self._outputs.items()}


def drop_output(content: bytes, name: str) -> bytes:
    """The model without its output tensor ``name`` and the operators that only it needs.

    Works on the TFLite flatbuffer with the schema module LiteRT ships; the remaining outputs
    are computed exactly as before (a test compares them).

    Raises:
        ValueError: the model has no output called ``name``.
    """
    from ai_edge_litert import schema_py_generated as schema  # on first use, as the runtime

    model = schema.ModelT.InitFromObj(schema.Model.GetRootAsModel(content, 0))
    graph = model.subgraphs[0]
    kept = [i for i in graph.outputs if graph.tensors[i].name.decode() != name]
    if len(kept) == len(graph.outputs):
        raise ValueError(f"the model has no output {name!r}")
    needed, operators = set(kept), []
    for operator in reversed(graph.operators):
        if any(i in needed for i in operator.outputs):
            operators.append(operator)
            needed.update(i for i in operator.inputs if i >= 0)
    graph.operators, graph.outputs = operators[::-1], kept
    builder = flatbuffers.Builder(len(content))
    builder.Finish(model.Pack(builder), file_identifier=b"TFL3")
    return bytes(builder.Output())


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
