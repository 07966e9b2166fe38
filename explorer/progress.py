"""A visible sign of progress while a view is computed: a loading notification in every tab
("Computing the view · Predicting the posterior (1 of 3)…") and the same words in the status
line, shown once a job has run for :data:`SHOW_AFTER_S` (a slider step or a quick prediction
shows nothing) and removed when the job ends.

The app names the stage it starts (:meth:`Progress.step`); the first stage of a job fixes its
plan (a prediction: predict, sample, send; a slider move: sample, send), which numbers the
stages. The worker ends the job (:meth:`Progress.done`) whatever happened in it. Tabs that
connect while a job is shown get the notification too.
"""

from __future__ import annotations

import contextlib
import threading
from typing import Any

from hkpd.explorer.worker import CoalescingWorker

PREDICT = "Predicting the posterior"
SAMPLE = "Drawing the samples and the uncertainty"
SEND = "Sending the bodies to the browser"
PLANS = {PREDICT: (PREDICT, SAMPLE, SEND), SAMPLE: (SAMPLE, SEND)}
"""A job's stages, by the stage it starts with."""
TITLE = "Computing the view"
SHOW_AFTER_S = 0.5
"""A job shorter than this shows no sign (no flicker on every slider step)."""


class Progress:
    """The progress notice of the app's worker jobs (thread-safe).

    Args:
        server: the ``viser.ViserServer`` whose tabs are told.
        status: the status section (:class:`~hkpd.explorer.panels.status.StatusSection`) whose
            line repeats the notice.
        worker: the app's :class:`~hkpd.explorer.worker.CoalescingWorker` (None: the caller
            calls :meth:`done`); every job it ends ends the notice.
        show_after_s: how long a job runs before its sign is shown.
    """

    def __init__(
        self,
        server: Any,
        status: Any,
        worker: CoalescingWorker | None = None,
        show_after_s: float = SHOW_AFTER_S,
    ) -> None:
        self.server, self.status, self.show_after_s = server, status, show_after_s
        self._lock = threading.Lock()
        self._plan: tuple[str, ...] = ()
        self._text = ""
        self._job = 0
        self._shown = False
        self._handles: dict[int, Any] = {}
        self._timer: threading.Timer | None = None
        self._status: tuple[str, str] | None = None
        """The status line before this job wrote to it, and what it wrote."""
        server.on_client_connect(self._connected)
        if worker is not None:
            worker.on_job_end = lambda _lane: self.done()

    @property
    def text(self) -> str:
        """The current stage in words ("" between jobs)."""
        with self._lock:
            return self._text

    @property
    def shown(self) -> bool:
        """The sign is on screen (the job has run longer than ``show_after_s``)."""
        with self._lock:
            return self._shown

    def step(self, stage: str) -> None:
        """The running job starts ``stage`` (one of :data:`PLANS`' stages).

        Raises:
            ValueError: an unknown stage.
        """
        if not any(stage in plan for plan in PLANS.values()):
            raise ValueError(f"unknown stage {stage!r}; stages: {list(PLANS[PREDICT])}")
        with self._lock:
            if not self._plan or stage not in self._plan:
                self._plan = PLANS.get(stage, (stage,))
            index = self._plan.index(stage) + 1
            self._text = f"{stage} ({index} of {len(self._plan)})…"
            shown, job, starting = self._shown, self._job, self._timer is None
            text = self._text
            if starting and not shown:
                self._timer = threading.Timer(self.show_after_s, self._show, (job,))
                self._timer.daemon = True
        if shown:
            self._update()
        elif stage == PREDICT:  # the status line says so at once, as it always did
            self._show_status(text)
        if not shown and starting and self._timer is not None:
            self._timer.start()

    def done(self) -> None:
        """The job ended: remove its sign; the status line goes back to what it said before
        unless the job wrote its own (its timings, an error, a prompt)."""
        with self._lock:
            timer, handles, status = self._timer, list(self._handles.values()), self._status
            self._plan, self._text, self._shown, self._timer = (), "", False, None
            self._status = None
            self._handles = {}
            self._job += 1
        if timer is not None:
            timer.cancel()
        for handle in handles:
            with contextlib.suppress(Exception):  # the tab is gone
                handle.remove()
        if status is not None and self.status.line.content == status[1]:
            self.status.show_status(status[0])

    def _show_status(self, text: str) -> None:
        line = f"⏳ *{text}*"
        with self._lock:
            before = self.status.line.content if self._status is None else self._status[0]
            self._status = (before, line)
        self.status.show_status(line)

    def _show(self, job: int) -> None:
        with self._lock:
            if job != self._job or not self._text:
                return  # ended meanwhile
            self._shown = True
        self._update()

    def _update(self) -> None:
        """Show the current stage in the status line and every tab."""
        text = self.text
        if not text:
            return
        self._show_status(text)
        for client in list(self.server.get_clients().values()):
            self._tell(client, text)

    def _tell(self, client: Any, text: str) -> None:
        key = getattr(client, "client_id", id(client))
        with self._lock:
            handle = self._handles.get(key)
        if handle is not None:
            with contextlib.suppress(Exception):
                handle.body = text
            return
        handle = client.add_notification(TITLE, text, loading=True, with_close_button=False)
        with self._lock:
            current = self._shown
            if current:
                self._handles[key] = handle
        if not current:  # the job ended while the notification was being added
            with contextlib.suppress(Exception):
                handle.remove()

    def _connected(self, client: Any) -> None:
        text = self.text
        if text and self.shown:
            self._tell(client, text)
