"""``hkpd-poses``: build and inspect pose banks.

hkpd-poses build BVH_DIR [BVH_DIR ...] --out poses.npz [--min-change-deg 5] [--no-mirror]
hkpd-poses info poses.npz
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from hkpd.poses.bank import PoseBank
from hkpd.poses.bank_builder import build_pose_bank
from hkpd.poses.subject_split import SPLIT_NAMES


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hkpd-poses", description="Build SMPL pose banks from BVH motion capture."
    )
    commands = parser.add_subparsers(dest="command", required=True)
    build = commands.add_parser(
        "build", help="retarget BVH files onto SMPL and write a pose bank (.npz)"
    )
    build.add_argument("bvh_dirs", nargs="+", metavar="BVH_DIR", help="folders with .bvh files")
    build.add_argument("--out", required=True, help="output .npz file")
    build.add_argument(
        "--min-change-deg",
        type=float,
        default=5.0,
        help="keep a frame only if some joint turned this much since the last kept one (5)",
    )
    build.add_argument("--no-mirror", action="store_true", help="do not add mirrored copies")
    build.add_argument("--val-fraction", type=float, default=0.1, help="share of val subjects")
    build.add_argument("--test-fraction", type=float, default=0.1, help="share of test subjects")
    build.add_argument("--quiet", action="store_true", help="no progress bar")
    info = commands.add_parser("info", help="print what a pose bank holds")
    info.add_argument("bank", help="a .npz written by 'hkpd-poses build'")
    return parser


def _build(args: argparse.Namespace) -> int:
    bank, summary = build_pose_bank(
        args.bvh_dirs,
        min_change_deg=args.min_change_deg,
        mirror=not args.no_mirror,
        val_fraction=args.val_fraction,
        test_fraction=args.test_fraction,
        progress=not args.quiet,
    )
    path = bank.save(args.out)
    print(summary.table())
    print(f"wrote {len(bank)} poses to {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


def _info(args: argparse.Namespace) -> int:
    bank = PoseBank.load(args.bank, split="all")
    print(f"{args.bank}: {len(bank)} poses, {len(bank.clip_names)} clips")
    for index, split in enumerate(SPLIT_NAMES):
        part = bank.split == index
        subjects = sorted(int(s) for s in np.unique(bank.subject[part]))
        print(f"  {split:<5} {int(part.sum()):>7} poses, subjects {subjects}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``hkpd-poses``; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        return _build(args) if args.command == "build" else _info(args)
    except (FileNotFoundError, ValueError) as error:
        print(f"hkpd-poses: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
