"""Data files shipped with hkpd (installed as ``hkpd.assets``); see README.md beside this file.

:func:`shipped_file` finds one of them: the one lookup the body model, the predictor's weights
and BlazePose's models share.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path


def shipped_file(parts: tuple[str, ...], what: str, remedy: str) -> Path:
    """Path of the shipped file ``hkpd.assets/<parts joined by />``.

    Args:
        parts: the file's path inside ``hkpd.assets``, e.g. ``("models", "hkpd_hierarchical.pt")``.
        what: what the file is, for the error (e.g. ``"the pretrained model"``).
        remedy: what to do when it is missing, for the error.

    Raises:
        FileNotFoundError: the file is not in this installation, naming it and the remedy.
    """
    resource = importlib.resources.files("hkpd.assets").joinpath(*parts)
    if not resource.is_file():
        raise FileNotFoundError(
            f"{what} {'/'.join(parts)} is not in this installation of hkpd; {remedy}"
        )
    return Path(str(resource))
