"""Ctrl-C and SIGTERM as a request to stop after the current training step.

A signal that interrupted a step halfway would leave weights one step ahead of the step
counter, and under ``torchrun`` it would leave the other ranks waiting inside a collective.
So the handlers only note the request; the loop looks at it after each step (all ranks
together, :func:`hkpd.training.distributed.average_and_any`), saves a checkpoint and stops.
Alone, a second Ctrl-C stops at once. Under torchrun it does not: every worker gets the
terminal's SIGINT and then torchrun's copy of it (torchrun kills workers that do not stop
within its own time limit).
"""

from __future__ import annotations

import signal
import threading
from types import FrameType


class StopSignals:
    """Within a ``with`` block, SIGINT and SIGTERM set :attr:`requested` instead of raising.

    Outside the main thread (where Python cannot install handlers) nothing changes. The
    previous handlers come back when the block ends.

    Args:
        force_on_second_interrupt: a second SIGINT raises KeyboardInterrupt (SIGTERM never
            does).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, force_on_second_interrupt: bool = True) -> None:
        self.force_on_second_interrupt = force_on_second_interrupt
        self.requested = self._interrupted = False
        self._previous: dict[int, object] = {}

    def _note(self, signum: int, frame: FrameType | None) -> None:
        if signum == signal.SIGINT:
            if self._interrupted and self.force_on_second_interrupt:
                raise KeyboardInterrupt
            self._interrupted = True
        self.requested = True

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for signum in self.SIGNALS:
                self._previous[signum] = signal.signal(signum, self._note)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        self._previous.clear()
