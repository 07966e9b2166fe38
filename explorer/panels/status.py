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
        text += (
            " The photo was also read flipped left to right: that reading fitted the keypoints "
            "better, so the fit started from it."
        )
    body = body_sentence(posterior)
    if body:
        text += f" {body}"
    return f"*{text}*{quality_text(posterior)}"


def quality_text(posterior: BodyPosterior) -> str:
    """The reading's quality (:mod:`hkpd.prediction.quality`) for the status line: a bold
    warning with what looks wrong when the score is low or a warning flag is set, else the
    score and any notes (flags that do not warn); each flag in words (:func:`flag_words`),
    never its name. "" for a custom provider's posterior without a quality."""
    quality = getattr(posterior, "quality", None)
    if quality is None:
        return ""
    if quality.low:
        words = f" *({flag_words(quality)}.)*" if quality.flags else ""
        return f" **⚠ Check this reading: quality {quality.score:.2f}.**{words}"
    notes = f"; note: {flag_words(quality)}" if quality.flags else ""
    return f" *Quality {quality.score:.2f}{notes}.*"


def flag_words(quality: ReadingQuality) -> str:
    """``quality``'s flags in words (:data:`hkpd.prediction.quality.FLAG_MEANINGS`, the one
    place a flag gets its words), the warning flags first, joined by "; "."""
    ordered = sorted(quality.flags, key=lambda flag: flag not in WARNING_FLAGS)
    return "; ".join(FLAG_MEANINGS[flag] for flag in ordered)
