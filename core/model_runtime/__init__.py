"""TF.js graph models run with torch (``hkpd.model_runtime``).

:class:`GraphModel` loads a ``model.json`` and its weight shards and runs it on CPU or CUDA
with TensorFlow's semantics, without TensorFlow; damaged or hostile files raise
:class:`ModelFileError`. Imports nothing of hkpd but ``hkpd.assets`` (the shipped models).
"""

from __future__ import annotations

from hkpd.model_runtime.graph_file import ModelFileError, read_graph_file
from hkpd.model_runtime.graph_model import GraphModel, GraphRunError

__all__ = ["GraphModel", "GraphRunError", "ModelFileError", "read_graph_file"]
