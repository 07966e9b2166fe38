"""Static outputs (exported pages, ``show()``'s notebook pages) say what they show and nothing
of the live app (issue 50): every text in the page's embedded scene (column titles, colour
bars' labels, the arrows' line) and its caption is scanned for the live app's words (shift +
drag, fit timings, panel paths, markdown), and the column titles follow the colouring."""

from __future__ import annotations

import base64
import html
import re

import msgspec
import zstandard
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer import cli, show
from hkpd.explorer.html_page import CAPTION_ID, static_text

DOUBLE = "test_explorer_double:OcclusionAwareDouble"
LIVE_APP_WORDS = re.compile(
    r"shift|click|drag a box|(?<!to orbit, )\bdrag\b(?! to orbit)|\bfit \d+ ms|\d+ ms\b|›|"
    r"\*|slider|panel|Pick the person|Distribution|Teaching",
    re.IGNORECASE,
)
"""Words only the live app may say (a page's "Drag to orbit, scroll to zoom" is for the page)."""


def page_texts(page: str) -> tuple[str, list[str]]:
    """The caption of an exported ``page`` and every string in its embedded viser scene."""
    data = re.search(r'window.__VISER_EMBED_DATA__="([^"]*)"', page).group(1)
    raw = base64.b64decode(data)
    inner = zstandard.ZstdDecompressor().decompress(raw[8:], int.from_bytes(raw[:8], "little"))
    size = int.from_bytes(inner[:8], "little")
    scene = msgspec.msgpack.decode(inner[8 : 8 + size])
    strings: list[str] = []

    def collect(value: object) -> None:
        if isinstance(value, str):
            strings.append(value)
        elif isinstance(value, dict):
            for item in value.values():
                collect(item)
        elif isinstance(value, list | tuple):
            for item in value:
                collect(item)

    collect(scene["messages"])
    caption = re.search(f'<div id="{CAPTION_ID}"[^>]*>(.*?)</div>', page, re.S).group(1)
    return html.unescape(re.sub(r"<[^>]+>", " ", caption)), strings


def label_texts(strings: list[str]) -> list[str]:
    """The strings a reader sees (sentences and titles, not node names or enum values)."""
    return [s for s in strings if " " in s and not s.startswith("/")]


def test_an_exported_compare_page_in_change_colouring_says_nothing_of_the_live_app(
    tmp_path,
) -> None:
    page = tmp_path / "page.html"
    assert cli.main(
        ["--demo", "synthetic", "--provider", DOUBLE, "--samples", "20", "--meshes", "2",
         "--export-html", str(page), "--occluder", "250", "210", "300", "260",
         "--colouring", "change", "--compare", "no-occluders"]
    ) == 0  # fmt: skip
    caption, strings = page_texts(page.read_text(encoding="utf-8"))
    seen = label_texts(strings)
    assert "Photo" in strings  # the static title, not "Photo · shift+drag to hide a part"
    assert any(s.startswith("A: change: uncertainty\n÷") for s in seen), seen
    assert "B (without the boxes):\nuncertainty ÷ A's" in seen  # short lines: see compare_scene
    assert not any(s.startswith(("Uncertainty\nover samples", "A: uncertainty")) for s in seen)
    for text in [caption, *seen]:
        assert not LIVE_APP_WORDS.search(text), (LIVE_APP_WORDS.search(text), text)
    assert "coloured by B's spread ÷ A's" in caption and "Drag to orbit" in caption


def test_a_notebook_page_says_nothing_of_the_live_app() -> None:
    double = OcclusionAwareDouble()
    posterior = double.predict(double.scene.image, [(250, 210, 300, 260)]).posterior
    page = show(posterior, double.scene.image, photo_name="demo.png", num_samples=20,
                num_displayed=2)  # fmt: skip
    caption, strings = page_texts(page.html)
    seen = label_texts(strings)
    assert "Uncertainty\nover samples" in seen and "Photo" in strings
    for text in [caption, *seen]:
        assert not LIVE_APP_WORDS.search(text), (LIVE_APP_WORDS.search(text), text)
    assert len(repr(page)) <= 200


def test_status_lines_become_plain_sentences() -> None:
    line = (
        "*Conditioned on 16 keypoints (fit 120 ms). Body drawn: female 69 %, not sure (state "
        "the sex in Photo › Body); height 163 ± 8 cm.* **⚠ Check this reading: quality 0.4.**"
    )
    assert static_text(line) == (
        "Conditioned on 16 keypoints. Body drawn: female 69 %, not sure; height 163 ± 8 cm. "
        "⚠ Check this reading: quality 0.4."
    )
