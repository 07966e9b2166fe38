"""Checkpoints: save, resume and load trained networks (the format, beside the network, so
that prediction and evaluation load weights without importing the training stack).

A checkpoint is one ``torch.save`` file holding plain data only (loadable with
``weights_only=True``):

| key | content |
|---|---|
| ``format`` | ``"hkpd-checkpoint"`` |
| ``version`` | format version (1) |
| ``network_config`` | dict, rebuilds the network with ``DistributionNetwork.from_config`` |
| ``model`` | the network's ``state_dict`` (float32, or float16 in exported weights but for
  the 23 calibration scales, :data:`FULL_PRECISION_KEYS`; loaded as float32 either way) |
| ``optimizer`` | the optimiser's ``state_dict`` (absent in exported weights) |
| ``step`` | optimiser steps done |
| ``train_config`` | the :class:`~hkpd.training.config.TrainConfig` as a dict |
| ``samples_seen`` | training examples seen |
| ``rng`` | random states (torch CPU and CUDA, numpy, python) at the save, so a resumed run
  continues bit-exactly (absent in exported weights) |
| ``rng_per_rank`` | under ``torchrun``: every rank's random states, by rank (absent alone) |
| ``checksum`` | SHA-256 of the model tensors' bytes (format 2): a damaged file is refused |
| ``evidence_config`` | the evidence settings tuned for these weights (format 3, optional): a
  plain dict that :meth:`hkpd.conditioning.EvidenceConfig.from_dict` reads; absent, the
  predictor uses ``EvidenceConfig()``'s defaults |

Format 1 files (no checksum) and format 2 files (no evidence settings) still load.

:func:`read_checkpoint` trusts nothing in the file: the config is checked against the limits of
:mod:`hkpd.network.config` and against the stored tensors' names and shapes before any network
is built, and the weights must be finite and at most :data:`MAX_WEIGHT_MAGNITUDE`
(``docs/network.md``, "Refused inputs: checkpoints").
"""

from __future__ import annotations

import hashlib
import math
import random
from pathlib import Path
from typing import Any

import numpy as np
import torch

from hkpd.network.config import NetworkConfig

FORMAT = "hkpd-checkpoint"
VERSION = 3

EVIDENCE_CONFIG_KEY = "evidence_config"
"""The evidence settings tuned for the weights (``hkpd-tune-evidence --write-to``); checkpoints
older than it lack it, and their predictor takes the conditioning defaults."""

EvidenceSettings = dict[str, float | int | str]
"""Evidence settings as stored: :class:`~hkpd.conditioning.EvidenceConfig` field -> value."""

CALIBRATION_KEY = "log_concentration_scale"
"""The network's per-joint concentration calibration buffer; checkpoints older than it lack it
(and load with zeros, i.e. uncalibrated)."""


FULL_PRECISION_KEYS = frozenset({CALIBRATION_KEY})
"""Tensors kept in float32 in half-precision (exported) weights: the concentration calibration
(23 numbers) sits on a grid of ``log(2) / 4`` steps (up to ``5 log 2``) that float16 misses by up
to 9e-4, which would move the calibrated concentrations by up to 0.09 %. Every other weight of
the shipped network is stored exactly in float16 (it was trained and exported that way)."""


MAX_WEIGHT_MAGNITUDE = 1e4
"""Largest magnitude a stored floating-point tensor may hold. The shipped network's largest is
33.2 (a batch-norm running variance; its largest trained weight is 20.5), the ablation models'
at most 12.4: a file above this bound (300 times the shipped one) is a diverged run, and is
refused on load like one holding NaN or inf. Integer tensors (batch-norm step counters) are not
bounded."""


class CheckpointError(ValueError):
    """A file is not a readable hkpd checkpoint; the message says why and what to do."""


def save_checkpoint(
    path: Path,
    model: torch.nn.Module,
    network_config: dict,
    step: int,
    train_config: dict,
    samples_seen: int,
    optimizer: torch.optim.Optimizer | None = None,
    half_precision: bool = False,
    evidence_config: EvidenceSettings | None = None,
    rank_random_states: list[dict[str, Any]] | None = None,
) -> Path:
    """Write a checkpoint atomically (to a temporary name, then renamed).

    Args:
        half_precision: store float tensors as float16 (but :data:`FULL_PRECISION_KEYS`) and
            no optimiser state (for shipping small weights; not for resuming);
            :func:`load_network` loads them as float32.
        evidence_config: evidence settings tuned for these weights (``EvidenceConfig.to_dict()``),
            stored under :data:`EVIDENCE_CONFIG_KEY`; None stores none.
        rank_random_states: every rank's :func:`random_states` of a multi-process run.
    """
    state = model.state_dict()
    if half_precision:
        state = {
            key: value.half()
            if value.is_floating_point() and key not in FULL_PRECISION_KEYS
            else value
            for key, value in state.items()
        }
    payload: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "network_config": network_config,
        "model": {key: value.detach().cpu() for key, value in state.items()},
        "step": int(step),
        "train_config": train_config,
        "samples_seen": int(samples_seen),
    }
    if optimizer is not None and not half_precision:
        payload["optimizer"] = optimizer.state_dict()
        payload["rng"] = random_states()
        if rank_random_states is not None:
            payload["rng_per_rank"] = rank_random_states
    if evidence_config is not None:
        payload[EVIDENCE_CONFIG_KEY] = dict(evidence_config)
    payload["checksum"] = model_checksum(payload["model"])
    return _write_payload(payload, path)


def store_evidence_config(
    source: Path | str, target: Path | str, settings: EvidenceSettings
) -> Path:
    """Copy the checkpoint ``source`` to ``target`` (which may be ``source``) with ``settings``
    as its evidence settings, everything else as it was (weights, checksum, training state).

    Raises:
        FileNotFoundError, CheckpointError: as :func:`read_checkpoint`.
    """
    payload = read_checkpoint(source)
    payload["version"] = VERSION
    payload[EVIDENCE_CONFIG_KEY] = dict(settings)
    return _write_payload(payload, Path(target))


def stored_evidence_config(payload: dict) -> EvidenceSettings:
    """The evidence settings a checkpoint read by :func:`read_checkpoint` stores (empty when it
    stores none: older checkpoints, and those never tuned)."""
    return dict(payload.get(EVIDENCE_CONFIG_KEY, {}))


def _write_payload(payload: dict[str, Any], path: Path) -> Path:
    """``torch.save`` atomically (to a temporary name, then renamed)."""
    partial = path.with_name(path.name + ".partial")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        torch.save(payload, partial)
        partial.replace(path)
    except OSError as error:
        partial.unlink(missing_ok=True)  # never leave a half-written file filling the disk
        raise OSError(
            f"cannot write the checkpoint {path} ({error.strerror or error}); free some space "
            "or choose a writable --out"
        ) from error
    return path


def model_checksum(state: dict[str, torch.Tensor]) -> str:
    """SHA-256 over the names and raw bytes of a state dict's tensors (sorted by name)."""
    digest = hashlib.sha256()
    for key in sorted(state):
        tensor = state[key].detach().cpu().contiguous()
        digest.update(key.encode())
        digest.update(str(tensor.dtype).encode())
        digest.update(tensor.reshape(-1).view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


def random_states() -> dict[str, Any]:
    """Every global random state a training step draws from, as plain data."""
    numpy_state = np.random.get_state()  # noqa: NPY002 (saving the legacy global state)
    states: dict[str, Any] = {
        "torch": torch.get_rng_state(),
        "numpy": {
            "keys": torch.from_numpy(numpy_state[1].astype(np.int64)),
            "position": int(numpy_state[2]),
            "has_gauss": int(numpy_state[3]),
            "cached_gaussian": float(numpy_state[4]),
        },
        "python": random.getstate(),
    }
    if torch.cuda.is_available():
        states["cuda"] = torch.cuda.get_rng_state_all()
    return states


def restore_random_states(states: dict[str, Any]) -> None:
    """Inverse of :func:`random_states`."""
    torch.set_rng_state(states["torch"].cpu())
    numpy_state = states["numpy"]
    np.random.set_state((  # noqa: NPY002 (restoring the legacy global state)
        "MT19937", numpy_state["keys"].numpy().astype(np.uint32), numpy_state["position"],
        numpy_state["has_gauss"], numpy_state["cached_gaussian"],
    ))  # fmt: skip
    python = states["python"]
    random.setstate((python[0], tuple(python[1]), python[2]))
    if "cuda" in states and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(states["cuda"])


def read_checkpoint(path: Path | str, map_location: str | torch.device = "cpu") -> dict:
    """Load and validate a checkpoint file.

    Raises:
        FileNotFoundError: no such file.
        CheckpointError: not an hkpd checkpoint, written by a newer format version, damaged
            (checksum), a ``network_config`` out of the limits or not fitting the stored
            tensors, or non-finite or diverged weights; one line naming the file.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {path} does not exist")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as error:  # torch raises many types for corrupt files
        raise CheckpointError(f"{path} is not a readable checkpoint ({error})") from error
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not an hkpd checkpoint (no '{FORMAT}' marker)")
    if int(payload.get("version", 0)) > VERSION:
        raise CheckpointError(
            f"{path} has checkpoint format {payload['version']}; this hkpd reads up to "
            f"{VERSION}. Upgrade hkpd."
        )
    if not isinstance(payload.get("model"), dict) or "network_config" not in payload:
        raise CheckpointError(f"{path} is an hkpd checkpoint without weights or architecture")
    weights = payload["model"]
    settings = payload.get(EVIDENCE_CONFIG_KEY, {})
    if not isinstance(settings, dict) or not all(isinstance(key, str) for key in settings):
        raise CheckpointError(
            f"{path} has malformed evidence settings ('{EVIDENCE_CONFIG_KEY}' must map setting "
            f"names to values, got {settings!r}); store them again with hkpd-tune-evidence "
            "--write-to"
        )
    if not all(isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in weights.items()):
        raise CheckpointError(f"{path} is damaged: its weights are not all named tensors")
    config = stored_network_config(payload, path)
    _check_backbone_layout(config, weights, path)
    expected = payload.get("checksum")
    if expected is not None and model_checksum(payload["model"]) != expected:
        raise CheckpointError(
            f"{path} is damaged: its weights do not match the checksum stored with them; "
            "use another copy (or the previous checkpoint)"
        )
    _check_weight_values(weights, path)
    _check_tensor_shapes(config, weights, path)
    return payload


def stored_network_config(payload: dict, path: Path | str) -> NetworkConfig:
    """The :class:`NetworkConfig` a checkpoint's payload stores, checked against the limits
    (:data:`hkpd.network.config.INTEGER_LIMITS`, :data:`~hkpd.network.config.SEQUENCE_LIMITS`).

    Raises:
        CheckpointError: not a config, or a value of the wrong type or out of range.
    """
    stored = payload.get("network_config")
    if not isinstance(stored, dict) or not all(isinstance(key, str) for key in stored):
        raise CheckpointError(f"{path} is damaged: its network_config is not a dict of settings")
    try:
        return NetworkConfig.from_dict(stored)
    except (TypeError, ValueError) as error:
        raise CheckpointError(
            f"{path} has an unusable network_config: {_one_line(error)}; the file is damaged "
            "or was not written by hkpd-train, use another checkpoint"
        ) from None


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())


def _check_backbone_layout(config: NetworkConfig, state: dict, path: Path | str) -> None:
    """The backbone's stages and blocks per stage, read from the tensor names
    (``backbone.stages.<stage>.<block>.…``), must be ``config.backbone_blocks``: checked from
    the names alone, before anything is built."""
    wanted = {
        (stage, block) for stage, n in enumerate(config.backbone_blocks) for block in range(n)
    }
    held: set[tuple[int, int]] = set()
    for key in state:
        parts = key.split(".")[:4]
        if len(parts) == 4 and parts[:2] == ["backbone", "stages"]:
            digits = parts[2].isdigit() and parts[3].isdigit() and len(parts[2] + parts[3]) < 9
            held.add((int(parts[2]), int(parts[3])) if digits else (-1, -1))
    if held != wanted:
        stages = 1 + max((stage for stage, _ in held), default=-1)
        found: list[int] | str = [
            len({block for s, block in held if s == stage}) for stage in range(min(stages, 64))
        ]
        if (-1, -1) in held or stages > 64:
            found = "stages that no config can describe"
        raise CheckpointError(
            f"{path} does not fit its own architecture: its network_config says backbone_blocks "
            f"{list(config.backbone_blocks)}, but its weights hold {found}; the file is damaged, "
            "use another checkpoint"
        )


def _check_weight_values(state: dict[str, torch.Tensor], path: Path | str) -> None:
    """Every floating-point tensor finite and at most :data:`MAX_WEIGHT_MAGNITUDE` in size."""
    for key, tensor in state.items():
        if not tensor.is_floating_point() or tensor.numel() == 0:
            continue
        largest = _largest_magnitude(tensor)
        if not math.isfinite(largest):
            what = "NaN" if math.isnan(largest) else "inf"
            raise CheckpointError(
                f"{path} holds non-finite weights ({what} in {key}), as a diverged training "
                "run writes; use an earlier checkpoint"
            )
        if largest > MAX_WEIGHT_MAGNITUDE:
            raise CheckpointError(
                f"{path} holds weights larger than {MAX_WEIGHT_MAGNITUDE:g} in magnitude "
                f"({largest:.3g} in {key}), as a diverged training run writes; use an earlier "
                "checkpoint"
            )


_SAME_SIZE_INTEGERS = {
    torch.float16: torch.int16,
    torch.bfloat16: torch.int16,
    torch.float32: torch.int32,
    torch.float64: torch.int64,
}


def _largest_magnitude(tensor: torch.Tensor) -> float:
    """The largest ``|entry|`` of a float tensor: NaN if any entry is NaN, else inf if any is
    infinite. Read from the bits (sign cleared, the largest pattern is the largest magnitude,
    inf's above every finite one and NaN's above inf's): float16 arithmetic on the CPU took
    1.6 s for the shipped file, this takes a few ms."""
    integers = _SAME_SIZE_INTEGERS.get(tensor.dtype)
    if integers is None:
        return float(tensor.detach().double().abs().amax())
    worst = (tensor.detach().view(integers) & torch.iinfo(integers).max).amax()
    if worst > torch.tensor(math.inf, dtype=tensor.dtype).view(integers):
        return math.nan
    return float(worst.view(tensor.dtype))


def _check_tensor_shapes(config: NetworkConfig, state: dict, path: Path | str) -> None:
    """The stored tensors must be exactly the names and shapes of ``config``'s network (built on
    the ``meta`` device, which allocates no memory; the config is already within the limits),
    except for a missing :data:`CALIBRATION_KEY` (older checkpoints)."""
    from hkpd.network.model import DistributionNetwork

    with torch.device("meta"):
        expected = {k: tuple(v.shape) for k, v in DistributionNetwork(config).state_dict().items()}
    missing = sorted(set(expected) - set(state) - {CALIBRATION_KEY})
    unexpected = sorted(set(state) - set(expected))
    wrong = [k for k in expected if k in state and tuple(state[k].shape) != expected[k]]
    if missing or unexpected or wrong:
        if wrong:
            found = f"{wrong[0]} is {tuple(state[wrong[0]].shape)} in the file"
            problem = f"{found} but {expected[wrong[0]]} for that config"
        else:
            problem = f"missing {missing[:3]}, unexpected {unexpected[:3]}"
        raise CheckpointError(
            f"{path} does not fit its own architecture: its network_config does not match its "
            f"weights ({problem}); the file is damaged, use another checkpoint"
        )


def load_network(path: Path | str, device: str | torch.device = "cpu") -> tuple[Any, dict]:
    """Rebuild the trained network from a checkpoint, in float32 and eval mode (float16
    weights, as exported, are upcast exactly; float32 ones load as stored).

    Returns:
        ``(network, checkpoint dict)``.
    """
    from hkpd.network import DistributionNetwork

    payload = read_checkpoint(path)
    network = DistributionNetwork.from_config(payload["network_config"])
    load_weights(network, float32_state(payload["model"]), path)
    return network.to(device).eval(), payload


def float32_state(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """``state`` with every floating-point tensor as float32 (float16 and bfloat16 convert
    exactly); integer tensors (batch-norm counters) as they are."""
    return {
        key: value.float() if value.is_floating_point() else value for key, value in state.items()
    }


def load_weights(network: Any, state: dict, source: Path | str) -> None:
    """``network.load_state_dict(state)``, strictly, except that a state written before the
    concentration calibration existed (no :data:`CALIBRATION_KEY`) loads as uncalibrated.

    Raises:
        CheckpointError: any other missing or unexpected key.
    """
    missing, unexpected = network.load_state_dict(state, strict=False)
    if unexpected or set(missing) - {CALIBRATION_KEY}:
        raise CheckpointError(
            f"{source} does not fit its own architecture: missing {missing}, unexpected "
            f"{unexpected}"
        )
    if CALIBRATION_KEY in missing:
        with torch.no_grad():
            getattr(network, CALIBRATION_KEY).zero_()


STEM_WEIGHT_KEY = "backbone.stem.0.weight"
"""The first convolution's ``(width, input channels, 7, 7)`` weight in a network's state."""


def with_zero_mask_channel(stem_weight: torch.Tensor) -> torch.Tensor:
    """An ``"edges"`` network's first-layer weight ``(W, 1 + 17, k, k)`` widened for the
    ``"edges+mask"`` proxy: ``(W, 2 + 17, k, k)`` with zeros for the mask channel (inserted after
    the edge channel), so the widened network computes exactly what the original did."""
    zeros = torch.zeros_like(stem_weight[:, :1])
    return torch.cat([stem_weight[:, :1], zeros, stem_weight[:, 1:]], 1)


def load_initial_weights(network: Any, path: Path | str, device: str | torch.device) -> None:
    """Copy a trained network's weights into ``network`` (``hkpd-train --init-weights``).

    The architectures must match, except that ``network`` may add the concentration gain the
    trained one lacks (its gain layers then keep their zero initialisation), and may read the
    ``"edges+mask"`` proxy where the trained one read ``"edges"`` (the mask channel's first-layer
    weights start at zero): either way the network starts out predicting exactly what the
    trained one did. A per-joint concentration
    calibration of the trained weights (:mod:`hkpd.training.calibrate_concentration`) is not
    carried over: a fine-tune trains the raw distributions; calibrate its result again.

    Raises:
        ValueError: if the architectures differ otherwise.
    """
    from hkpd.network.config import NetworkConfig

    initial, payload = load_network(path, device)
    wanted = network.config.to_dict()
    found = NetworkConfig.from_dict(payload["network_config"]).to_dict()
    adds_gain = wanted["concentration_gain"] and not found["concentration_gain"]
    if adds_gain:
        found["concentration_gain"] = True
    adds_mask = found["image_proxy"] == "edges" and wanted["image_proxy"] == "edges+mask"
    if adds_mask:
        found["image_proxy"], found["input_channels"] = "edges+mask", wanted["input_channels"]
    if found != wanted:
        raise ValueError(
            f"--init-weights {path} has architecture {payload['network_config']}, but this run "
            f"builds {wanted}: match --image-size, --backbone-base-width and --pose-head"
        )
    weights = {key: value for key, value in initial.state_dict().items() if key != CALIBRATION_KEY}
    if adds_mask:
        weights[STEM_WEIGHT_KEY] = with_zero_mask_channel(weights[STEM_WEIGHT_KEY])
    missing, unexpected = network.load_state_dict(weights, strict=False)
    with torch.no_grad():
        getattr(network, CALIBRATION_KEY).zero_()
    not_gain = [key for key in missing if "log_gain" not in key and key != CALIBRATION_KEY]
    if unexpected or not_gain:
        raise ValueError(f"--init-weights {path}: missing {missing}, unexpected {unexpected}")
