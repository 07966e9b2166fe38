"""One background thread that runs the explorer's heavy work, coalescing requests.

GUI callbacks never compute: they update the state and :meth:`CoalescingWorker.submit` a job.
Each *lane* ("predict", "sample", ...) holds at most ONE pending job; a newer submission
replaces the older one, so dragging a slider through fifty values runs a handful of jobs, not
fifty. A submission may carry a debounce delay: the job runs only once no newer submission
for its lane arrived for that long (used for predictions, which are slow, while a box is being
resized); with ``leading`` an isolated submission (nothing pending or submitted in its lane for
that long) runs at once, and only the ones that follow it closely wait. When several lanes are
due, the one listed first runs first.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

Job = Callable[[], None]


@dataclass
class LaneStats:
    """Counters of one lane: jobs submitted, run, and replaced before they ran."""

    submitted: int = 0
    run: int = 0
    superseded: int = 0
    failed: int = 0
    last_seconds: float = 0.0


@dataclass
class _Pending:
    job: Job
    due: float


@dataclass
class CoalescingWorker:
    """A single worker thread with one pending slot per lane.

    Args:
        lanes: lane names, highest priority first.
        on_error: called (in the worker thread) with the lane and exception when a job raises;
            the worker keeps running. Defaults to printing the traceback.
        on_job_end: called (in the worker thread) with the lane after each job, however it
            ended (the app removes its progress sign there).
    """

    lanes: Sequence[str]
    on_error: Callable[[str, BaseException], None] | None = None
    on_job_end: Callable[[str], None] | None = None
    stats: dict[str, LaneStats] = field(init=False)
    _pending: dict[str, _Pending] = field(init=False, default_factory=dict)
    _last_submitted: dict[str, float] = field(init=False, default_factory=dict)
    _running: str | None = field(init=False, default=None)
    _stopping: bool = field(init=False, default=False)
    _condition: threading.Condition = field(init=False, default_factory=threading.Condition)
    _thread: threading.Thread | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        if len(set(self.lanes)) != len(self.lanes) or not self.lanes:
            raise ValueError(f"lanes must be distinct and non-empty, got {list(self.lanes)}")
        self.stats = {lane: LaneStats() for lane in self.lanes}

    # ------------------------------------------------------------------ control
    def start(self) -> CoalescingWorker:
        """Start the thread (daemon: it never keeps the process alive)."""
        with self._condition:
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._loop, name="hkpd-explorer-worker", daemon=True
                )
                self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        """Drop pending jobs, let the running one finish, end the thread."""
        with self._condition:
            self._stopping = True
            self._pending.clear()
            self._condition.notify_all()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout)

    def submit(self, lane: str, job: Job, delay_s: float = 0.0, leading: bool = False) -> None:
        """Make ``job`` the pending job of ``lane``, replacing any job not yet started.

        Args:
            lane: one of :attr:`lanes`.
            job: callable without arguments, run in the worker thread.
            delay_s: debounce: run no earlier than this many seconds from now (a newer
                submission restarts the wait).
            leading: run at once when the lane has nothing pending and its last submission is
                ``delay_s`` old or more (an isolated edit waits for nothing; issue 58: the
                explorer's occluder edits); the submissions that follow it closely wait.
        """
        if lane not in self.stats:
            raise ValueError(f"unknown lane {lane!r}; lanes are {list(self.lanes)}")
        with self._condition:
            if self._stopping:
                return
            stats = self.stats[lane]
            stats.submitted += 1
            if lane in self._pending:
                stats.superseded += 1
            now, wait = time.monotonic(), max(delay_s, 0.0)
            last = self._last_submitted.get(lane)
            isolated = lane not in self._pending and (last is None or now - last >= wait)
            self._last_submitted[lane] = now
            self._pending[lane] = _Pending(job, now if leading and isolated else now + wait)
            self._condition.notify_all()

    def wait_idle(self, timeout: float = 10.0) -> bool:
        """Block until nothing is pending or running; False on timeout."""
        deadline = time.monotonic() + timeout
        with self._condition:
            while self._pending or self._running is not None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._condition.wait(min(remaining, 0.05))
            return True

    # ------------------------------------------------------------------ thread
    def _next_due(self) -> tuple[str, Job] | None:
        """Pop the highest-priority due job (caller holds the condition)."""
        now = time.monotonic()
        for lane in self.lanes:
            pending = self._pending.get(lane)
            if pending is not None and pending.due <= now:
                del self._pending[lane]
                return lane, pending.job
        return None

    def _loop(self) -> None:
        while True:
            with self._condition:
                while True:
                    if self._stopping:
                        self._condition.notify_all()
                        return
                    picked = self._next_due()
                    if picked is not None:
                        break
                    if self._pending:
                        wait = min(p.due for p in self._pending.values()) - time.monotonic()
                        self._condition.wait(max(wait, 0.0))
                    else:
                        self._condition.wait()
                lane, job = picked
                self._running = lane
            started = time.perf_counter()
            failed = False
            try:
                job()
            except Exception as error:  # keep serving: one bad job must not kill the app
                failed = True
                if self.on_error is not None:
                    self.on_error(lane, error)
                else:
                    traceback.print_exc()
            if self.on_job_end is not None:
                self.on_job_end(lane)
            with self._condition:
                stats = self.stats[lane]
                stats.run += 1
                stats.failed += int(failed)
                stats.last_seconds = time.perf_counter() - started
                self._running = None
                self._condition.notify_all()
