"""Export a training checkpoint as small shipping weights (float16, no optimiser state).

Usage: ``python -m hkpd.training.export runs/hkpd/last.pt assets/models/hkpd_hierarchical.pt``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hkpd.network.checkpoint import load_network, save_checkpoint, stored_evidence_config


def export_weights(checkpoint: Path, out: Path) -> Path:
    """Write ``checkpoint``'s network as float16 weights at ``out`` (loads as float32), with the
    evidence settings stored with it."""
    network, payload = load_network(checkpoint)
    return save_checkpoint(
        out,
        network,
        payload["network_config"],
        payload["step"],
        payload["train_config"],
        payload["samples_seen"],
        half_precision=True,
        evidence_config=stored_evidence_config(payload) or None,
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("out", type=Path)
    arguments = parser.parse_args(argv)
    try:
        path = export_weights(arguments.checkpoint, arguments.out)
    except (FileNotFoundError, ValueError) as error:
        print(f"export: error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
