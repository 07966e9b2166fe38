"""The two lines above the tabs: what the app is doing, and which distribution is shown."""

from __future__ import annotations

from dataclasses import dataclass

import viser

from hkpd.explorer.body_text import body_sentence
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.quality import FLAG_MEANINGS, WARNING_FLAGS, ReadingQuality

PICKING_TEXT = "**Drag a box around the person** (Shift + drag on the photo)."


@dataclass(frozen=True)
class StatusSection:
    """Handles of the status lines.

    Attributes:
        line: timings, progress, errors and prompts.
        source: which distribution is shown (:func:`source_text`).
    """

    line: viser.GuiMarkdownHandle
    source: viser.GuiMarkdownHandle

    def show_status(self, text: str) -> None:
        """Replace the status line with ``text`` (markdown)."""
        self.line.content = text

    def show_picking(self) -> None:
        """Say in the status line that the next drag picks the person."""
        self.line.content = PICKING_TEXT

    def show_source(self, posterior: BodyPosterior) -> None:
        """Which distribution is shown, and why when the evidence fit fell back."""
        self.source.content = source_text(posterior)


def build_status_section(gui: viser.GuiApi) -> StatusSection:
    """The status lines, empty until the first prediction."""
    return StatusSection(line=gui.add_markdown("Starting…"), source=gui.add_markdown(""))


def source_text(posterior: BodyPosterior) -> str:
    """The status line for a posterior: which distribution is shown, why when the evidence fit
    fell back, whether the network read a copy of the crop turned upright or mirrored, and
    the drawn body's sex (with its probability, or "stated"), height and mass
    (:func:`hkpd.explorer.body_text.body_sentence`; only for a posterior with sexes), and the
    reading's quality (:func:`quality_text`).

    A custom provider's posterior may lack the evidence attributes: it then reads as the
    network alone."""
    reason = getattr(posterior, "fallback_reason", None)
    if reason:
        text = f"Network only: {reason}."
    elif getattr(posterior, "conditioned", False):
        fit = posterior.evidence_fit
        mask = " and the person mask" if "silhouette" in tuple(getattr(fit, "terms", ())) else ""
        text = (
            f"Conditioned on {fit.evidence_count} keypoints{mask} "
            f"(fit {fit.seconds * 1000:.0f} ms)."
        )
    else:
        text = "Network only."
    tilt = getattr(posterior, "upright_tilt_degrees", None)
    if tilt is not None:
        text += f" The person leans {abs(tilt):.0f}°: read from a copy turned upright."
    if getattr(posterior, "mirror_read", False):
        text += " Read from the mirror image (its body fits the keypoints better)."
    body = body_sentence(posterior)
    if body:
        text += f" {body}"
    return f"*{text}*{quality_text(posterior)}"


def quality_text(posterior: BodyPosterior) -> str:
    """The reading's quality (:mod:`hkpd.prediction.quality`) for the status line: a bold
    warning with its flags when the score is low or a warning flag is set, else the score and
    any notes (flags that do not warn); "" for a custom provider's posterior without one."""
    quality = getattr(posterior, "quality", None)
    if quality is None:
        return ""
    if quality.low:
        return f" **⚠ Check this reading: {quality.warning()}.**{_first_warning_meaning(quality)}"
    notes = f"; note: {', '.join(quality.flags)}" if quality.flags else ""
    return f" *Quality {quality.score:.2f}{notes}.*"


def _first_warning_meaning(quality: ReadingQuality) -> str:
    """What the first warning flag of ``quality`` means, in words (" *(…)*"), or ""."""
    named = [flag for flag in quality.flags if flag in WARNING_FLAGS]
    return f" *({FLAG_MEANINGS[named[0]]}.)*" if named else ""
