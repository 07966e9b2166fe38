"""The photo ``hkpd-explore`` opens by default: a CC0 photo of a kneeling lunge shipped in
``hkpd.assets`` (its licence and source: ``assets/photos/NOTICE.md``)."""

from __future__ import annotations

import importlib.resources
from pathlib import Path

SHIPPED_PHOTO = ("photos", "warrior_lunge.jpg")
"""The photo inside the ``hkpd.assets`` package."""


def shipped_photo() -> Path:
    """Path of the shipped CC0 photo.

    Raises:
        FileNotFoundError: it is not in this installation.
    """
    resource = importlib.resources.files("hkpd.assets").joinpath(*SHIPPED_PHOTO)
    if not resource.is_file():
        raise FileNotFoundError(
            f"the shipped photo {'/'.join(SHIPPED_PHOTO)} is missing from this installation of hkpd"
        )
    return Path(str(resource))
