"""Move a network's shape means back to the shape prior's centre, keeping every pose output.

A fine-tune whose 2D/3D joint losses were allowed to bend the shape (before
``--shape-from-nll-only``) can leave the shape head with a large constant offset (orientation
run 1: β₁ ≈ +7.5 and β₃ ≈ +7.2 on every image, where the prior is N(0, 1.25²)). Trained by the
shape NLL alone, the head then mostly widens its standard deviation instead of moving the mean.
:func:`recentre_shape_mean` removes the offset in one exact step: the mean output is linear in
its layer, ``μ = W e + b``, so ``b -= d`` (``d``: the mean of ``μ`` over a set of training
crops) shifts every predicted mean by ``-d``; the hierarchical head also feeds ``μ`` to its
joint layers, whose first layer absorbs the shift (``bias += W_μ d``), so every pose output is
unchanged.

Usage: ``python -m hkpd.training.recentre_shape IN.pt OUT.pt [--poses poses.npz]``, then
``hkpd-train --init-weights OUT.pt ...``.
"""

from __future__ import annotations

import torch

from hkpd.network.hierarchical_head import HierarchicalHead
from hkpd.training.weight_edit_command import run_weight_edit


@torch.no_grad()
def recentre_shape_mean(network: torch.nn.Module, proxies: torch.Tensor) -> torch.Tensor:
    """Shift ``network``'s predicted shape means so that they average 0 over ``proxies``.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` (changed in place).
        proxies: ``(B, 18, S, S)`` training crops' proxies.

    Returns:
        ``(K,)`` the offset ``d`` that was removed from every predicted mean.
    """
    head = network.head
    num_betas = int(network.config.num_betas)
    offset = network(proxies).shape_mean.mean(0).to(head.globals_out.bias.dtype)
    head.globals_out.bias[:num_betas] -= offset
    if isinstance(head, HierarchicalHead):  # its joint layers read the mean: keep their input
        start = head.trunk[0].out_features  # the shared input is [embedding, mean, std, ...]
        columns = head.first_layer.weight[:, start : start + num_betas]
        head.first_layer.bias += columns @ offset
    return offset


def _recentre(network: torch.nn.Module, proxies: torch.Tensor) -> str:
    offset = recentre_shape_mean(network, proxies)
    return f"removed the shape-mean offset {[round(v, 3) for v in offset.tolist()]}"


def main(argv: list[str] | None = None) -> int:
    return run_weight_edit(
        argv,
        "recentre_shape",
        __doc__.splitlines()[0],
        "weights to recentre",
        "crops to average over",
        _recentre,
    )


if __name__ == "__main__":
    raise SystemExit(main())
