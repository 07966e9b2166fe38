"""The runtime's ops against hand-computed TensorFlow semantics, for the cases the parity
fixtures do not reach: asymmetric SAME and explicit padding, dilations, depthwise multipliers,
bilinear resizing in all three coordinate modes, StridedSlice's masks, TopKV2's tie order,
gathers, splits, integer division, casts, fused activations and weight dequantisation."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from model_runtime_files import const, node, placeholder, write_model

from hkpd.model_runtime import GraphModel
from hkpd.model_runtime.graph_file import GraphNode
from hkpd.model_runtime.op_registry import NodeError
from hkpd.model_runtime.ops import prepare_op, supported_ops

GENERATOR = np.random.default_rng(5)


def _run(op: str, inputs: list, constant: tuple[int, ...] = (), **attributes) -> tuple:
    """Run one op on ``inputs`` (numpy or torch); ``constant`` lists the inputs given to the
    builder as constants (absorbed where it can)."""
    tensors = [torch.as_tensor(np.asarray(value)) for value in inputs]
    constants = [tensors[i] if i in constant else None for i in range(len(tensors))]
    graph_node = GraphNode("n", op, tuple(f"i{i}" for i in range(len(inputs))), attributes)
    prepared = prepare_op(graph_node, constants)
    arguments = [None if i in prepared.absorbed else t for i, t in enumerate(tensors)]
    return prepared.function(arguments, prepared.params)


def _reference_conv(x, kernel, stride, dilation, pads, depthwise=False) -> np.ndarray:
    """NHWC convolution by loops in float64 with explicit ``pads`` (top, bottom, left, right)."""
    top, bottom, left, right = pads
    padded = np.pad(x.astype(np.float64), ((0, 0), (top, bottom), (left, right), (0, 0)))
    kh, kw = kernel.shape[:2]
    span_h, span_w = (kh - 1) * dilation + 1, (kw - 1) * dilation + 1
    out_h = (padded.shape[1] - span_h) // stride + 1
    out_w = (padded.shape[2] - span_w) // stride + 1
    rows = []
    for r in range(out_h):
        columns = []
        for c in range(out_w):
            window = padded[
                :,
                r * stride : r * stride + span_h : dilation,
                c * stride : c * stride + span_w : dilation,
            ]
            if depthwise:
                value = np.einsum("nhwc,hwcm->ncm", window, kernel).reshape(x.shape[0], -1)
            else:
                value = np.einsum("nhwc,hwco->no", window, kernel)
            columns.append(value)
        rows.append(np.stack(columns, 1))
    return np.stack(rows, 1)


def _attributes(stride: int, dilation: int, padding: str, explicit=None) -> dict:
    attributes = {
        "strides": [1, stride, stride, 1],
        "dilations": [1, dilation, dilation, 1],
        "padding": padding,
    }
    if explicit is not None:
        attributes["explicit_paddings"] = explicit
    return attributes


@pytest.mark.parametrize(
    ("size", "stride", "dilation", "padding", "pads"),
    [
        (4, 2, 1, "SAME", (0, 1, 0, 1)),  # TF puts the odd pixel after
        (5, 2, 1, "SAME", (1, 1, 1, 1)),
        (6, 1, 2, "SAME", (2, 2, 2, 2)),
        (7, 3, 1, "VALID", (0, 0, 0, 0)),
        (5, 1, 1, "EXPLICIT", (2, 0, 1, 3)),
    ],
)
@pytest.mark.parametrize("depthwise", [False, True])
def test_convolutions_pad_like_tensorflow(size, stride, dilation, padding, pads, depthwise) -> None:
    x = GENERATOR.standard_normal((2, size, size, 3)).astype(np.float32)
    kernel = GENERATOR.standard_normal((3, 3, 3, 2 if depthwise else 4)).astype(np.float32)
    explicit = [0, 0, pads[0], pads[1], pads[2], pads[3], 0, 0] if padding == "EXPLICIT" else None
    op = "DepthwiseConv2dNative" if depthwise else "Conv2D"
    (out,) = _run(op, [x, kernel], (1,), **_attributes(stride, dilation, padding, explicit))
    expected = _reference_conv(x, kernel, stride, dilation, pads, depthwise)
    assert out.shape == expected.shape
    np.testing.assert_allclose(out.numpy(), expected, atol=2e-5)


@pytest.mark.parametrize("fused", [["BiasAdd"], ["BiasAdd", "Relu6"], ["BiasAdd", "LeakyRelu"]])
def test_fused_convolution_adds_the_bias_then_activates(fused) -> None:
    x = 3 * GENERATOR.standard_normal((1, 4, 4, 2)).astype(np.float32)
    kernel = GENERATOR.standard_normal((1, 1, 2, 3)).astype(np.float32)
    bias = np.array([-1.0, 0.5, 2.0], np.float32)
    attributes = _attributes(1, 1, "VALID") | {"fused_ops": fused, "leakyrelu_alpha": 0.3}
    (out,) = _run("_FusedConv2D", [x, kernel, bias], (1, 2), **attributes)
    linear = np.einsum("nhwc,co->nhwo", x.astype(np.float64), kernel[0, 0]) + bias
    if "Relu6" in fused:
        linear = np.clip(linear, 0, 6)
    if "LeakyRelu" in fused:
        linear = np.where(linear < 0, 0.3 * linear, linear)
    np.testing.assert_allclose(out.numpy(), linear, atol=1e-5)


def test_fused_matmul_with_prelu_and_transposes() -> None:
    a = GENERATOR.standard_normal((3, 4)).astype(np.float32)
    b = GENERATOR.standard_normal((5, 4)).astype(np.float32)
    bias = GENERATOR.standard_normal(5).astype(np.float32)
    alpha = np.full(5, 0.1, np.float32)
    attributes = {"fused_ops": ["BiasAdd", "Prelu"], "num_args": 2, "transpose_b": True}
    (out,) = _run("_FusedMatMul", [a, b, bias, alpha], (), **attributes)
    linear = a.astype(np.float64) @ b.T + bias
    np.testing.assert_allclose(out.numpy(), np.where(linear < 0, 0.1 * linear, linear), atol=1e-5)


@pytest.mark.parametrize(
    ("align", "half", "expected"),
    [
        (False, False, [0.0, 0.5, 1.0, 1.0]),  # TF's legacy mode: source = 0.5·j
        (False, True, [0.0, 0.25, 0.75, 1.0]),  # half pixel: source = 0.5·(j + 0.5) - 0.5
        (True, False, [0.0, 1 / 3, 2 / 3, 1.0]),  # corners aligned: source = j / 3
    ],
)
def test_resize_bilinear_coordinate_modes(align, half, expected) -> None:
    image = np.array([0.0, 1.0], np.float32).reshape(1, 1, 2, 1)
    size = np.array([1, 4], np.int32)
    attributes = {"align_corners": align, "half_pixel_centers": half}
    (out,) = _run("ResizeBilinear", [image, size], (1,), **attributes)
    np.testing.assert_allclose(out.numpy().reshape(-1), expected, atol=1e-7)


def test_max_pool_same_ignores_padding() -> None:
    x = -np.arange(1, 17, dtype=np.float32).reshape(1, 4, 4, 1)  # all negative
    attributes = {"ksize": [1, 3, 3, 1], "strides": [1, 2, 2, 1], "padding": "SAME"}
    (out,) = _run("MaxPool", [x], **attributes)
    # windows rows/cols {0,1,2} and {2,3} (padding after): maxima at the top-left of each
    np.testing.assert_array_equal(out.numpy().reshape(2, 2), [[-1, -3], [-9, -11]])


@pytest.mark.parametrize(
    ("begin", "end", "strides", "masks", "index"),
    [
        ([1, 0], [3, 0], [1, 1], {"end_mask": 2}, np.s_[1:3, :]),
        (
            [0, -1],
            [0, 0],
            [1, 1],
            {"begin_mask": 1, "end_mask": 1, "shrink_axis_mask": 2},
            np.s_[:, -1],
        ),
        ([0, 0], [0, 0], [1, -2], {"begin_mask": 3, "end_mask": 3}, np.s_[:, ::-2]),
        ([1, 0, 0], [2, 0, 0], [1, 1, 1], {"new_axis_mask": 2, "end_mask": 4}, np.s_[1:2, None, :]),
        ([0, 2], [0, 5], [1, 1], {"ellipsis_mask": 1}, np.s_[..., 2:5]),
        ([-3, 1], [-1, 10], [1, 2], {}, np.s_[-3:-1, 1:10:2]),
    ],
)
def test_strided_slice_masks_follow_numpy(begin, end, strides, masks, index) -> None:
    x = np.arange(4 * 6, dtype=np.float32).reshape(4, 6)
    arguments = [x, np.array(begin, np.int32), np.array(end, np.int32), np.array(strides, np.int32)]
    (out,) = _run("StridedSlice", arguments, (1, 2, 3), **masks)
    np.testing.assert_array_equal(out.numpy(), x[index])


def test_top_k_orders_ties_by_index_and_returns_int32() -> None:
    x = np.array([[0.0, 2.0, 1.0, 2.0, 0.0, 0.0]], np.float32)
    values, indices = _run("TopKV2", [x, np.array(4, np.int32)], (1,), sorted=True)
    np.testing.assert_array_equal(values.numpy(), [[2.0, 2.0, 1.0, 0.0]])
    np.testing.assert_array_equal(indices.numpy(), [[1, 3, 2, 0]])
    assert indices.dtype == torch.int32


def test_gathers_pick_tensorflows_elements_and_refuse_out_of_range() -> None:
    params = np.arange(24, dtype=np.float32).reshape(2, 3, 4)
    (out,) = _run("GatherV2", [params, np.array([[2, 0]], np.int32), np.array(1, np.int32)], (2,))
    np.testing.assert_array_equal(out.numpy(), params[:, [[2, 0]]])
    indices = np.array([[1, 2], [0, 0]], np.int32)
    (out,) = _run("GatherNd", [params, indices])
    np.testing.assert_array_equal(out.numpy(), params[[1, 0], [2, 0]])
    with pytest.raises(NodeError, match="out of range"):
        _run("GatherNd", [params, np.array([[2, 0]], np.int32)])


def test_splits_concatenation_pack_and_unpack() -> None:
    x = np.arange(12, dtype=np.float32).reshape(2, 6)
    pieces = _run("SplitV", [x, np.array([1, -1, 2], np.int32), np.array(-1, np.int32)], (1, 2))
    assert [tuple(p.shape) for p in pieces] == [(2, 1), (2, 3), (2, 2)]
    halves = _run("Split", [np.array(1, np.int32), x], (0,), num_split=2)
    (joined,) = _run("ConcatV2", [*halves, np.array(1, np.int32)], (2,))
    np.testing.assert_array_equal(joined.numpy(), x)
    rows = _run("Unpack", [x], axis=0, num=2)
    (stacked,) = _run("Pack", list(rows), axis=1)
    np.testing.assert_array_equal(stacked.numpy(), x.T)
    (squeezed,) = _run("Squeeze", [x.reshape(1, 2, 1, 6)], squeeze_dims=[2])
    assert tuple(squeezed.shape) == (1, 2, 6)


def test_integer_division_casts_and_reductions() -> None:
    a, b = np.array([7, -7, 7, -7], np.int32), np.array([2, 2, -2, -2], np.int32)
    (quotient,) = _run("FloorDiv", [a, b])
    (remainder,) = _run("FloorMod", [a, b])
    np.testing.assert_array_equal(quotient.numpy(), [3, -4, -4, 3])
    np.testing.assert_array_equal(remainder.numpy(), [1, 1, -1, -1])
    assert quotient.dtype == torch.int32
    (cast,) = _run("Cast", [np.array([-1.7, 1.7], np.float32)], DstT="DT_INT32")
    np.testing.assert_array_equal(cast.numpy(), [-1, 1])
    x = GENERATOR.standard_normal((2, 3, 4)).astype(np.float32)
    (mean,) = _run("Mean", [x, np.array([1, -1], np.int32)], (1,), keep_dims=True)
    np.testing.assert_allclose(mean.numpy(), x.mean(axis=(1, 2), keepdims=True), atol=1e-6)
    (argmax,) = _run("ArgMax", [np.array([[1.0, 3.0, 3.0]], np.float32), np.array(1)], (1,))
    assert argmax.tolist() == [1] and argmax.dtype == torch.int32


def test_uint8_and_uint16_affine_weights_dequantise_as_tfjs(tmp_path) -> None:
    """value = q·scale + min (float32 weights), and Math.round half up for int32 weights."""
    quantised = np.array([0, 1, 2, 255], np.uint8)
    wide = np.array([0, 3, 65535], np.uint16)
    nodes = [
        placeholder("x", [1]),
        const("f"),
        const("i", "DT_INT32"),
        node("out", "Identity", ["f"]),
        node("out2", "Identity", ["i"]),
    ]
    path = write_model(
        tmp_path,
        nodes,
        {"f": np.zeros(4, np.float32), "i": np.zeros(3, np.int32)},
        quantization={
            "f": {"dtype": "uint8", "scale": 0.5, "min": -1.0},
            "i": {"dtype": "uint16", "scale": 0.5, "min": -1.0},
        },
        raw_weights={"f": quantised.tobytes(), "i": wide.astype("<u2").tobytes()},
        signature={"outputs": {"out": {"name": "out:0"}, "out2": {"name": "out2"}}},
    )
    outputs = GraphModel.load(path).run({"x": torch.zeros(1)})
    np.testing.assert_array_equal(outputs["out"].numpy(), [-1.0, -0.5, 0.0, 126.5])
    np.testing.assert_array_equal(outputs["out2"].numpy(), [-1, 1, 32767])  # 0.5 -> 1


def test_every_op_of_the_four_models_is_implemented() -> None:
    used = {
        "Add", "AddV2", "ArgMax", "Cast", "ConcatV2", "Const", "Conv2D", "DepthwiseConv2dNative",
        "Equal", "ExpandDims", "FloorDiv", "FloorMod", "FusedDepthwiseConv2dNative", "GatherNd",
        "GatherV2", "Identity", "LeakyRelu", "MaxPool", "Maximum", "Mean", "Minimum", "Mul",
        "Pack", "Pad", "PadV2", "Placeholder", "RealDiv", "Relu", "Relu6", "Reshape",
        "ResizeBilinear", "Sigmoid", "Softmax", "SparseToDense", "SplitV", "Sqrt",
        "SquaredDifference", "Squeeze", "StridedSlice", "Sub", "TopKV2", "Transpose",
        "Unpack", "_FusedConv2D", "_FusedMatMul",
    }  # fmt: skip
    assert used <= supported_ops()


def test_a_model_moves_to_float64_and_back(tmp_path) -> None:
    nodes = [placeholder("x", [-1, 2]), const("w"), node("out", "MatMul", ["x", "w"])]
    weights = {"w": np.array([[1.0, 2.0], [3.0, 4.0]], np.float32)}
    model = GraphModel.load(write_model(tmp_path, nodes, weights))
    x = torch.tensor([[1.0, 1.0]])
    assert model.to(dtype=torch.float64).run({"x": x})["out"].dtype == torch.float64
    out = model.to(dtype=torch.float32).run({"x": x})["out"]
    assert out.dtype == torch.float32 and out.tolist() == [[4.0, 6.0]]


def test_ops_of_the_packages_other_models() -> None:
    """AddN, BiasAdd, Slice, Tile, Select, Range, Size, Reciprocal (movenet-multipose, the hand
    and age models use them)."""
    a, b = np.array([1.0, 2.0], np.float32), np.array([3.0, -5.0], np.float32)
    (total,) = _run("AddN", [a, b, a])
    np.testing.assert_array_equal(total.numpy(), [5.0, -1.0])
    (biased,) = _run("BiasAdd", [np.zeros((2, 2), np.float32), b])
    np.testing.assert_array_equal(biased.numpy(), [[3.0, -5.0], [3.0, -5.0]])
    x = np.arange(24, dtype=np.float32).reshape(2, 3, 4)
    (sliced,) = _run("Slice", [x, np.array([1, 0, 1], np.int32), np.array([1, -1, 2], np.int32)])
    np.testing.assert_array_equal(sliced.numpy(), x[1:2, :, 1:3])
    (tiled,) = _run("Tile", [a, np.array([3], np.int32)], (1,))
    np.testing.assert_array_equal(tiled.numpy(), np.tile(a, 3))
    (chosen,) = _run("Select", [np.array([True, False]), x[:2, 0], -x[:2, 0]])
    np.testing.assert_array_equal(chosen.numpy(), np.stack([x[0, 0], -x[1, 0]]))
    (chosen,) = _run("SelectV2", [np.array([True, False, True, False]), x, -x])
    np.testing.assert_array_equal(chosen.numpy(), np.where([True, False, True, False], x, -x))
    (steps,) = _run("Range", [np.array(1, np.int32), np.array(8, np.int32), np.array(3, np.int32)])
    assert steps.tolist() == [1, 4, 7] and steps.dtype == torch.int32
    (steps,) = _run("Range", [np.float32(0.0), np.float32(1.0), np.float32(0.25)])
    np.testing.assert_array_equal(steps.numpy(), [0.0, 0.25, 0.5, 0.75])
    (size,) = _run("Size", [x])
    assert int(size) == 24
    (inverse,) = _run("Reciprocal", [np.array([4.0], np.float32)])
    assert inverse.tolist() == [0.25]


def test_average_pool_same_averages_only_inside_the_image() -> None:
    x = np.arange(1, 10, dtype=np.float32).reshape(1, 3, 3, 1)
    attributes = {"ksize": [1, 2, 2, 1], "strides": [1, 2, 2, 1], "padding": "SAME"}
    (out,) = _run("AvgPool", [x], **attributes)
    # windows {0,1}x{0,1}, {0,1}x{2}, {2}x{0,1}, {2}x{2} (padding after, not counted)
    expected = [[(1 + 2 + 4 + 5) / 4, (3 + 6) / 2], [(7 + 8) / 2, 9]]
    np.testing.assert_allclose(out.numpy().reshape(2, 2), expected)


def test_outputs_are_ordinary_tensors(tmp_path) -> None:
    """Not inference tensors: callers may change them in place or use them in autograd."""
    nodes = [placeholder("x", [-1, 2]), node("out", "Relu", ["x"])]
    out = GraphModel.load(write_model(tmp_path, nodes, {})).run({"x": torch.ones(1, 2)})["out"]
    assert not out.is_inference()
    out += 1
    assert out.tolist() == [[2.0, 2.0]]


def test_changing_an_output_that_is_a_constant_leaves_the_model_intact(tmp_path) -> None:
    nodes = [placeholder("x", [1]), const("c"), node("out", "Identity", ["c"])]
    model = GraphModel.load(write_model(tmp_path, nodes, {"c": np.array([1.0], np.float32)}))
    model.run({"x": torch.zeros(1)})["out"].fill_(7.0)
    assert model.run({"x": torch.zeros(1)})["out"].tolist() == [1.0]
