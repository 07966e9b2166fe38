"""Scenes for slides and notebooks without a browser: ``hkpd-explore --export-html`` writes one
self-contained page (no external resources, a caption saying what is shown) and keeps an
existing file; ``hkpd.explorer.show(posterior)`` returns what Jupyter displays inline."""

from __future__ import annotations

import html
import re

import numpy as np
import pytest

from hkpd.explorer import cli
from hkpd.explorer.html_page import CAPTION_ID, PageExistsError, write_page

DOUBLE = "test_explorer_double:OcclusionAwareDouble"
OCCLUDER = ("250", "210", "300", "260")
EXTERNAL = re.compile(r"""(?:src|href|action)\s*=\s*["']?\s*(?:https?:)?//""", re.IGNORECASE)
"""An attribute that makes a browser fetch something from elsewhere."""


def export(path, *extra: str) -> int:
    return cli.main(
        ["--demo", "synthetic", "--provider", DOUBLE, "--samples", "20", "--meshes", "2",
         "--export-html", str(path), "--occluder", *OCCLUDER, *extra]
    )  # fmt: skip


def test_export_html_writes_one_self_contained_page_with_its_caption(tmp_path, capsys) -> None:
    page = tmp_path / "page.html"
    assert export(page) == 0
    text = page.read_text(encoding="utf-8")
    assert text.startswith("<!doctype html>") and "window.__VISER_EMBED_DATA__=" in text
    assert not EXTERNAL.search(text), EXTERNAL.search(text)
    assert "url(http" not in text and "@import" not in text
    caption = re.search(f'<div id="{CAPTION_ID}"[^>]*>(.*?)</div>', text).group(1)
    caption = html.unescape(caption)
    assert "Photo: the synthetic demo scene." in caption
    assert "Model: provider test_explorer_double:OcclusionAwareDouble." in caption
    assert "1 occluder(s) hide parts of the photo: #1 (250, 210)-(300, 260)." in caption
    assert "2 of 20 samples" in caption and "Network only." in caption
    assert "<title>hkpd: the synthetic demo scene</title>" in text
    out = capsys.readouterr().out
    assert f"wrote {page}" in out and "HTTP" not in out  # no server address offered to anyone


def test_export_html_keeps_an_existing_file_unless_forced(tmp_path, capsys) -> None:
    page = tmp_path / "slides.html"
    page.write_text("my slides")
    with pytest.raises(SystemExit, match="exists: choose another name, or pass --force"):
        export(page)
    assert page.read_text() == "my slides"
    with pytest.raises(SystemExit, match="does not exist: create it first"):
        export(tmp_path / "missing" / "page.html")
    with pytest.raises(SystemExit, match="--occluder needs x0 y0 x1 y1"):
        cli.main(["--export-html", str(tmp_path / "p.html"), "--occluder", "5", "5", "1", "9"])
    assert export(page, "--force") == 0
    assert "window.__VISER_EMBED_DATA__=" in page.read_text()
    with pytest.raises(PageExistsError):
        write_page(page, "again")


def test_show_a_real_posterior_returns_an_inline_page() -> None:
    from hkpd.explorer import ScenePage, show
    from hkpd.explorer.demo_photo import shipped_photo
    from hkpd.prediction import Predictor, load_image

    try:
        predictor = Predictor.from_pretrained(device="cpu")
    except FileNotFoundError as error:
        pytest.skip(f"no shipped model: {error}")
    photo = load_image(shipped_photo()).pixels
    keypoints = predictor.detector.detect(photo).keypoints
    knee, ankle = keypoints[14], keypoints[16]
    box = (*(np.minimum(knee, ankle) - 20), *(np.maximum(knee, ankle) + 20))
    posterior = predictor.predict(photo, occluders=[box])
    page = show(posterior, photo_name="warrior_lunge.jpg", num_samples=10, num_displayed=1)
    assert isinstance(page, ScenePage)
    inline = page._repr_html_()
    assert inline.startswith("<iframe srcdoc=") and "</iframe>" in inline
    inner = html.unescape(re.search(r'srcdoc="([^"]*)"', inline).group(1))
    assert inner == page.html and "window.__VISER_EMBED_DATA__=" in inner
    assert "Photo: warrior_lunge.jpg." in page.caption and "1 occluder(s)" in page.caption
    assert "1 of 10 samples" in page.caption
