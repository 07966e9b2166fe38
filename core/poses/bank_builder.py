"""Build a :class:`~hkpd.poses.bank.PoseBank` from folders of BVH files.

Steps per file: parse, retarget onto SMPL (the cgspeed T-pose frame is dropped), drop root
translation (only rotations are kept), drop near-duplicate frames, add left/right mirrored copies;
then assign each clip's poses to the split of its CMU subject.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import roma
import torch
from tqdm import tqdm

from hkpd.mirror_symmetry import mirror_pose
from hkpd.poses.bank import PoseBank
from hkpd.poses.bvh import BvhParseError, load_bvh
from hkpd.poses.frame_selection import select_distinct_frames
from hkpd.poses.retargeting import retarget
from hkpd.poses.subject_split import SPLIT_NAMES, assign_splits, subject_of


@dataclass
class BuildSummary:
    """What :func:`build_pose_bank` did.

    Attributes:
        files: BVH files that were read successfully.
        skipped: ``(path, reason)`` of files that could not be used.
        frames: per split, source frames (after dropping T-pose frames).
        kept: per split, frames kept after near-duplicate removal (before mirroring).
        poses: per split, poses stored (kept frames, doubled when mirroring).
        clips: per split, number of clips.
        subjects: per split, sorted subject numbers.
        flavours: number of files of each skeleton flavour.
    """

    files: list[Path] = field(default_factory=list)
    skipped: list[tuple[Path, str]] = field(default_factory=list)
    frames: dict[str, int] = field(default_factory=lambda: dict.fromkeys(SPLIT_NAMES, 0))
    kept: dict[str, int] = field(default_factory=lambda: dict.fromkeys(SPLIT_NAMES, 0))
    poses: dict[str, int] = field(default_factory=lambda: dict.fromkeys(SPLIT_NAMES, 0))
    clips: dict[str, int] = field(default_factory=lambda: dict.fromkeys(SPLIT_NAMES, 0))
    subjects: dict[str, list[int]] = field(default_factory=dict)
    flavours: dict[str, int] = field(default_factory=dict)

    def table(self) -> str:
        """A plain-text summary table."""
        lines = [
            f"{'split':<6} {'subjects':>8} {'clips':>6} {'frames':>8} {'kept':>7} {'poses':>7}",
        ]
        for split in SPLIT_NAMES:
            lines.append(
                f"{split:<6} {len(self.subjects.get(split, [])):>8} {self.clips[split]:>6} "
                f"{self.frames[split]:>8} {self.kept[split]:>7} {self.poses[split]:>7}"
            )
        lines.append(
            f"{'total':<6} {sum(len(s) for s in self.subjects.values()):>8} "
            f"{sum(self.clips.values()):>6} {sum(self.frames.values()):>8} "
            f"{sum(self.kept.values()):>7} {sum(self.poses.values()):>7}"
        )
        flavours = ", ".join(f"{n}: {c}" for n, c in sorted(self.flavours.items()))
        lines.append(f"files read: {len(self.files)} ({flavours}); skipped: {len(self.skipped)}")
        for split in SPLIT_NAMES:
            lines.append(f"{split} subjects: {self.subjects.get(split, [])}")
        return "\n".join(lines)


def find_bvh_files(directories: Sequence[str | Path]) -> list[Path]:
    """All ``*.bvh`` files under the given folders (recursively), sorted, without duplicates.

    Raises:
        FileNotFoundError: a folder does not exist.
        ValueError: no folders given, or a folder holds no BVH file.
    """
    if not directories:
        raise ValueError("give at least one folder of BVH files")
    files: list[Path] = []
    for directory in map(Path, directories):
        if not directory.is_dir():
            raise FileNotFoundError(f"BVH folder {directory} does not exist or is not a folder")
        found = sorted(p for p in directory.rglob("*") if p.suffix.lower() == ".bvh")
        if not found:
            raise ValueError(f"BVH folder {directory} contains no .bvh files")
        files.extend(found)
    return list(dict.fromkeys(p.resolve() for p in files))


def build_pose_bank(
    directories: Sequence[str | Path],
    min_change_deg: float = 5.0,
    mirror: bool = True,
    val_fraction: float = 0.1,
    test_fraction: float = 0.1,
    progress: bool = True,
) -> tuple[PoseBank, BuildSummary]:
    """Retarget every BVH file under ``directories`` into one pose bank.

    Args:
        directories: folders searched recursively for ``*.bvh``.
        min_change_deg: a frame is kept only when some joint turned by at least this many
            degrees since the last kept frame of the clip.
        mirror: also store the left/right mirror image of every kept pose.
        val_fraction, test_fraction: share of subjects held out (see
            :func:`hkpd.poses.subject_split.assign_splits`).
        progress: show a tqdm progress bar over files.

    Returns:
        The bank (all splits) and a summary.

    Raises:
        FileNotFoundError / ValueError: bad folders (see :func:`find_bvh_files`), or no file
            could be used. Files that fail to parse or retarget are skipped with a warning.
    """
    files = find_bvh_files(directories)
    summary = BuildSummary()
    clips = _retargeted_clips(files, min_change_deg, summary, progress)
    if summary.skipped:
        listing = "\n".join(f"  {p}: {reason}" for p, reason in summary.skipped)
        warnings.warn(f"skipped {len(summary.skipped)} BVH file(s):\n{listing}", stacklevel=2)
    if not clips:
        raise ValueError(f"none of the {len(files)} BVH files could be used (see warnings)")

    splits = assign_splits([clip.subject for clip in clips], val_fraction, test_fraction)
    names = tuple(dict.fromkeys(clip.name for clip in clips))
    columns = _bank_columns(clips, names, splits, mirror, summary)
    for split in SPLIT_NAMES:
        summary.subjects[split] = sorted(s for s, name in splits.items() if name == split)
    bank = PoseBank(
        **{k: np.concatenate(v) for k, v in columns.items()},
        clip_names=names,
    )
    return bank, summary


@dataclass(frozen=True)
class _Clip:
    """One retargeted BVH file's kept frames.

    Attributes:
        name: the file stem; subject: its CMU subject.
        body_pose: ``(N, 23, 3, 3)``; global_orient: ``(N, 3, 3)``.
        frames: ``(N,)`` long, each kept frame's index in the file.
        num_frames: frames of the clip after dropping the T-pose frame.
    """

    name: str
    subject: int
    body_pose: torch.Tensor
    global_orient: torch.Tensor
    frames: torch.Tensor
    num_frames: int


def _retargeted_clips(
    files: Sequence[Path], min_change_deg: float, summary: BuildSummary, progress: bool
) -> list[_Clip]:
    """Parse, retarget and thin every file; files that fail are listed in ``summary``."""
    clips: list[_Clip] = []
    for path in tqdm(files, desc="retargeting BVH", unit="file", disable=not progress):
        try:
            subject = subject_of(path.stem)
            motion = load_bvh(path)
            clip = retarget(motion)
        except (BvhParseError, ValueError, KeyError) as error:
            summary.skipped.append((path, str(error)))
            continue
        kept = select_distinct_frames(clip.body_pose, min_change_deg)
        first_frame = 1 if motion.num_frames > clip.num_frames else 0
        clips.append(
            _Clip(
                path.stem,
                subject,
                clip.body_pose[kept],
                clip.global_orient[kept],
                kept + first_frame,
                clip.num_frames,
            )
        )
        summary.files.append(path)
        summary.flavours[clip.flavour] = summary.flavours.get(clip.flavour, 0) + 1
    return clips


def _bank_columns(
    clips: Sequence[_Clip],
    names: tuple[str, ...],
    splits: dict[int, str],
    mirror: bool,
    summary: BuildSummary,
) -> dict[str, list[np.ndarray]]:
    """The bank's columns, a list of arrays per :class:`PoseBank` field (each clip, then its
    mirror image when ``mirror``); counts frames, poses and clips per split in ``summary``."""
    keys = ("body_pose", "global_orient", "subject", "clip", "frame", "mirrored", "split")
    columns: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    for clip in clips:
        split = splits[clip.subject]
        copies = [(clip.body_pose, clip.global_orient, False)]
        if mirror:
            copies.append((*mirror_pose(clip.body_pose, clip.global_orient), True))
        for pose, orient, is_mirror in copies:
            count = len(pose)
            columns["body_pose"].append(roma.rotmat_to_rotvec(pose).float().numpy())
            columns["global_orient"].append(roma.rotmat_to_rotvec(orient).float().numpy())
            columns["subject"].append(np.full(count, clip.subject, np.int32))
            columns["clip"].append(np.full(count, names.index(clip.name), np.int32))
            columns["frame"].append(clip.frames.numpy().astype(np.int32))
            columns["mirrored"].append(np.full(count, is_mirror))
            columns["split"].append(np.full(count, SPLIT_NAMES.index(split), np.int8))
            summary.poses[split] += count
        summary.frames[split] += clip.num_frames
        summary.kept[split] += len(clip.body_pose)
        summary.clips[split] += 1
    return columns
