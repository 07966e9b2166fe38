"""One self-contained HTML page of an explorer scene, for course pages, slides and notebooks.

viser serialises the nodes its server holds (``server.scene.as_html()``: its web client with the
scene embedded as data, no external resources, no server needed to view it). This module adds
what a reader of a saved page needs and a live view does not: a caption saying what is shown
(photo, model, evidence, occluders, samples) and a title. It writes the page without ever
overwriting a file the user made (unless asked), and wraps it for notebooks (an ``<iframe
srcdoc>``, which Jupyter shows inline).

The scene itself is whatever the server holds: the live explorer's (the "Export page" button)
or a headless app's (:mod:`hkpd.explorer.notebook`, ``hkpd-explore --export-html``).
"""

from __future__ import annotations

import html
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import viser

from hkpd.explorer.panels.status import source_text
from hkpd.explorer.scene_file import PAGE_SCENE_ID
from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.prediction.posterior import BodyPosterior

Box = tuple[float, float, float, float]

CAPTION_ID = "hkpd-caption"
"""``id`` of the caption's element in the page (tests and style sheets find it by this)."""

CAPTION_STYLE = (
    "position:fixed;left:12px;bottom:12px;max-width:min(70ch,90vw);max-height:32vh;"
    "overflow:auto;z-index:1000;"
    "padding:8px 12px;border-radius:6px;background:rgba(255,255,255,0.9);color:#222;"
    "font:13px/1.4 system-ui,sans-serif;box-shadow:0 1px 4px rgba(0,0,0,0.25)"
)


class PageExistsError(FileExistsError):
    """The page's file exists and overwriting it was not asked for."""


@dataclass(frozen=True)
class SceneCaption:
    """What a saved scene shows, in words.

    Attributes:
        photo: the photo's name (a file name, or a description such as "the shipped photo").
        model: which model predicted (a checkpoint's name, or "the shipped model").
        evidence: which distribution is shown (:func:`hkpd.explorer.panels.status.source_text`).
        occluders: the boxes hidden from the network, ``(x0, y0, x1, y1)`` photo pixels.
        num_samples: samples behind the uncertainty colouring.
        num_displayed: sample bodies drawn around the most likely one.
        concentration_factors: ``(joint name, factor)`` of every joint whose concentration was
            scaled (empty: as predicted).
        numbers: a sentence of posterior numbers (:mod:`hkpd.explorer.caption_numbers`).
        colouring: the uncertainty body's colouring (a key of ``COLOURINGS``).
        compare: what posterior B is, in words, when a second set of columns shows it.
        scene_source: the scene file the page was made from ("" when none).
    """

    photo: str
    model: str
    evidence: str
    occluders: tuple[Box, ...]
    num_samples: int
    num_displayed: int
    concentration_factors: tuple[tuple[str, float], ...] = ()
    numbers: str = ""
    colouring: str = "log"
    compare: str = ""
    scene_source: str = ""

    @property
    def title(self) -> str:
        """A short title for the page (the browser tab)."""
        return f"hkpd: {self.photo}"

    def text(self, interactive: bool = True) -> str:
        """The caption as plain sentences; ``interactive``: for a page (it ends with how to
        turn the view), else for a still image (a PNG)."""
        if self.occluders:
            boxes = "; ".join(
                "#{} ({:.0f}, {:.0f})-({:.0f}, {:.0f})".format(i + 1, *box)
                for i, box in enumerate(self.occluders)
            )
            hidden = f"{len(self.occluders)} occluder(s) hide parts of the photo: {boxes}."
        else:
            hidden = "No occluders."
        if self.concentration_factors:
            scaled = ", ".join(
                f"{name.replace('_', ' ')} {factor:.3g}×"
                for name, factor in self.concentration_factors
            )
            hidden += f" Concentrations scaled: {scaled}."
        colour = (
            "its spread over the samples divided by its spread without occluders at default "
            "concentrations"
            if self.colouring == "change"
            else f"its spread over the {self.num_samples} samples"
        )
        compare = (
            f" Further right, B ({self.compare}): the same columns for that setting, its "
            "uncertainty body coloured "
            + ("by B's spread ÷ A's." if self.colouring == "change" else "on the same scale.")
            if self.compare
            else ""
        )
        text = (
            f"Photo: {self.photo}. Model: {self.model}. {self.evidence} {hidden} "
            f"Left: the photo with the detected keypoints and the most likely body drawn over "
            f"it. Middle: the most likely body and {self.num_displayed} of "
            f"{self.num_samples} samples. Right: each vertex coloured by {colour} (colour bar "
            f"below it).{compare} {self.numbers}"
            + (" Drag to orbit, scroll to zoom." if interactive else "")
        )
        text = " ".join(text.split())
        return f"{text} Scene: {self.scene_source}." if self.scene_source else text


LIVE_APP_ONLY = (
    re.compile(r"\s*\(fit \d+ ms\)"),  # how long the fit took on this machine, this time
    re.compile(r"\s*\([^()]*›[^()]*\)"),  # "(state the sex in Photo › Body)": a panel path
    re.compile(r"\*+"),  # markdown emphasis: a page shows plain text
)
"""What the live app's status line says that a saved page or PNG must not."""


def static_text(markdown: str) -> str:
    """A status line (markdown) as a saved page's plain sentences: without fit timings,
    pointers to the live panel ("Photo › Body") and markdown emphasis."""
    for pattern in LIVE_APP_ONLY:
        markdown = pattern.sub("", markdown)
    return " ".join(markdown.split())


def describe_scene(
    posterior: BodyPosterior,
    *,
    photo: str,
    model: str,
    occluders: Sequence[Box],
    num_samples: int,
    num_displayed: int,
    concentration_factors: Sequence[float] = (),
    numbers: str = "",
    colouring: str = "log",
    compare: str = "",
) -> SceneCaption:
    """The caption of a scene showing ``posterior`` (see :class:`SceneCaption`);
    ``concentration_factors``: ``(23,)`` factor per body joint (empty or all 1: as predicted)."""
    evidence = static_text(source_text(posterior))
    if getattr(posterior, "turned", False):
        evidence += (
            " Turned around: the same keypoints fitted by a body facing the other way (left "
            "and right swapped)."
        )
    scaled = tuple(
        (name, float(factor))
        for name, factor in zip(BODY_JOINT_NAMES, concentration_factors, strict=False)
        if abs(factor - 1.0) > 1e-6
    )
    return SceneCaption(
        photo=photo,
        model=model,
        evidence=evidence,
        occluders=tuple(tuple(float(v) for v in box) for box in occluders),
        num_samples=int(num_samples),
        num_displayed=int(num_displayed),
        concentration_factors=scaled,
        numbers=numbers,
        colouring=colouring,
        compare=compare,
    )


def scene_page(
    server: viser.ViserServer, caption: SceneCaption, scene_json: str | None = None
) -> str:
    """The scene ``server`` holds as one self-contained HTML document, with ``caption`` shown
    over its bottom-left corner and as its title, and ``scene_json`` (the scene file it shows,
    :mod:`hkpd.explorer.scene_file`) embedded so that the page reopens as a scene."""
    page = server.scene.as_html()
    title = html.escape(caption.title)
    page = page.replace("<title>Viser</title>", f"<title>{title}</title>", 1)
    block = (
        f'<div id="{CAPTION_ID}" style="{CAPTION_STYLE}">'
        f"<strong>{title}</strong><br>{html.escape(caption.text())}</div>"
    )
    if scene_json is not None:
        block += (
            f'<script type="application/json" id="{PAGE_SCENE_ID}">'
            f"{html.escape(scene_json, quote=False)}</script>"
        )
    start = page.index("<body")
    body_open = page.index(">", start) + 1
    return page[:body_open] + block + page[body_open:]


def write_page(path: str | Path, page: str, *, force: bool = False) -> Path:
    """Write ``page`` to ``path`` (UTF-8); refuse to replace an existing file unless ``force``.

    Raises:
        PageExistsError: ``path`` exists and ``force`` is False.
        IsADirectoryError / FileNotFoundError: ``path`` is a folder, or its folder is missing.
    """
    target = Path(path)
    if target.is_dir():
        raise IsADirectoryError(f"{target} is a folder: give a file name such as page.html")
    if not target.parent.is_dir():
        raise FileNotFoundError(f"folder {target.parent} does not exist: create it first")
    mode = "w" if force else "x"
    try:
        with target.open(mode, encoding="utf-8") as file:
            file.write(page)
    except FileExistsError:
        raise PageExistsError(
            f"{target} exists: choose another name, or pass --force to replace it"
        ) from None
    return target


def iframe_html(page: str, height: int = 520) -> str:
    """``page`` inside an ``<iframe srcdoc>`` ``height`` CSS pixels tall (what notebooks show
    inline: the page needs no server and no file)."""
    return (
        f'<iframe srcdoc="{html.escape(page, quote=True)}" width="100%" height="{int(height)}" '
        'style="border:1px solid #ddd" title="hkpd scene"></iframe>'
    )
