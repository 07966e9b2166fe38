"""Train/validation/test split of mocap clips by CMU subject, so no person appears in two splits.

CMU clip names start with the subject number: ``02_01.bvh`` is subject 2, trial 1
(``005_02`` and ``60_01_scaled`` work too).
"""

from __future__ import annotations

import math
import re
import zlib
from collections.abc import Iterable

SPLIT_NAMES: tuple[str, ...] = ("train", "val", "test")
"""Split names; a pose bank stores a split as an index into this tuple."""

_SUBJECT_PATTERN = re.compile(r"^(\d+)_")


def subject_of(clip_name: str) -> int:
    """The CMU subject number of a clip name such as ``"02_01"`` (-> 2).

    Raises:
        ValueError: if the name does not start with digits followed by ``_``.
    """
    match = _SUBJECT_PATTERN.match(clip_name)
    if match is None:
        raise ValueError(
            f"cannot read a CMU subject number from clip name {clip_name!r}: expected names like "
            "'02_01' (subject _ trial); rename the file or put it in a separate bank"
        )
    return int(match.group(1))


def assign_splits(
    subjects: Iterable[int], val_fraction: float = 0.1, test_fraction: float = 0.1, seed: int = 0
) -> dict[int, str]:
    """Deterministically assign whole subjects to ``"train"``, ``"val"`` and ``"test"``.

    Subjects are ordered by a hash of ``(seed, subject)``; the first ``ceil(test_fraction * n)``
    go to test, the next ``ceil(val_fraction * n)`` to validation, the rest to training. With
    fewer than three subjects everything is training data. The result depends only on the set of
    subjects and the arguments, not on file order.

    Returns:
        subject -> split name.
    """
    if not (0 <= val_fraction < 1 and 0 <= test_fraction < 1 and val_fraction + test_fraction < 1):
        raise ValueError("val_fraction and test_fraction must be in [0, 1) and sum below 1")
    unique = sorted({int(s) for s in subjects})
    ordered = sorted(unique, key=lambda s: (zlib.crc32(f"{seed}:{s}".encode()), s))
    if len(ordered) < 3:
        return dict.fromkeys(ordered, "train")
    num_test = math.ceil(test_fraction * len(ordered)) if test_fraction > 0 else 0
    num_val = math.ceil(val_fraction * len(ordered)) if val_fraction > 0 else 0
    num_test = min(num_test, len(ordered) - 1)
    num_val = min(num_val, len(ordered) - 1 - num_test)
    splits: dict[int, str] = {}
    for rank, subject in enumerate(ordered):
        if rank < num_test:
            splits[subject] = "test"
        elif rank < num_test + num_val:
            splits[subject] = "val"
        else:
            splits[subject] = "train"
    return splits
