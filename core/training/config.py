"""The training configuration: one readable dataclass, saved with every run and checkpoint.

Every field is also a command-line flag of ``hkpd-train`` (``--batch-size 16``), and
``--config run.json`` loads a saved configuration first, so a run can be repeated or tweaked.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import math
import re
import types
import typing
from dataclasses import dataclass
from pathlib import Path

from hkpd.network.config import NetworkConfig
from hkpd.poses.mixed_source import PoseMix
from hkpd.proxy import DEFAULT_IMAGE_PROXY, IMAGE_PROXIES, proxy_channels
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.generator import SyntheticDataConfig
from hkpd.synthesis.orientation import OrientationMix


@dataclass
class TrainConfig:
    """Everything that defines a training run.

    Attributes:
        out: run folder (checkpoints, CSV logs, curves, the config itself).
        poses: pose bank ``.npz`` from ``hkpd-poses build``; None uses the procedural prior.
        backgrounds: optional folder of background images (procedural clutter otherwise).
        steps: optimiser steps in total.
        batch_size: examples per step and process: under ``torchrun`` with N processes a step
            takes the averaged gradient of N x batch_size examples (the global batch).
        image_size: proxy side in pixels (256 as in the paper; smaller for quick tests).
        pose_head: ``"hierarchical"`` (the paper's f_hier) or ``"independent"`` (f_indep).
        backbone_base_width: channels of the first ResNet-18 stage (64 is the paper's; 32 or 16
            for CPU training).
        learning_rate: Adam learning rate (at the first step, if ``final_learning_rate`` is set).
            It applies to the global batch as it is: N processes with batch B take the steps
            one process takes with batch N x B at the same rate (no automatic scaling).
        final_learning_rate: None keeps ``learning_rate`` constant; a value decays the rate to it
            along a half cosine over the ``steps`` of the run (:func:`learning_rate_at`), e.g. to
            anneal a model at the end of its training.
        num_samples: K, bodies sampled per example for the 2D samples loss.
        samples_loss_from: step at which the 2D loss on samples starts (the paper's stage 2);
            -1 never (the ablation "without samples loss").
        samples_loss_weight: weight of the 2D samples loss once it is on (the default is
            :class:`hkpd.training.schedule.LossWeights`'s, equal to the 2D mode loss's). Larger
            values pull samples harder towards *visible* keypoints, i.e. sharpen the
            distribution where the image shows the body, and leave hidden joints to the NLL.
        mode_loss_weight: weight of the 2D keypoint loss of the most likely body (the mode pose
            with the mean shape), on from the first step. Larger values make the mode follow
            the keypoint heatmaps more closely rather than the pose prior the network learnt.
        tpose_loss_weight: weight of the per-vertex T-pose shape loss (m², all stages; 0 off):
            the shape mean's rest vertices against the true shape's, as in the paper's code.
        joints3d_loss_from: step at which the 3D joint loss starts (stage 3); -1 never.
        device: ``auto`` (CUDA when present), ``cpu`` or ``cuda``.
        amp: mixed precision on CUDA (ignored on CPU).
        seed: seeds the data stream and the network initialisation (under torchrun, rank r
            draws the data stream of seed + r; every rank starts from the same weights).
        log_every: steps between CSV log rows.
        val_every: steps between validations (0: only at the end).
        val_size: validation examples (a fixed synthetic set from the pose bank's val split).
        checkpoint_every: steps between checkpoints (the last one is always written).
        tensorboard: also write TensorBoard logs (needs the tensorboard package).
        init_weights: start from these network weights (e.g. the shipped fp16 model) instead of
            a fresh initialisation; the architecture must match. Unlike ``--resume`` this starts a
            new run (step 0, new optimiser).
        concentration_gain: give the network a per-joint concentration gain
            (:attr:`hkpd.network.NetworkConfig.concentration_gain`); with ``init_weights`` from a
            network without one, the gain starts at zero.
        limb_occlusion_probability: fraction of training images in which one limb segment is
            covered by a box (:func:`hkpd.synthesis.augmentations.limb_occlusion_boxes`), as the
            explorer's occluders do; 0 keeps the paper's augmentations only.
        data_workers: CPU only: make batches in this many single-threaded worker processes
            (:class:`hkpd.synthesis.parallel.ParallelBatches`); 0 makes them in a background
            thread of the training process.
        roll_probability: share of training images whose view is rolled about the optical
            axis by a uniform angle (leaning, lying, upside-down people;
            :class:`hkpd.synthesis.orientation.OrientationMix`); 0 keeps people upright.
        max_roll_deg: largest roll of the rolled images, degrees (180: any in-plane
            orientation; 45 leaves what the predictor's upright reading does not undo).
        steep_view_probability: share of training images seen steeply from above or below.
        archetype_share: share of training poses drawn from the pose families (sitting,
            kneeling, lunging, squatting, arms overhead, ...; :mod:`hkpd.poses.archetypes`).
        limb_mix_share: share of training poses that put one bank pose's legs under another's
            upper body (:class:`hkpd.poses.mixed_source.MixedPoseSource`).
        keypoint_noise_sigma: detector-like Gaussian noise on the input keypoints, as a
            fraction of the crop side (:func:`hkpd.synthesis.augmentations.jitter_joints`);
            0 keeps the paper's uniform ±8 px.
        keypoint_outlier_probability: with ``keypoint_noise_sigma``, the share of input
            keypoints replaced by outliers (up to 20 % of the crop away).
        shape_from_nll_only: only the shape NLL trains the shape head: the 2D and 3D joint
            losses pose their bodies with the predicted shape detached
            (:func:`hkpd.training.losses.compute_losses`), and the hierarchical head's joint
            streams read the shape outputs detached
            (:attr:`hkpd.network.HierarchicalHead.detach_shape_input`), so no pose loss reaches
            the shape head through them either. Without it, on hard views (rolled, noisy
            keypoints) the samples loss bends the shape to absorb pose errors.
        max_minutes: stop after this many minutes of training steps (setup and the final
            validation come on top), with a checkpoint that ``--resume`` continues, e.g. on a
            machine lent for a fixed time; None runs all ``steps``. The learning-rate schedule
            still follows ``steps``.
        image_proxy: what the network sees of the image: ``edges`` (hkpd's and the paper's
            choice), or ``silhouette`` / ``rgb`` (the proxy ablation;
            :data:`hkpd.proxy.IMAGE_PROXIES`). A silhouette model needs a person mask for every
            photo it reads.
        world_size: processes training together, from torchrun's ``WORLD_SIZE`` (not a flag:
            each launch fills it in; 1 without torchrun). A run resumes with the world size it
            was started with.
    """

    out: Path = Path("runs/hkpd")
    poses: Path | None = None
    backgrounds: Path | None = None
    steps: int = 20_000
    batch_size: int = 32
    image_size: int = 256
    pose_head: str = "hierarchical"
    backbone_base_width: int = 64
    learning_rate: float = 1e-4
    final_learning_rate: float | None = None
    num_samples: int = 8
    samples_loss_from: int = 2_000
    joints3d_loss_from: int = 10_000
    samples_loss_weight: float = 1000.0
    mode_loss_weight: float = 1000.0
    tpose_loss_weight: float = 0.0
    device: str = "auto"
    amp: bool = True
    seed: int = 0
    log_every: int = 10
    val_every: int = 1_000
    val_size: int = 200
    checkpoint_every: int = 1_000
    tensorboard: bool = False
    data_workers: int = 0
    init_weights: Path | None = None
    concentration_gain: bool = False
    limb_occlusion_probability: float = 0.0
    max_minutes: float | None = None
    roll_probability: float = 0.0
    max_roll_deg: float = 180.0
    steep_view_probability: float = 0.0
    archetype_share: float = 0.0
    limb_mix_share: float = 0.0
    keypoint_noise_sigma: float = 0.0
    keypoint_outlier_probability: float = 0.0
    shape_from_nll_only: bool = False
    image_proxy: str = DEFAULT_IMAGE_PROXY
    world_size: int = 1

    def validate(self) -> TrainConfig:
        """Check every field's range; returns ``self``.

        Raises:
            ValueError: one line naming the flag, its value and what it must be.
        """
        at_least = {"steps": 1, "batch_size": 1, "log_every": 1, "checkpoint_every": 1,
                    "val_every": 0, "val_size": 1, "data_workers": 0, "num_samples": 1,
                    "image_size": 32, "backbone_base_width": 1, "world_size": 1}  # fmt: skip
        for name, low in at_least.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{_flag(name)} must be an integer >= {low}, got {value!r}")
        for name in ("learning_rate", "final_learning_rate", "max_minutes"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"{_flag(name)} must be a finite number > 0, got {value}")
        for name in ("samples_loss_weight", "mode_loss_weight", "tpose_loss_weight"):
            weight = getattr(self, name)
            if not (math.isfinite(weight) and weight >= 0):
                raise ValueError(f"{_flag(name)} must be a finite number >= 0, got {weight}")
        probabilities = ("limb_occlusion_probability", "roll_probability",
                         "steep_view_probability", "archetype_share", "limb_mix_share",
                         "keypoint_outlier_probability")  # fmt: skip
        for name in probabilities:
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{_flag(name)} is a probability in [0, 1], got {value}")
        if self.archetype_share + self.limb_mix_share > 1.0:
            raise ValueError("--archetype-share and --limb-mix-share add up to more than 1")
        if not 0.0 <= self.max_roll_deg <= 180.0:
            raise ValueError(f"--max-roll-deg must lie in [0, 180], got {self.max_roll_deg}")
        if not 0.0 <= self.keypoint_noise_sigma < 0.5:
            raise ValueError(
                f"--keypoint-noise-sigma is a fraction of the crop in [0, 0.5), got "
                f"{self.keypoint_noise_sigma}"
            )
        for name in ("samples_loss_from", "joints3d_loss_from"):
            if getattr(self, name) < -1:
                raise ValueError(f"{_flag(name)} must be a step >= 0, or -1 for never")
        if self.pose_head not in ("hierarchical", "independent"):
            raise ValueError(
                f"--pose-head must be 'hierarchical' or 'independent', got {self.pose_head!r}"
            )
        if self.image_proxy not in IMAGE_PROXIES:
            raise ValueError(
                f"--image-proxy must be one of {', '.join(IMAGE_PROXIES)}, got {self.image_proxy!r}"
            )
        if not re.fullmatch(r"auto|cpu|cuda(:\d+)?|mps", self.device):
            raise ValueError(
                f"--device must be auto, cpu, cuda, cuda:N or mps, got {self.device!r}"
            )
        return self

    def network_config(self) -> NetworkConfig:
        """The architecture this run trains."""
        return NetworkConfig(
            backbone_base_width=self.backbone_base_width,
            pose_head=self.pose_head,
            image_size=self.image_size,
            concentration_gain=self.concentration_gain,
            input_channels=proxy_channels(self.image_proxy),
            image_proxy=self.image_proxy,
        )

    def data_config(self) -> SyntheticDataConfig:
        """The synthetic data this run trains on (augmentations, orientations)."""
        augmentation = AugmentationConfig(
            limb_occlusion_probability=self.limb_occlusion_probability,
            keypoint_noise_sigma=self.keypoint_noise_sigma,
            keypoint_outlier_probability=self.keypoint_outlier_probability,
        )
        orientation = OrientationMix(
            roll_probability=self.roll_probability,
            max_roll_deg=self.max_roll_deg,
            steep_view_probability=self.steep_view_probability,
        )
        return SyntheticDataConfig(
            image_size=self.image_size,
            augmentation=augmentation,
            orientation=orientation,
            image_proxy=self.image_proxy,
        )

    def pose_mix(self) -> PoseMix:
        """The shares of pose families and limb mixes next to the bank's poses."""
        return PoseMix(archetype_share=self.archetype_share, limb_mix_share=self.limb_mix_share)

    def to_dict(self) -> dict:
        """Plain JSON-able values (paths as strings)."""
        return {
            key: (str(value) if isinstance(value, Path) else value)
            for key, value in dataclasses.asdict(self).items()
        }

    @classmethod
    def from_dict(cls, values: dict) -> TrainConfig:
        """Inverse of :meth:`to_dict`; unknown keys raise a ValueError naming them."""
        known = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ValueError(f"unknown training config keys: {', '.join(unknown)}")
        hints = typing.get_type_hints(cls)
        converted = {}
        for key, value in values.items():
            wants_path = Path in _members(hints[key])
            converted[key] = Path(value) if wants_path and value is not None else value
        return cls(**converted)

    def save(self, path: Path) -> None:
        path.write_text(json.dumps(self.to_dict(), indent=2) + "\n")

    @classmethod
    def load(cls, path: Path) -> TrainConfig:
        if not path.is_file():
            raise FileNotFoundError(f"training config {path} does not exist")
        return cls.from_dict(json.loads(path.read_text()))


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def learning_rate_at(step: int, config: TrainConfig) -> float:
    """The learning rate for optimiser step ``step`` (0-based) of a run with ``config``."""
    if config.final_learning_rate is None:
        return config.learning_rate
    progress = min(max(step, 0) / max(config.steps - 1, 1), 1.0)
    blend = 0.5 * (1.0 + math.cos(math.pi * progress))
    return config.final_learning_rate + (config.learning_rate - config.final_learning_rate) * blend


def _members(hint) -> tuple:
    if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union:
        return typing.get_args(hint)
    return (hint,)


_ATTRIBUTE_LINE = re.compile(r"^    (?P<name>[a-z_][a-z0-9_]*): (?P<text>.*)$")
"""One ``name: text`` entry of a Google-style Attributes section (continuations are deeper)."""


def field_descriptions() -> dict[str, str]:
    """``{field: description}`` from the "Attributes:" section of :class:`TrainConfig`'s docstring.

    Continuation lines are joined with single spaces and reST markup (``:func:`x```, double
    back-quotes) is reduced to plain text, so the result reads well in ``--help``.
    """
    doc = inspect.getdoc(TrainConfig) or ""
    _, _, attributes = doc.partition("Attributes:")
    descriptions: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in attributes.splitlines():
        entry = _ATTRIBUTE_LINE.match(line)
        if entry:
            current = descriptions.setdefault(entry["name"], [])
            current.append(entry["text"])
        elif current is not None and line.strip():
            current.append(line.strip())
    return {name: _plain_text(" ".join(parts)) for name, parts in descriptions.items()}


def _plain_text(text: str) -> str:
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text)  # :func:`name` -> name
    return text.replace("``", "").replace("%", "%%")  # argparse formats help with %


LAUNCH_FIELDS = ("world_size",)
"""Fields the launch fills in (torchrun's environment), not flags."""


def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    """Add one ``--flag`` per :class:`TrainConfig` field (default: not given).

    Each flag's help is the field's documented description followed by its default.
    """
    hints = typing.get_type_hints(TrainConfig)
    descriptions = field_descriptions()
    for field in dataclasses.fields(TrainConfig):
        if field.name in LAUNCH_FIELDS:
            continue
        flag = "--" + field.name.replace("_", "-")
        members = [m for m in _members(hints[field.name]) if m is not type(None)]
        kind = members[0]
        description = descriptions.get(field.name, "").rstrip(".")
        help_text = f"{description} (default: {field.default})".strip()
        if kind is bool:
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, help=help_text)
        else:
            parser.add_argument(flag, type=kind, help=help_text)


def config_from_arguments(arguments: argparse.Namespace) -> TrainConfig:
    """``--config`` file (if any), then every flag that was given on top."""
    config_file = getattr(arguments, "config", None)
    config = TrainConfig.load(config_file) if config_file else TrainConfig()
    given = {
        f.name: getattr(arguments, f.name)
        for f in dataclasses.fields(TrainConfig)
        if getattr(arguments, f.name, None) is not None
    }
    return dataclasses.replace(config, **given)
