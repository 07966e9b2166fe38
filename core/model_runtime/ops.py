"""Every op the runtime implements, registered by importing the op modules; one lookup.

The op types (see each module): ``ops_math`` (element-wise, reductions, ``Softmax``, ``Cast``,
``ArgMax``), ``ops_shape`` (reshapes, transposes, concatenation, splits, pads,
``StridedSlice``), ``ops_index`` (gathers, ``SparseToDense``, ``TopKV2``) and ``ops_nn``
(convolutions, ``MatMul``, ``MaxPool``, ``ResizeBilinear``). ``Const`` and ``Placeholder`` are
the graph model's own.
"""

from __future__ import annotations

import torch

from hkpd.model_runtime import ops_index, ops_math, ops_nn, ops_shape
from hkpd.model_runtime.graph_file import GraphNode
from hkpd.model_runtime.op_registry import OP_BUILDERS, NodeError, PreparedOp

OP_MODULES = (ops_index, ops_math, ops_nn, ops_shape)
"""The modules whose import registers the ops (named so the import is used)."""

GRAPH_OPS = frozenset({"Const", "Placeholder", "NoOp"})
"""Op types the graph model handles itself: constants, inputs and ``NoOp`` (no outputs; only
ever a control input, which execution order by data makes moot)."""


def supported_ops() -> frozenset[str]:
    """Every op type a graph may use."""
    return frozenset(OP_BUILDERS) | GRAPH_OPS


def prepare_op(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """The node ready to run (see :class:`~hkpd.model_runtime.op_registry.PreparedOp`).

    Args:
        node: the node.
        constants: for each input, its value if it is constant, else None.

    Raises:
        NodeError: the op is unknown or the node's attributes are malformed.
    """
    builder = OP_BUILDERS.get(node.op)
    if builder is None:
        raise NodeError(f"the op {node.op!r} is not implemented")
    return builder(node, constants)
