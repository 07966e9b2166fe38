"""The explorer's sign of progress (explorer/progress.py): a loading notification in every tab
and the status line while a slow job runs, nothing for a quick one, both cleared when the job
ends; and in the app, a slow prediction shows it and the finished view clears it."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import pytest
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.progress import PREDICT, SAMPLE, SEND, TITLE, Progress


class Notice:
    def __init__(self, title: str, body: str, loading: bool) -> None:
        self.title, self.body, self.loading, self.removed = title, body, loading, False

    def remove(self) -> None:
        self.removed = True


class Tab:
    def __init__(self, ident: int) -> None:
        self.client_id, self.notices = ident, []
        self.camera = SimpleNamespace(aspect=1.6, image_width=1400, position=0, look_at=0)

    def add_notification(self, title, body, loading=False, **_kwargs) -> Notice:
        self.notices.append(Notice(title, body, loading))
        return self.notices[-1]

    def shown(self) -> list[Notice]:
        return [n for n in self.notices if not n.removed]


class Server:
    def __init__(self, tabs) -> None:
        self.tabs, self.connect = {t.client_id: t for t in tabs}, None

    def get_clients(self):
        return dict(self.tabs)

    def on_client_connect(self, callback) -> None:
        self.connect = callback


def status_line(text: str = "Prediction 40 ms"):
    line = SimpleNamespace(content=text)
    return SimpleNamespace(line=line, show_status=lambda t: setattr(line, "content", t))


def wait_until(condition, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return False


def test_a_slow_job_is_shown_stage_by_stage_and_cleared_when_it_ends() -> None:
    tab, status = Tab(1), status_line()
    server = Server([tab])
    progress = Progress(server, status, show_after_s=0.05)
    progress.step(PREDICT)
    assert status.line.content == "⏳ *Predicting the posterior (1 of 3)…*"  # at once
    assert wait_until(lambda: progress.shown) and len(tab.shown()) == 1
    notice = tab.shown()[0]
    assert notice.title == TITLE and notice.loading and "(1 of 3)" in notice.body
    progress.step(SAMPLE)
    assert notice.body == "Drawing the samples and the uncertainty (2 of 3)…"
    assert "(2 of 3)" in status.line.content and len(tab.shown()) == 1  # replaced, not added
    late = Tab(2)  # a tab opened while the job runs is told too
    server.tabs[2] = late
    server.connect(late)
    assert late.shown()[0].body == notice.body
    progress.done()
    assert not tab.shown() and not late.shown() and not progress.text
    assert status.line.content == "Prediction 40 ms"  # what it said before the job


def test_a_quick_job_shows_nothing_and_its_own_status_line_stays() -> None:
    tab, status = Tab(1), status_line()
    progress = Progress(Server([tab]), status, show_after_s=0.2)
    progress.step(SAMPLE)  # a slider step: sample, send
    progress.step(SEND)
    assert progress.text == "Sending the bodies to the browser (2 of 2)…"
    status.show_status("Prediction 50 ms · 100 samples")  # the job's own line
    progress.done()
    time.sleep(0.3)
    assert tab.notices == [] and status.line.content == "Prediction 50 ms · 100 samples"
    with pytest.raises(ValueError, match="unknown stage"):
        progress.step("Thinking")


class SlowDouble:
    """The test double, slowed down while ``slow`` is set (a loaded laptop)."""

    def __init__(self) -> None:
        self.double, self.slow = OcclusionAwareDouble(), threading.Event()

    def predict(self, image, occluders, evidence=True, bbox=None):
        if self.slow.is_set():
            time.sleep(1.5)
        return self.double.predict(image, occluders, evidence, bbox)


def test_the_app_shows_a_slow_prediction_and_clears_it_with_the_view() -> None:
    provider = SlowDouble()
    app = ExplorerApp(provider, provider.double.scene.image, port=0, num_samples=20)
    try:
        assert app.wait_idle(60)
        tab = Tab(7)
        app.server.get_clients = lambda: {7: tab}
        provider.slow.set()
        app.add_occluder((250, 210, 300, 260))
        assert wait_until(lambda: app.progress.shown)
        assert "Predicting the posterior (1 of 3)" in app.panels.status.line.content
        assert tab.shown() and tab.shown()[0].loading
        assert app.wait_idle(60)
        assert not tab.shown() and not app.progress.text
        assert app.panels.status.line.content.startswith("Prediction ")  # the timings
        assert not app.errors
    finally:
        app.stop()
