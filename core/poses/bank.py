"""A pose bank: retargeted mocap poses stored in one ``.npz`` file, sampled at training time.

File format (``numpy.savez_compressed``, no pickled objects), N poses:

======================  ==============  =====================================================
key                     shape, dtype    meaning
======================  ==============  =====================================================
``format``              () str          ``"hkpd-pose-bank-v1"``
``body_pose``           (N, 23, 3) f32  axis-angle relative rotations of the 23 body joints
``global_orient``       (N, 3) f32      axis-angle body orientation in the mocap world
``subject``             (N,) i32        CMU subject number
``clip``                (N,) i32        index into ``clip_names``
``clip_names``          (C,) str        clip names (file stems)
``frame``               (N,) i32        frame index in the source file (0 = first frame)
``mirrored``            (N,) bool       pose is a left/right mirrored copy
``split``               (N,) i8         index into ``split_names``
``split_names``         (3,) str        ``("train", "val", "test")``
``joint_names``         (23,) str       the SMPL body joint names
======================  ==============  =====================================================
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import roma
import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.poses.subject_split import SPLIT_NAMES

BANK_FORMAT = "hkpd-pose-bank-v1"
_ARRAY_KEYS = ("body_pose", "global_orient", "subject", "clip", "frame", "mirrored", "split")


MAX_ROTATION_ANGLE = 4 * np.pi
"""Axis-angle magnitudes beyond this (radians) are rejected: rotations need at most π, and
anything this large is corrupt data, not a pose."""


@dataclass
class PoseBank:
    """Mocap poses in SMPL form; implements :class:`hkpd.poses.PoseSource`.

    Attributes (N poses):
        body_pose: ``(N, 23, 3)`` float32 axis-angle relative rotations.
        global_orient: ``(N, 3)`` float32 axis-angle orientation in the mocap world (SMPL axes).
        subject: ``(N,)`` int32 CMU subject numbers.
        clip: ``(N,)`` int32 indices into ``clip_names``.
        clip_names: clip names.
        frame: ``(N,)`` int32 source frame indices.
        mirrored: ``(N,)`` bool.
        split: ``(N,)`` int8 indices into :data:`hkpd.poses.subject_split.SPLIT_NAMES`.
        split_name: which split this bank holds (``"all"`` for a whole bank).
    """

    body_pose: np.ndarray
    global_orient: np.ndarray
    subject: np.ndarray
    clip: np.ndarray
    clip_names: tuple[str, ...]
    frame: np.ndarray
    mirrored: np.ndarray
    split: np.ndarray
    split_name: str = "all"

    def __post_init__(self) -> None:
        count = len(self.body_pose)
        if self.body_pose.shape[1:] != (23, 3) or self.global_orient.shape != (count, 3):
            raise ValueError(
                f"body_pose must be (N, 23, 3) and global_orient (N, 3), got "
                f"{self.body_pose.shape} and {self.global_orient.shape}"
            )
        for key in _ARRAY_KEYS[2:]:
            if getattr(self, key).shape != (count,):
                raise ValueError(
                    f"{key} must have shape ({count},), got {getattr(self, key).shape}"
                )
        for key in ("body_pose", "global_orient"):
            angles = np.linalg.norm(np.asarray(getattr(self, key), dtype=np.float64), axis=-1)
            bad = ~(np.isfinite(angles) & (angles <= MAX_ROTATION_ANGLE))
            if bad.any():
                poses = np.flatnonzero(bad.reshape(count, -1).any(1))
                raise ValueError(
                    f"{len(poses)} pose(s) have non-finite or absurd {key} rotations (axis-angle "
                    f"beyond {MAX_ROTATION_ANGLE:.1f} rad), e.g. pose {int(poses[0])}; rebuild "
                    "the bank with 'hkpd-poses build'"
                )

    def __len__(self) -> int:
        return len(self.body_pose)

    @property
    def subjects(self) -> tuple[int, ...]:
        """Sorted CMU subject numbers present in this bank."""
        return tuple(int(s) for s in np.unique(self.subject))

    def rotation_matrices(self, indices: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``body_pose (K, 23, 3, 3)`` and ``global_orient (K, 3, 3)`` float32 of given poses."""
        index = indices.cpu().numpy()
        body = roma.rotvec_to_rotmat(torch.from_numpy(self.body_pose[index]))
        orient = roma.rotvec_to_rotmat(torch.from_numpy(self.global_orient[index]))
        return body, orient

    def sample(self, count: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """Draw ``count`` poses uniformly with replacement (see :class:`hkpd.poses.PoseSource`).

        Returns:
            ``body_pose (count, 23, 3, 3)`` and ``global_orient (count, 3, 3)``, float32.
        """
        if len(self) == 0:
            raise ValueError(f"the {self.split_name!r} pose bank is empty; nothing to sample")
        if count < 0:
            raise ValueError(f"count must be >= 0, got {count}")
        indices = torch.randint(len(self), (count,), generator=generator)
        return self.rotation_matrices(indices)

    def select(self, mask: np.ndarray, split_name: str) -> PoseBank:
        """The poses where ``mask`` (``(N,)`` bool) is true, as a new bank."""
        return PoseBank(
            **{key: getattr(self, key)[mask] for key in _ARRAY_KEYS},
            clip_names=self.clip_names,
            split_name=split_name,
        )

    def save(self, path: str | Path) -> Path:
        """Write the bank to ``path`` (``.npz``; parent folders are created)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as handle:
            np.savez_compressed(
                handle,
                format=np.array(BANK_FORMAT),
                body_pose=self.body_pose.astype(np.float32),
                global_orient=self.global_orient.astype(np.float32),
                subject=self.subject.astype(np.int32),
                clip=self.clip.astype(np.int32),
                clip_names=np.array(self.clip_names, dtype=str),
                frame=self.frame.astype(np.int32),
                mirrored=self.mirrored.astype(bool),
                split=self.split.astype(np.int8),
                split_names=np.array(SPLIT_NAMES),
                joint_names=np.array(BODY_JOINT_NAMES),
            )
        return path

    @classmethod
    def load(cls, path: str | Path, split: str = "train") -> PoseBank:
        """Read a bank written by :meth:`save` (e.g. by ``hkpd-poses build``).

        Args:
            path: the ``.npz`` file.
            split: ``"train"``, ``"val"``, ``"test"`` or ``"all"``.

        Raises:
            FileNotFoundError: no such file.
            ValueError: not a pose bank, an unknown split, or an empty split.
        """
        path = Path(path)
        if split not in (*SPLIT_NAMES, "all"):
            raise ValueError(f"unknown split {split!r}; choose one of {(*SPLIT_NAMES, 'all')}")
        if not path.is_file():
            raise FileNotFoundError(
                f"pose bank {path} does not exist; build one with "
                "'hkpd-poses build BVH_DIR --out poses.npz' or use ProceduralPosePrior() (on the "
                "command line: leave --poses out)"
            )
        try:
            with np.load(path, allow_pickle=False) as data:
                contents = {key: data[key] for key in data.files}
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as error:
            raise ValueError(
                f"{path} is not a readable .npz pose bank ({type(error).__name__}: {error}); "
                "it may be truncated: rebuild it with 'hkpd-poses build'"
            ) from None
        if str(contents.get("format", "")) != BANK_FORMAT:
            raise ValueError(f"{path} is not a pose bank of format {BANK_FORMAT!r}")
        missing = [k for k in (*_ARRAY_KEYS, "clip_names", "split_names") if k not in contents]
        if missing:
            raise ValueError(f"{path} lacks the arrays {missing}")
        if tuple(str(n) for n in contents["split_names"]) != SPLIT_NAMES:
            raise ValueError(f"{path} has unexpected split names {contents['split_names']}")
        bank = cls(
            **{key: contents[key] for key in _ARRAY_KEYS},
            clip_names=tuple(str(n) for n in contents["clip_names"]),
        )
        if split == "all":
            return bank
        selected = bank.select(bank.split == SPLIT_NAMES.index(split), split)
        if len(selected) == 0:
            raise ValueError(
                f"{path} holds no {split!r} poses (too few subjects to split?); "
                "load split='all' or rebuild from more subjects"
            )
        return selected
