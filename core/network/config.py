"""``NetworkConfig``: every hyperparameter of :class:`hkpd.network.DistributionNetwork`.

The config round-trips through a plain dict (:meth:`NetworkConfig.to_dict`,
:meth:`NetworkConfig.from_dict`) so that training checkpoints can store it as JSON-friendly data.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

from hkpd.proxy import DEFAULT_IMAGE_PROXY, proxy_channels

POSE_HEADS = ("independent", "hierarchical")
"""Accepted values of :attr:`NetworkConfig.pose_head`."""


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
        # Tuples may arrive as lists from JSON.
        object.__setattr__(self, "backbone_blocks", tuple(int(b) for b in self.backbone_blocks))
        object.__setattr__(self, "joint_hidden", tuple(int(h) for h in self.joint_hidden))
        if self.pose_head not in POSE_HEADS:
            raise ValueError(f"pose_head must be one of {POSE_HEADS}, got {self.pose_head!r}")
        if self.backbone_base_width < 1 or not self.backbone_blocks:
            raise ValueError(
                "backbone_base_width must be positive and backbone_blocks non-empty, got "
                f"{self.backbone_base_width} and {self.backbone_blocks}"
            )
        if any(b < 1 for b in self.backbone_blocks) or any(h < 1 for h in self.joint_hidden):
            raise ValueError("backbone_blocks and joint_hidden entries must be positive")
        if min(self.head_hidden, self.num_betas, self.input_channels) < 1:
            raise ValueError("head_hidden, num_betas and input_channels must be positive")
        if self.input_channels != proxy_channels(self.image_proxy):  # also checks the name
            raise ValueError(
                f"the {self.image_proxy!r} proxy has {proxy_channels(self.image_proxy)} channels, "
                f"but input_channels is {self.input_channels}"
            )
        if self.image_size < 32:
            raise ValueError(f"image_size must be at least 32 pixels, got {self.image_size}")
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
