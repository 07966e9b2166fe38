"""Tests for hkpd.network: shapes, gradients, config round trip, input checks and the
hierarchical head's conditioning on ancestors."""

from __future__ import annotations

import copy

import pytest
import torch

from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.distributions import BodyDistribution, KinematicMatrixFisher
from hkpd.kinematic_tree import BODY_JOINT_NAMES, BODY_PARENTS, ancestors
from hkpd.network import (
    DistributionNetwork,
    GroupedLinear,
    HierarchicalHead,
    NetworkConfig,
)

TINY = {"backbone_base_width": 8, "head_hidden": 32, "joint_hidden": (16,), "image_size": 64}


@pytest.fixture(params=["independent", "hierarchical"])
def network(request) -> DistributionNetwork:
    torch.manual_seed(0)
    return DistributionNetwork(NetworkConfig(pose_head=request.param, **TINY))


def test_output_shapes_and_constraints(network):
    output = network(torch.rand(3, 18, 64, 64))
    assert isinstance(output, BodyDistribution)
    assert output.F.shape == (3, 23, 3, 3)
    assert output.shape_mean.shape == output.shape_std.shape == (3, 10)
    assert output.global_orient.shape == (3, 3, 3)
    assert output.camera.shape == (3, 3)
    assert (output.shape_std > 0).all() and (output.camera[:, 0] > 0).all()
    eye = torch.eye(3).expand(3, 3, 3)
    R = output.global_orient
    torch.testing.assert_close(R @ R.transpose(1, 2), eye, atol=1e-5, rtol=0)
    torch.testing.assert_close(torch.linalg.det(R), torch.ones(3), atol=1e-5, rtol=0)


def test_initial_prediction_is_sensible(network):
    output = network(torch.rand(2, 18, 64, 64))
    # Upright, facing the camera, weak-perspective scale near 1 NDC per metre.
    torch.testing.assert_close(
        output.global_orient, FRONTAL_GLOBAL_ORIENT.expand(2, 3, 3), atol=0.1, rtol=0
    )
    assert ((output.camera[:, 0] - 1.0).abs() < 0.1).all()
    # Pose distributions near concentration 1 about the identity: modes close to identity.
    mode = output.pose_distribution().mode
    assert (mode - torch.eye(3)).abs().amax() < 0.2


def test_distributions(network):
    output = network(torch.rand(2, 18, 64, 64))
    pose = output.pose_distribution()
    assert isinstance(pose, KinematicMatrixFisher)
    assert pose.parents == BODY_PARENTS and pose.batch_shape == (2,)
    assert pose.rsample(4).shape == (4, 2, 23, 3, 3)
    shape = output.shape_distribution()
    assert shape.batch_shape == (2,) and shape.event_shape == (10,)
    torch.testing.assert_close(shape.mean, output.shape_mean)


def test_gradients_reach_the_backbone(network):
    output = network(torch.rand(2, 18, 64, 64))
    loss = (
        output.F.square().sum()
        + output.shape_mean.sum()
        + output.shape_std.sum()
        + output.global_orient.sum()
        + output.camera.sum()
    )
    loss.backward()
    first_conv = network.backbone.stem[0].weight
    assert first_conv.grad is not None and first_conv.grad.abs().sum() > 0
    for name, parameter in network.named_parameters():
        assert parameter.grad is not None, f"no gradient for {name}"
        assert torch.isfinite(parameter.grad).all(), name


@pytest.mark.parametrize("base_width", [4, 8])
def test_backbone_weight_gradients_are_right_and_repeatable(base_width):
    """Narrow backbones' shortcut projections (1x1, stride 2, < 8 input channels) got a wrong,
    call-to-call different weight gradient from torch 2.13's channels-last CPU kernel (and a
    corrupted heap with one thread); every width must match the same network in float64."""
    from hkpd.network.backbone import ResNetBackbone

    torch.manual_seed(0)
    backbone = ResNetBackbone(18, base_width)
    for module in backbone.modules():  # non-zero residual branches, so every weight matters
        if isinstance(module, torch.nn.BatchNorm2d):
            torch.nn.init.ones_(module.weight)
    images = torch.rand(4, 18, 32, 32)

    def gradients(network: torch.nn.Module, dtype: torch.dtype) -> dict[str, torch.Tensor]:
        network.zero_grad()
        network(images.to(dtype)).square().sum().backward()
        return {name: p.grad.double() for name, p in network.named_parameters()}

    first = gradients(backbone, torch.float32)
    for _ in range(3):
        again = gradients(backbone, torch.float32)
        assert all(torch.equal(again[name], first[name]) for name in first)
    exact = gradients(copy.deepcopy(backbone).double(), torch.float64)
    for name, value in exact.items():  # float32 rounding: ~1e-3 of a parameter's largest
        error = (first[name] - value).abs().max() / value.abs().max().clamp_min(1e-12)
        assert error < 2e-2, name  # the wrong kernel was off by ~0.5


def test_config_round_trip_and_from_config():
    config = NetworkConfig(pose_head="independent", **TINY)
    data = config.to_dict()
    assert data["joint_hidden"] == [16] and data["backbone_blocks"] == [2, 2, 2, 2]
    assert NetworkConfig.from_dict(data) == config
    network = DistributionNetwork.from_config(data)
    assert network.config == config
    with pytest.raises(ValueError, match="unknown NetworkConfig keys"):
        NetworkConfig.from_dict({**data, "widht": 3})
    with pytest.raises(ValueError, match="pose_head"):
        NetworkConfig(pose_head="cascade")


def test_the_image_proxy_sets_the_input_channels():
    rgb = DistributionNetwork(NetworkConfig(image_proxy="rgb", input_channels=20, **TINY)).eval()
    assert rgb(torch.rand(1, 20, 64, 64)).F.shape == (1, 23, 3, 3)
    assert NetworkConfig.from_dict(rgb.config.to_dict()).image_proxy == "rgb"
    with pytest.raises(ValueError, match="'rgb' proxy has 20 channels, but input_channels is 18"):
        NetworkConfig(image_proxy="rgb")
    with pytest.raises(ValueError, match="unknown image proxy"):
        NetworkConfig(image_proxy="depth")


def test_state_dict_loads_into_network_from_same_config(network):
    clone = DistributionNetwork.from_config(network.config.to_dict())
    clone.load_state_dict(network.state_dict())
    network.eval()
    clone.eval()
    x = torch.rand(2, 18, 64, 64)
    torch.testing.assert_close(clone(x).F, network(x).F)


def test_bad_input_is_rejected(network):
    with pytest.raises(ValueError, match=r"proxy must have shape \(B, 18, 64, 64\)"):
        network(torch.rand(2, 17, 64, 64))
    with pytest.raises(ValueError, match="image_size=64"):
        network(torch.rand(2, 18, 128, 128))
    with pytest.raises(TypeError, match="floating-point"):
        network(torch.zeros(2, 18, 64, 64, dtype=torch.uint8))


def test_grouped_linear_matches_separate_layers():
    torch.manual_seed(1)
    layer = GroupedLinear(3, 5, 4)
    x = torch.randn(7, 3, 5)
    expected = torch.stack([x[:, g] @ layer.weight[g] + layer.bias[g] for g in range(3)], dim=1)
    torch.testing.assert_close(layer(x), expected)
    with pytest.raises(ValueError, match="expects"):
        layer(torch.randn(7, 2, 5))


def _descendants(joint: int) -> set[int]:
    return {j for j in range(23) if joint in ancestors(BODY_PARENTS, j)}


@pytest.mark.parametrize("joint_name", ["left_hip", "spine3", "right_shoulder"])
def test_hierarchical_head_conditions_on_ancestors_only(joint_name):
    torch.manual_seed(2)
    head = HierarchicalHead(
        feature_dim=24,
        hidden=32,
        joint_hidden=(16, 16),
        num_betas=10,
        parents=BODY_PARENTS,
        initial_pose_concentration=1.0,
        initial_shape_std=1.0,
        initial_camera_scale=1.0,
    )
    features = torch.randn(3, 24)
    joint = BODY_JOINT_NAMES.index(joint_name)
    change = torch.randn(3, 3, 3) * 3.0

    def perturb(level, F):
        if joint not in level:
            return F
        F = F.clone()
        F[:, level.index(joint)] += change
        return F

    with torch.no_grad():
        base = head.predict(features).F
        edited = head.predict(features, edit=perturb).F
    descendants = _descendants(joint)
    assert descendants, "test joints must have children"
    for j in range(23):
        difference = (edited[:, j] - base[:, j]).abs().amax().item()
        if j == joint:
            torch.testing.assert_close(edited[:, j], base[:, j] + change)
        elif j in descendants:
            assert difference > 1e-5, f"{BODY_JOINT_NAMES[j]} ignores its ancestor {joint_name}"
        else:
            assert difference == 0.0, f"{BODY_JOINT_NAMES[j]} depends on non-ancestor {joint_name}"


def test_hierarchical_head_is_deterministic_per_example():
    """Examples in a batch do not influence each other (no cross-batch mixing in the head)."""
    torch.manual_seed(3)
    network = DistributionNetwork(NetworkConfig(pose_head="hierarchical", **TINY)).eval()
    x = torch.rand(4, 18, 64, 64)
    with torch.no_grad():
        together = network(x).F
        alone = network(x[2:3]).F
    torch.testing.assert_close(together[2:3], alone, atol=1e-5, rtol=1e-5)


def test_mixed_precision_outputs_are_full_precision(network):
    """Under autocast the heads still decode (and SVD) in float32."""
    with torch.autocast("cpu", dtype=torch.bfloat16):
        output = network(torch.rand(2, 18, 64, 64))
    for name, value in vars(output).items():
        assert value.dtype == torch.float32, name
        assert torch.isfinite(value).all(), name
    output.F.sum().backward()
    assert network.backbone.stem[0].weight.grad is not None


def test_detached_shape_input_keeps_pose_losses_off_the_shape_outputs():
    torch.manual_seed(0)
    network = DistributionNetwork(NetworkConfig(backbone_base_width=8, image_size=32))
    proxies = torch.rand(3, 18, 32, 32)
    num_betas = network.config.num_betas

    def shape_row_gradient() -> tuple[torch.Tensor, float]:
        network.zero_grad(set_to_none=True)
        output = network(proxies)
        output.F.square().sum().backward()  # a loss on the pose only
        rows = network.head.globals_out.weight.grad[: 2 * num_betas]  # shape mean and std
        return output.F.detach(), float(rows.abs().sum())

    coupled_F, coupled = shape_row_gradient()
    network.head.detach_shape_input = True
    detached_F, detached = shape_row_gradient()
    assert coupled > 0.0  # the paper's head trains the shape outputs through the joint streams
    assert detached == 0.0
    torch.testing.assert_close(detached_F, coupled_F)  # same values, other gradients
