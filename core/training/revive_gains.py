"""Bring back joints whose concentration gain is stuck beyond its bound, keeping every output.

With ``--concentration-gain`` each joint scales its matrix-Fisher parameter by ``exp(g)``, ``g``
clamped to ``±MAX_LOG_GAIN``. Before :func:`hkpd.network.output_decoding.bounded_log_gain`, the
clamp had no gradient beyond the bound, so a joint whose ``g`` one large step threw far past it
(the orientation fine-tunes: both elbows near -300, both hands near -300, the right collar near
-140 on every crop) kept ``exp(-6)`` of its raw concentration for good. Its mode was then barely
trained (the right collar's drifted 23° off, the right shoulder's 49°) and its samples scattered.

:func:`revive_stuck_gains` finds the joints whose ``g`` lies beyond the bound on *every* probe
crop and replaces their gain layer's row by the constant bound (weights 0, bias ``±bound``):
the network's output is exactly what it was, but the gain is now at the edge of its range, where
training moves it again.

Usage: ``python -m hkpd.training.revive_gains IN.pt OUT.pt [--poses poses.npz]``, then
``hkpd-train --init-weights OUT.pt ...``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.network.hierarchical_head import HierarchicalHead
from hkpd.network.output_decoding import MAX_LOG_GAIN
from hkpd.training.weight_edit_command import run_weight_edit


@dataclass(frozen=True)
class GainRange:
    """One joint's log-gain over the probe crops.

    Attributes:
        joint: body joint name.
        low, median, high: smallest, median and largest ``g``.
        revived: its gain row was replaced by the constant bound.
    """

    joint: str
    low: float
    median: float
    high: float
    revived: bool


def _gain_layers(head: HierarchicalHead) -> list[tuple[tuple[int, ...], torch.nn.Module]]:
    """Each depth level's joints and its log-gain layer (``GroupedLinear``, one row per joint)."""
    pairs = zip(head.levels, head.level_streams, strict=True)
    layers = [(level, streams.log_gain) for level, streams in pairs]
    if any(layer is None for _, layer in layers):
        raise ValueError("this network has no concentration gain (--concentration-gain)")
    return layers


@torch.no_grad()
def log_gains(network: torch.nn.Module, proxies: torch.Tensor) -> torch.Tensor:
    """``(B, 23)`` raw (unclamped) log-gains of every joint for ``proxies`` ``(B, C, S, S)``."""
    head = network.head
    if not isinstance(head, HierarchicalHead):
        raise ValueError("only the hierarchical head has per-joint gain layers")
    layers = _gain_layers(head)
    captured: dict[int, torch.Tensor] = {}
    hooks = [
        layer.register_forward_hook(
            lambda _module, _inputs, output, depth=depth: captured.__setitem__(depth, output)
        )
        for depth, (_, layer) in enumerate(layers)
    ]
    try:
        network(proxies)
    finally:
        for hook in hooks:
            hook.remove()
    gains = torch.empty(proxies.shape[0], head.num_joints)
    for depth, (level, _) in enumerate(layers):
        gains[:, list(level)] = captured[depth][..., 0].float().cpu()
    return gains


@torch.no_grad()
def revive_stuck_gains(network: torch.nn.Module, proxies: torch.Tensor) -> list[GainRange]:
    """Reset the gain rows of joints stuck beyond ``±MAX_LOG_GAIN`` on all ``proxies``.

    Args:
        network: a hierarchical :class:`hkpd.network.DistributionNetwork` with a concentration
            gain (changed in place).
        proxies: ``(B, C, S, S)`` crops to probe with.

    Returns:
        Every joint's range before the change, and whether it was revived.
    """
    gains = log_gains(network, proxies)
    ranges = []
    for level, layer in _gain_layers(network.head):
        for row, joint in enumerate(level):
            low, high = float(gains[:, joint].min()), float(gains[:, joint].max())
            stuck = high < -MAX_LOG_GAIN or low > MAX_LOG_GAIN
            if stuck:
                layer.weight[row].zero_()
                layer.bias[row] = -MAX_LOG_GAIN if high < -MAX_LOG_GAIN else MAX_LOG_GAIN
            median = float(gains[:, joint].median())
            ranges.append(GainRange(BODY_JOINT_NAMES[joint], low, median, high, stuck))
    return ranges


def _revive(network: torch.nn.Module, proxies: torch.Tensor) -> str | None:
    """Revive, print every joint's range; say what changed (None: nothing was stuck)."""
    with torch.no_grad():
        before = network(proxies).F
        ranges = revive_stuck_gains(network, proxies)
        change = float((network(proxies).F - before).abs().max() / before.abs().max())
    print("| joint | log-gain min | median | max | revived |\n|---|---|---|---|---|")
    for entry in ranges:
        print(
            f"| {entry.joint} | {entry.low:.2f} | {entry.median:.2f} | {entry.high:.2f} "
            f"| {'yes' if entry.revived else ''} |"
        )
    revived = [entry.joint for entry in ranges if entry.revived]
    if not revived:
        print("no joint's gain is stuck beyond the bound; nothing written")
        return None
    return f"revived {', '.join(revived)}; largest change of F on the probe crops: {change:.1e}"


def main(argv: list[str] | None = None) -> int:
    return run_weight_edit(
        argv,
        "revive_gains",
        __doc__.splitlines()[0],
        "weights to repair",
        "crops to probe with",
        _revive,
    )


if __name__ == "__main__":
    raise SystemExit(main())
