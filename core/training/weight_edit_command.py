"""The command line shared by the tools that edit trained weights (``recentre_shape`` and
``revive_gains`` before a fine-tune, ``calibrate_concentration`` after one): ``IN.pt OUT.pt``,
crops to probe with, and ``OUT.pt`` is never overwritten. :func:`run_weight_edit` is the whole
command of an edit that only needs the probe crops."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import torch

from hkpd.network.checkpoint import load_network, save_checkpoint, stored_evidence_config
from hkpd.poses import pose_source
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator

WeightEdit = Callable[[torch.nn.Module, torch.Tensor], str | None]
"""Changes a network in place, given the ``(B, C, S, S)`` probe crops' proxies, and returns the
line to print before ``wrote OUT`` (None: nothing to write). A ValueError is reported as an
error of the command."""


def weight_edit_arguments(
    argv: list[str] | None,
    description: str,
    checkpoint_help: str,
    examples_help: str,
    default_examples: int = 200,
    poses_help: str = "pose bank (train split); else procedural",
    figure: bool = False,
) -> argparse.Namespace:
    """Parse ``checkpoint out [--poses] [--examples] [--seed]`` (and ``[--figure]`` when asked
    for); exits (code 2) on a bad
    ``--examples`` or an ``out`` that exists, before anything is loaded."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("checkpoint", type=Path, help=checkpoint_help)
    parser.add_argument("out", type=Path, help="where to write them (for --init-weights)")
    parser.add_argument("--poses", type=Path, help=poses_help)
    parser.add_argument("--examples", type=int, default=default_examples, help=examples_help)
    parser.add_argument("--seed", type=int, default=7)
    if figure:
        parser.add_argument("--figure", type=Path, help="also draw the result into this PNG")
    arguments = parser.parse_args(argv)
    if arguments.examples < 1:
        parser.error("--examples must be >= 1")
    if arguments.out.exists():
        parser.error(f"{arguments.out} exists; choose another name (nothing was written)")
    return arguments


def training_proxies(
    network: torch.nn.Module, poses: Path | None, count: int, seed: int
) -> torch.Tensor:
    """``(count, C + 17, S, S)`` proxies of upright training-split crops at the network's size
    (and of its image proxy)."""
    config = SyntheticDataConfig(
        image_size=int(network.config.image_size), image_proxy=network.config.image_proxy
    )
    generator = SyntheticDataGenerator(pose_source(poses, "train"), config)
    return generator.generate(count, seed).batch.proxy


def load_with_proxies(
    arguments: argparse.Namespace,
) -> tuple[torch.nn.Module, dict, torch.Tensor]:
    """The checkpoint's network (eval mode), its payload and the probe crops' proxies.

    Raises:
        FileNotFoundError, ValueError: as :func:`hkpd.network.checkpoint.load_network`.
    """
    network, payload = load_network(arguments.checkpoint)
    network.eval()
    proxies = training_proxies(network, arguments.poses, arguments.examples, arguments.seed)
    return network, payload, proxies


def save_edited(out: Path, network: torch.nn.Module, payload: dict) -> None:
    """Write ``network`` with the loaded checkpoint's step, configs, sample count and stored
    evidence settings (after editing concentrations, re-tune them: ``hkpd-tune-evidence
    --write-to``)."""
    save_checkpoint(
        out, network, payload["network_config"], payload["step"],
        payload["train_config"], payload["samples_seen"],
        evidence_config=stored_evidence_config(payload) or None,
    )  # fmt: skip


def run_weight_edit(
    argv: list[str] | None,
    program: str,
    description: str,
    checkpoint_help: str,
    examples_help: str,
    edit: WeightEdit,
) -> int:
    """Parse ``IN.pt OUT.pt [--poses] [--examples] [--seed]``, load the network and the probe
    crops, apply ``edit`` and write ``OUT.pt`` (unless ``edit`` returns None).

    Returns:
        The exit status: 0 done (or nothing to write), 2 a missing or unusable checkpoint, or
        an edit that does not apply to it (the reason is printed as ``program: error: ...``).
    """
    arguments = weight_edit_arguments(argv, description, checkpoint_help, examples_help)
    try:
        network, payload, proxies = load_with_proxies(arguments)
        done = edit(network, proxies)
    except (FileNotFoundError, ValueError) as error:
        print(f"{program}: error: {error}", file=sys.stderr)
        return 2
    if done is None:
        return 0
    save_edited(arguments.out, network, payload)
    print(done)
    print(f"wrote {arguments.out}")
    return 0
