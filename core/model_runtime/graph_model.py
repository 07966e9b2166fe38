"""A TF.js graph model run with torch: :class:`GraphModel`.

``GraphModel.load(path)`` reads ``model.json`` and its shards (``graph_file``), checks that
every op is implemented, folds the nodes whose inputs are all constants, prepares each other
node once (kernels in torch's layout: ``ops``) and orders them topologically. ``run`` executes
that order on the given inputs under ``torch.no_grad`` (not ``inference_mode``: its outputs
are ordinary tensors that callers may modify or use in autograd later), freeing each
intermediate tensor after its last use. No TensorFlow is needed.

Example::

    model = GraphModel.load("faceres.json")
    outputs = model.run({"input_1": faces})  # faces (N, 224, 224, 3) float32
    p_male = outputs["gender_pred/Sigmoid"]  # (N, 1)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from hkpd.model_runtime.graph_file import GraphFile, GraphNode, ModelFileError, read_graph_file
from hkpd.model_runtime.op_registry import NodeError, PreparedOp, torch_dtype
from hkpd.model_runtime.ops import prepare_op, supported_ops

Reference = tuple[str, int]
"""A node's output: ``(node name, output index)``."""


class GraphRunError(ValueError):
    """Running the graph failed on the given inputs; the message names the file and node."""


def parse_reference(text: str) -> Reference:
    """``"name"`` -> ``(name, 0)``, ``"name:k"`` -> ``(name, k)``."""
    name, _, index = text.rpartition(":")
    if name and index.isdigit():
        return name, int(index)
    return text, 0


def reference_name(reference: Reference) -> str:
    """The inverse of :func:`parse_reference` (``":0"`` left out)."""
    return reference[0] if reference[1] == 0 else f"{reference[0]}:{reference[1]}"


@dataclass(frozen=True)
class _Step:
    """One prepared node in a plan: the value slots it reads (None: absorbed), writes (output
    index -> slot, for the outputs something reads) and frees after it ran."""

    node: GraphNode
    prepared: PreparedOp
    reads: tuple[int | None, ...]
    writes: tuple[tuple[int, int], ...]
    frees: tuple[int, ...]


@dataclass(frozen=True)
class _Plan:
    """How to compute some outputs: slots of constants and inputs, the steps, the results."""

    slot_count: int
    constants: tuple[tuple[int, Reference], ...]
    inputs: tuple[tuple[str, int], ...]
    steps: tuple[_Step, ...]
    outputs: tuple[tuple[str, int], ...]


@dataclass(frozen=True)
class InputSpec:
    """One input of the model: its torch dtype kind and shape (-1: any size; None: any)."""

    name: str
    dtype: str
    shape: tuple[int, ...] | None


class GraphModel:
    """A loaded graph model. Build with :meth:`load`; move with :meth:`to`; run with :meth:`run`.

    Attributes:
        path: the ``model.json``.
        inputs: the model's inputs (its ``Placeholder`` nodes) by name.
        output_names: the outputs :meth:`run` returns by default (the signature's, else every
            node nothing reads), e.g. ``"gender_pred/Sigmoid"``; ``"name:k"`` for output k > 0.
    """

    def __init__(self, graph: GraphFile) -> None:
        self.path = graph.path
        self._nodes = {node.name: node for node in graph.nodes}
        self._check_ops(graph)
        self.output_names = self._default_outputs(graph)
        order = self._topological_order([parse_reference(n) for n in self.output_names])
        self.inputs = self._input_specs([node.name for node in graph.nodes])
        self._constants: dict[Reference, torch.Tensor] = {}
        self._prepared: dict[str, PreparedOp] = {}
        self._plans: dict[tuple[str, ...], _Plan] = {}
        self._prepare(order, graph)
        self._float_dtype = torch.float32
        self._device = torch.device("cpu")

    @classmethod
    def load(cls, path: str | Path) -> GraphModel:
        """Read, check and prepare the model at ``path`` (its ``model.json``).

        Raises:
            FileNotFoundError: no such file.
            ModelFileError: the file or its shards are damaged, hostile or use an op this
                runtime does not implement (one line naming the file and what is wrong).
        """
        return cls(read_graph_file(path))

    def _error(self, node: GraphNode, message: str) -> ModelFileError:
        return ModelFileError(f"{self.path}: node {node.name!r} ({node.op}): {message}")

    def _check_ops(self, graph: GraphFile) -> None:
        """Refuse a graph with an op this runtime does not implement, naming op and node."""
        known = supported_ops()
        for node in graph.nodes:
            if node.op not in known:
                raise ModelFileError(
                    f"{self.path}: node {node.name!r} uses the op {node.op!r}, which hkpd's "
                    f"model runtime does not implement"
                )

    def _default_outputs(self, graph: GraphFile) -> list[str]:
        """The signature's outputs (checked to exist), else the nodes nothing reads."""
        if graph.outputs:
            names = [reference_name(parse_reference(out.name)) for out in graph.outputs]
        else:
            read = {parse_reference(ref)[0] for node in graph.nodes for ref in node.inputs}
            sinks = [n for n in graph.nodes if n.name not in read]
            names = [n.name for n in sinks if n.op not in ("Const", "NoOp")]
        for name in names:
            if parse_reference(name)[0] not in self._nodes:
                raise ModelFileError(f"{self.path}: the output {name!r} is no node of the graph")
        if not names:
            raise ModelFileError(f"{self.path}: the graph has no outputs")
        return names

    def _topological_order(self, targets: list[Reference]) -> list[str]:
        """Names of the nodes ``targets`` depend on, each after its inputs; refuses cycles and
        references to missing nodes."""
        order: list[str] = []
        state: dict[str, int] = {}  # 1: being visited, 2: done
        for target, _ in targets:
            stack = [(target, 0)]
            while stack:
                name, position = stack.pop()
                node = self._nodes[name]
                if position == 0:
                    if state.get(name) == 2:
                        continue
                    state[name] = 1
                if position < len(node.inputs):
                    stack.append((name, position + 1))
                    child = parse_reference(node.inputs[position])[0]
                    if child not in self._nodes:
                        raise self._error(node, f"reads {child!r}, which is no node")
                    if state.get(child) == 1:
                        raise self._error(node, f"is part of a cycle through {child!r}")
                    if state.get(child) != 2:
                        stack.append((child, 0))
                else:
                    state[name] = 2
                    order.append(name)
        return order

    def _input_specs(self, order: list[str]) -> dict[str, InputSpec]:
        """The placeholders among ``order`` with their dtype and shape attributes (every
        placeholder of the graph: :meth:`run` requires those its outputs need)."""
        specs = {}
        for name in order:
            node = self._nodes[name]
            if node.op == "Placeholder":
                dtype = node.attributes.get("dtype") or "DT_FLOAT"
                try:
                    torch_dtype(dtype, torch.float32)
                except NodeError as error:
                    raise self._error(node, str(error)) from None
                shape = node.attributes.get("shape")
                specs[name] = InputSpec(name, dtype, shape if isinstance(shape, tuple) else None)
        return specs

    def _prepare(self, order: list[str], graph: GraphFile) -> None:
        """Constants from the weights, constant nodes folded, the rest prepared as steps."""
        for name in order:
            node = self._nodes[name]
            if node.op == "Placeholder":
                continue
            if node.op == "Const":
                self._constants[(name, 0)] = self._constant(node, graph)
                continue
            references = [parse_reference(ref) for ref in node.inputs]
            for reference in references:
                folded = (reference[0], 0) in self._constants
                if folded and reference not in self._constants:
                    raise self._error(node, f"reads {reference_name(reference)!r}, no output")
            constants = [self._constants.get(ref) for ref in references]
            try:
                prepared = prepare_op(node, constants)
                if all(value is not None for value in constants):
                    self._fold(node, prepared, constants)
                    continue
            except NodeError as error:
                raise self._error(node, str(error)) from None
            self._prepared[name] = prepared

    def _constant(self, node: GraphNode, graph: GraphFile) -> torch.Tensor:
        """A ``Const`` node's value from the weights."""
        value = graph.weights.get(node.name)
        if value is None:
            raise self._error(node, "a constant without a weight of that name")
        return torch.from_numpy(np.array(value))

    def _fold(self, node: GraphNode, prepared: PreparedOp, constants: list) -> None:
        """Run a node whose inputs are all constants now; its outputs become constants."""
        arguments = [None if i in prepared.absorbed else v for i, v in enumerate(constants)]
        try:
            with torch.no_grad():
                outputs = prepared.function(arguments, prepared.params)
        except NodeError:
            raise
        except (RuntimeError, IndexError, TypeError, ValueError) as error:
            raise self._error(node, f"folding it failed: {error}") from None
        for index, value in enumerate(outputs):
            self._constants[(node.name, index)] = value

    def _plan(self, outputs: tuple[str, ...]) -> _Plan:
        """The (cached) plan that computes ``outputs``: only the nodes they need, each
        intermediate freed after its last reader."""
        if outputs in self._plans:
            return self._plans[outputs]
        targets = [parse_reference(name) for name in outputs]
        for name in outputs:
            reference = parse_reference(name)
            known = reference[0] in self._prepared or reference[0] in self.inputs
            if reference not in self._constants and not known:
                raise KeyError(f"{self.path}: {name!r} is no output this model computes")
        slots: dict[Reference, int] = {}

        def slot(reference: Reference) -> int:
            return slots.setdefault(reference, len(slots))

        reads_of: list[tuple[int | None, ...]] = []
        names = [n for n in self._topological_order(targets) if n in self._prepared]
        for name in names:
            node, prepared = self._nodes[name], self._prepared[name]
            references = [parse_reference(ref) for ref in node.inputs]
            reads_of.append(tuple(
                None if i in prepared.absorbed else slot(ref) for i, ref in enumerate(references)
            ))  # fmt: skip
        output_slots = tuple((name, slot(ref)) for name, ref in zip(outputs, targets, strict=True))
        steps = self._steps_with_frees(names, reads_of, slots, {s for _, s in output_slots})
        constants = tuple((s, ref) for ref, s in slots.items() if ref in self._constants)
        inputs = tuple((ref[0], s) for ref, s in slots.items() if ref[0] in self.inputs)
        plan = _Plan(len(slots), constants, inputs, steps, output_slots)
        self._plans[outputs] = plan
        return plan

    def _steps_with_frees(
        self,
        names: list[str],
        reads_of: list[tuple[int | None, ...]],
        slots: dict[Reference, int],
        kept: set[int],
    ) -> tuple[_Step, ...]:
        """The steps of ``names``, each freeing the slots it was the last to read (not the
        constants' nor the ``kept`` outputs')."""
        last_reader: dict[int, int] = {}
        for position, reads in enumerate(reads_of):
            for read in reads:
                if read is not None:
                    last_reader[read] = position
        permanent = kept | {s for ref, s in slots.items() if ref in self._constants}
        steps = []
        for position, (name, reads) in enumerate(zip(names, reads_of, strict=True)):
            writes = tuple(
                (ref[1], s) for ref, s in slots.items() if ref[0] == name and ref not in
                self._constants
            )  # fmt: skip
            frees = tuple(
                s for s, last in last_reader.items() if last == position and s not in permanent
            )
            steps.append(_Step(self._nodes[name], self._prepared[name], reads, writes, frees))
        return tuple(steps)

    def to(self, device: torch.device | str | None = None, dtype: torch.dtype | None = None):
        """Move the constants and prepared kernels to ``device`` and/or make the model's float
        tensors ``dtype`` (e.g. float64 to check accumulation errors). Returns ``self``."""
        device = torch.device(device) if device is not None else self._device
        dtype = dtype or self._float_dtype

        def moved(value: torch.Tensor) -> torch.Tensor:
            if value.is_floating_point():
                return value.to(device=device, dtype=dtype)
            return value.to(device=device)

        self._constants = {ref: moved(value) for ref, value in self._constants.items()}
        for prepared in self._prepared.values():
            prepared.params = {key: moved(value) for key, value in prepared.params.items()}
        self._device, self._float_dtype = device, dtype
        return self

    @property
    def device(self) -> torch.device:
        """Where the model's tensors live (inputs are moved there)."""
        return self._device

    def run(
        self,
        inputs: Mapping[str, torch.Tensor | np.ndarray],
        outputs: Sequence[str] | None = None,
    ) -> dict[str, torch.Tensor]:
        """Run the graph.

        Args:
            inputs: each input by name (see :attr:`inputs`; ``"name:0"`` works too), in the
                layout and dtype kind the model declares (float or int), any batch size
                where the model leaves it free (-1).
            outputs: the outputs wanted (default :attr:`output_names`); any node of the
                graph the default outputs need may be named.

        Returns:
            Each wanted output by name, on the model's device.

        Raises:
            ValueError: an input is missing, unknown, of the wrong dtype kind or shape.
            GraphRunError: a node failed on these inputs (naming it).
        """
        wanted = tuple(outputs) if outputs is not None else tuple(self.output_names)
        plan = self._plan(wanted)
        values: list[torch.Tensor | None] = [None] * plan.slot_count
        for slot, reference in plan.constants:
            values[slot] = self._constants[reference]
        given = self._checked_inputs(inputs, {name for name, _ in plan.inputs})
        for name, slot in plan.inputs:
            values[slot] = given[name]
        with torch.no_grad():
            for step in plan.steps:
                self._run_step(step, values)
        shared = {slot for slot, _ in plan.constants} | {slot for _, slot in plan.inputs}
        return {  # a constant or an input given back is copied: callers may change outputs
            name: values[slot].clone() if slot in shared else values[slot]
            for name, slot in plan.outputs
        }

    def _run_step(self, step: _Step, values: list[torch.Tensor | None]) -> None:
        """Run one step on ``values`` (slots), writing its outputs and freeing its dead slots."""
        arguments = [None if read is None else values[read] for read in step.reads]
        try:
            results = step.prepared.function(arguments, step.prepared.params)
        except (RuntimeError, IndexError, TypeError, ValueError) as error:
            message = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise GraphRunError(
                f"{self.path}: node {step.node.name!r} ({step.node.op}) failed: {message}"
            ) from None
        for index, slot in step.writes:
            if index >= len(results):
                raise GraphRunError(f"{self.path}: node {step.node.name!r} has no output {index}")
            values[slot] = results[index]
        for slot in step.frees:
            values[slot] = None

    def _checked_inputs(
        self, inputs: Mapping[str, torch.Tensor | np.ndarray], needed: set[str]
    ) -> dict[str, torch.Tensor]:
        """The inputs by placeholder name, checked against :attr:`inputs` and converted to the
        model's device and dtypes."""
        given = {parse_reference(name)[0]: value for name, value in inputs.items()}
        unknown = sorted(set(given) - set(self.inputs))
        missing = sorted(needed - set(given))
        if unknown or missing:
            raise ValueError(
                f"{self.path}: inputs {sorted(self.inputs)} expected; unknown {unknown}, "
                f"missing {missing}"
            )
        return {name: self._checked_input(self.inputs[name], given[name]) for name in given}

    def _checked_input(self, spec: InputSpec, value: torch.Tensor | np.ndarray) -> torch.Tensor:
        """One input as a tensor of the model's dtype for it, its shape checked."""
        tensor = torch.as_tensor(value)
        wants_float = spec.dtype in ("DT_FLOAT", "DT_HALF", "DT_DOUBLE")
        if tensor.is_floating_point() != wants_float or tensor.is_complex():
            kind = "floating-point" if wants_float else "integer"
            raise ValueError(
                f"{self.path}: the input {spec.name!r} must be {kind} ({spec.dtype}), "
                f"got {tensor.dtype}"
            )
        shape = spec.shape
        if shape is not None and (
            tensor.dim() != len(shape)
            or any(want not in (-1, got) for want, got in zip(shape, tensor.shape, strict=True))
        ):
            raise ValueError(
                f"{self.path}: the input {spec.name!r} must have the shape {list(shape)} "
                f"(-1: any), got {list(tensor.shape)}"
            )
        dtype = torch_dtype(spec.dtype, self._float_dtype)
        return tensor.to(device=self._device, dtype=dtype)
