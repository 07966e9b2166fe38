"""Notebooks: ``hkpd.explorer.show`` adds no server lines to a cell (viser prints through
rich's global console, which a notebook turns into cell outputs), and what it returns has a
short text repr and an inline view under 4 MB."""

from __future__ import annotations

import io

import rich
import rich.console
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer import show

MAX_REPR_CHARS = 200
MAX_INLINE_BYTES = 4_000_000


def test_show_prints_nothing_and_returns_a_small_page(capfd, monkeypatch) -> None:
    cell = io.StringIO()  # stands in for a notebook cell's rich output
    monkeypatch.setattr(rich, "_console", rich.console.Console(file=cell, force_terminal=True))
    double = OcclusionAwareDouble()
    posterior = double.predict(double.scene.image, []).posterior
    page = show(posterior, image=double.scene.image, num_samples=10, num_displayed=1)
    out, err = capfd.readouterr()
    assert cell.getvalue() == "" and out == "" and "viser" not in err
    assert len(repr(page)) <= MAX_REPR_CHARS and repr(page).startswith("ScenePage(")
    assert len(page._repr_html_().encode("utf-8")) <= MAX_INLINE_BYTES
    assert len(repr(posterior)) <= MAX_REPR_CHARS
    rich.print("after show, the cell's console is the notebook's again")
    assert "after show" in cell.getvalue()


class Notification:
    def __init__(self, title: str) -> None:
        self.title, self.removed = title, False

    def remove(self) -> None:
        self.removed = True


class Tab:
    client_id = 7

    def __init__(self) -> None:
        self.shown: list[Notification] = []

    def add_notification(self, title: str, body: str, **_kwargs) -> Notification:
        self.shown.append(Notification(title))
        return self.shown[-1]


def test_a_notification_replaces_the_last_one_of_its_title() -> None:
    from hkpd.explorer.notices import Notices

    notices, tab = Notices(), Tab()
    for title in ("Weak keypoints", "Photo loaded", "Weak keypoints", "Weak keypoints"):
        notices.show(tab, title, "…", error=title.startswith("Weak"))
    removed = [(n.title, n.removed) for n in tab.shown]
    assert removed == [("Weak keypoints", True), ("Photo loaded", False),
                       ("Weak keypoints", True), ("Weak keypoints", False)]  # fmt: skip
