"""``NetworkConfig``: every hyperparameter of :class:`hkpd.network.DistributionNetwork`.

The config round-trips through a plain dict (:meth:`NetworkConfig.to_dict`,
:meth:`NetworkConfig.from_dict`) so that training checkpoints can store it as JSON-friendly data.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from numbers import Integral, Real
from typing import Any

from hkpd.proxy import DEFAULT_IMAGE_PROXY, proxy_channels

POSE_HEADS = ("independent", "hierarchical")
"""Accepted values of :attr:`NetworkConfig.pose_head`."""

INTEGER_LIMITS: dict[str, tuple[int, int]] = {
    "backbone_base_width": (1, 256),
    "head_hidden": (1, 8192),
    "num_betas": (1, 300),
    "image_size": (32, 1024),
    "input_channels": (1, 64),
}
"""Inclusive ``(lowest, highest)`` of each integer field. Generous for real use (the shipped
network: width 32, head 512, 10 betas, 128 px; ResNet-18 is width 64 at 256 px) and far below
what would exhaust memory: a checkpoint's config is checked against them (and its tensors'
shapes) before any network is built (``docs/network.md``, "Refused inputs")."""

SEQUENCE_LIMITS: dict[str, tuple[int, tuple[int, int]]] = {
    "backbone_blocks": (5, (1, 36)),
    "joint_hidden": (4, (1, 8192)),
}
"""``(most entries, (lowest, highest) entry)`` of each tuple field: up to 5 ResNet stages of up
to 36 blocks (ResNet-152's deepest stage has 36), up to 4 hidden layers per joint. The largest
backbone these allow (180 blocks) takes 0.4-0.8 s (load 10) to lay out on the ``meta`` device
for the shape check; the shipped one (8 blocks) ~30 ms."""


@dataclass(frozen=True)
class NetworkConfig:
    """Architecture of the distribution-prediction network.

    Attributes:
        backbone_base_width: channels of the first ResNet stage; the four stages have
            ``base × (1, 2, 4, 8)`` channels. 64 is ResNet-18 as in the paper; 32 or 16 give
            light networks for CPU training.
        backbone_blocks: basic blocks per stage; ``(2, 2, 2, 2)`` is ResNet-18.
        pose_head: ``"hierarchical"`` (the paper's f_hier, Eq. 6) or ``"independent"``
            (f_indep, Eq. 4).
        head_hidden: width of the fully connected layers on the pooled image features.
        joint_hidden: hidden widths of each joint's FC stream in the hierarchical head.
        num_betas: shape coefficients predicted (10 for SMPL-format bodies).
        image_size: side of the square proxy the network takes, pixels (256 normally).
        input_channels: proxy channels: the image proxy's (1 edge image) + 17 joint heatmaps;
            must match ``image_proxy``.
        image_proxy: what the network sees of the image (:data:`hkpd.proxy.IMAGE_PROXIES`):
            ``"edges"`` (hkpd's and the paper's), or ``"silhouette"`` / ``"rgb"`` (the proxy
            ablation's models; 18 or 20 input channels).
        initial_pose_concentration: at initialisation every joint's ``F`` is close to this
            multiple of the identity (see ``docs/network.md`` for the choice).
        initial_camera_scale: weak-perspective scale ``s`` at initialisation, NDC per metre.
        initial_shape_std: shape standard deviation at initialisation.
        concentration_gain: each joint also predicts a log-gain ``g`` from its own features and
            its ``F`` is scaled by ``exp(g)`` (an hkpd addition to the paper's heads, see
            ``docs/network.md``): one output moves a joint's whole concentration, so the network
            can learn quickly to be less sure of a hidden limb. The gain layers start at zero,
            so switching it on keeps a trained network's predictions at first.
    """

    backbone_base_width: int = 64
    backbone_blocks: tuple[int, ...] = (2, 2, 2, 2)
    pose_head: str = "hierarchical"
    head_hidden: int = 512
    joint_hidden: tuple[int, ...] = (256,)
    num_betas: int = 10
    image_size: int = 256
    input_channels: int = 18
    image_proxy: str = DEFAULT_IMAGE_PROXY
    initial_pose_concentration: float = 1.0
    initial_camera_scale: float = 1.0
    initial_shape_std: float = 1.0
    concentration_gain: bool = False

    def __post_init__(self) -> None:
        # Lists arrive for the tuples from JSON and checkpoints; every value is checked for its
        # type and range first, so that no network is ever built from a hostile config.
        for name, (low, high) in INTEGER_LIMITS.items():
            object.__setattr__(self, name, _whole_number(name, getattr(self, name), low, high))
        for name, (count, (low, high)) in SEQUENCE_LIMITS.items():
            entries = _whole_numbers(name, getattr(self, name), count, low, high)
            object.__setattr__(self, name, entries)
        for name in ("initial_pose_concentration", "initial_camera_scale", "initial_shape_std"):
            object.__setattr__(self, name, _finite_number(name, getattr(self, name)))
        if not isinstance(self.concentration_gain, bool):
            raise ValueError(
                f"concentration_gain must be true or false, got {_shown(self.concentration_gain)}"
            )
        if not isinstance(self.pose_head, str) or self.pose_head not in POSE_HEADS:
            raise ValueError(f"pose_head must be one of {POSE_HEADS}, got {_shown(self.pose_head)}")
        if not isinstance(self.image_proxy, str):
            raise ValueError(f"image_proxy must be a proxy name, got {_shown(self.image_proxy)}")
        if self.input_channels != proxy_channels(self.image_proxy):  # also checks the name
            raise ValueError(
                f"the {self.image_proxy!r} proxy has {proxy_channels(self.image_proxy)} channels, "
                f"but input_channels is {self.input_channels}"
            )
        if self.initial_camera_scale <= 0 or self.initial_shape_std <= 0:
            raise ValueError("initial_camera_scale and initial_shape_std must be positive")
        if self.initial_pose_concentration < 0:
            raise ValueError("initial_pose_concentration must be non-negative")

    def to_dict(self) -> dict[str, Any]:
        """A plain dict (lists instead of tuples) that :meth:`from_dict` accepts."""
        data = asdict(self)
        return {k: list(v) if isinstance(v, tuple) else v for k, v in data.items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> NetworkConfig:
        """Build a config from a dict such as :meth:`to_dict` returns.

        Raises:
            ValueError: on keys that are not config fields (e.g. a typo or a newer version).
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(
                f"unknown NetworkConfig keys {unknown}; the known keys are {sorted(known)}"
            )
        return cls(**data)


def _shown(value: object) -> str:
    """``repr(value)``, cut to 60 characters (a hostile file may store a huge value)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _whole_number(name: str, value: object, low: int, high: int) -> int:
    """``value`` as an int in ``low..high``, or a ValueError naming the field and the range."""
    if isinstance(value, bool) or not isinstance(value, Integral) or not low <= value <= high:
        raise ValueError(f"{name} must be an integer in {low}..{high}, got {_shown(value)}")
    return int(value)


def _whole_numbers(name: str, value: object, count: int, low: int, high: int) -> tuple[int, ...]:
    """``value`` as a tuple of 1..``count`` ints in ``low..high``, or a ValueError."""
    wanted = f"{name} must be a list of 1 to {count} integers in {low}..{high}"
    if not isinstance(value, (list, tuple)) or not 1 <= len(value) <= count:
        raise ValueError(f"{wanted}, got {_shown(value)}")
    try:
        return tuple(_whole_number(name, entry, low, high) for entry in value)
    except ValueError:
        raise ValueError(f"{wanted}, got {_shown(value)}") from None


def _finite_number(name: str, value: object) -> float:
    """``value`` as a finite float, or a ValueError naming the field."""
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {_shown(value)}")
    return float(value)
