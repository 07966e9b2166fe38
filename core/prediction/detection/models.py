"""BlazePose's two TFLite models (shipped in ``hkpd.assets/blazepose``), run with LiteRT.

LiteRT (``ai-edge-litert``, Google's TensorFlow Lite runtime on PyPI) executes the ``.tflite``
files; nothing is converted or downloaded. :func:`drop_output` can remove an unused output and
the operators only it needs while loading (the landmark model's 256×256 segmentation head is
37 % of its time). Each :class:`TfliteModel` holds one interpreter and is not thread-safe (the
caller serialises calls).
"""

from __future__ import annotations

import hashlib
import os
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
    return shipped_file(parts, "BlazePose model", REINSTALL)


MODEL_FILES: dict[str, tuple[int, str]] = {
    "pose_detection.tflite": (
        2_959_046,
        "9ba9dd3d42efaaba86b4ff0122b06f29c4122e756b329d89dca1e297fd8f866c",
    ),
    "pose_landmark_full.tflite": (
        6_440_512,
        "e9a5c5cb17f736fafd4c2ec1da3b3d331d6edbe8a0d32395855aeb2cdfd64b9f",
    ),
}
"""Each shipped model's size in bytes and sha256, as ``assets/blazepose/NOTICE.md`` lists
them (the files are copied unmodified from the ``mediapipe==0.10.21`` wheel)."""

REINSTALL = "reinstall hkpd (pip install -e . from a full clone)"
"""What to do about a missing or damaged model file."""

_verified: dict[str, tuple[int, int, int]] = {}
"""Path -> ``(size, mtime_ns, inode)`` of each model file whose sha256 this process checked."""


class DamagedModelError(ValueError):
    """A BlazePose model file is not the one hkpd ships; the message names it and the fix."""


def read_blazepose_model(parts: tuple[str, str]) -> bytes:
    """The bytes of one of BlazePose's model files (:data:`DETECTOR_MODEL`,
    :data:`LANDMARK_MODEL`), checked against :data:`MODEL_FILES`: its size always, its sha256
    once per process and file (again only when the file's size, time or inode change; 13-17 ms
    for both files on the 2-core development machine at load 9, docs/benchmarks.md).

    Raises:
        FileNotFoundError: the file is missing (a broken install).
        DamagedModelError: the file has another size or sha256 (truncated, emptied, replaced
            by a text pointer, or changed anywhere), naming it and how to restore it.
    """
    path = blazepose_model_path(parts)
    size, digest = MODEL_FILES[parts[1]]
    with path.open("rb") as file:
        status = os.fstat(file.fileno())
        if status.st_size != size:
            raise DamagedModelError(
                f"the BlazePose model {path} is damaged ({status.st_size:,} bytes instead of "
                f"{size:,}); {REINSTALL} to restore it"
            )
        content = file.read(size + 1)
    stamp = (status.st_size, status.st_mtime_ns, status.st_ino)
    if len(content) != size or _verified.get(str(path)) != stamp:
        found = hashlib.sha256(content).hexdigest()
        if found != digest:
            raise DamagedModelError(
                f"the BlazePose model {path} is damaged (its sha256 is {found[:16]}..., not the "
                f"shipped {digest[:16]}...); {REINSTALL} to restore it"
            )
        _verified[str(path)] = stamp
    return content


def forget_verified_models() -> None:
    """Check every model's sha256 again on its next read (for tests)."""
    _verified.clear()


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
