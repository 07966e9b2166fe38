"""The photo ``hkpd-explore`` opens by default: a CC0 photo of a kneeling lunge shipped in
``hkpd.assets`` (its licence and source: ``assets/photos/NOTICE.md``)."""

from __future__ import annotations

from pathlib import Path

from hkpd.assets import shipped_file

SHIPPED_PHOTO = ("photos", "warrior_lunge.jpg")
"""The photo inside the ``hkpd.assets`` package."""


def shipped_photo() -> Path:
    """Path of the shipped CC0 photo.

    Raises:
        FileNotFoundError: it is not in this installation.
    """
    return shipped_file(
        SHIPPED_PHOTO, "the shipped photo", "reinstall hkpd, or pass a photo of your own"
    )
