"""Ctrl-C in the command-line programs: at any moment one line, exit status 130, never swallowed.

Two things stand in the way of that in a plain ``main()``:

- **Imports that swallow it.** ``import trimesh`` (and libraries like it) wraps optional imports
  in ``except BaseException``, so a KeyboardInterrupt raised inside one is caught and the program
  runs on as if nothing happened. :func:`deferred_interrupts` notes a SIGINT instead of raising
  it, and raises it once the block (the imports) is over.
- **The imports before** ``main()``. The console scripts import the command's module, and with it
  torch, OpenCV and trimesh, before ``main`` runs. So ``hkpd-predict``, ``hkpd-eval``,
  ``hkpd-train`` and ``hkpd-explore`` start in :func:`run_command` (the entry points below): it
  imports the command under :func:`deferred_interrupts`, then runs its ``main``, and turns a
  KeyboardInterrupt from anywhere into ``PROGRAM: interrupted`` on stderr and status 130.

- **Code that swallows it later.** Some library code still catches the KeyboardInterrupt (1 of
  20 random SIGINTs to ``hkpd-predict`` ran to the end with exit 0 while only the imports were
  deferred). So :func:`run_command` also installs a handler that *remembers* the SIGINT before
  raising it, and the commands call :func:`raise_if_interrupted` at their safe points (before
  each photo, before a folder is committed, before a report is written): a swallowed Ctrl-C is
  raised again there.

The commands' own ``main`` catch KeyboardInterrupt where they have something to clean up or to
say (which photos are done, the checkpoint written) and return :data:`INTERRUPTED_STATUS`.
This module imports nothing of hkpd; the commands are imported by name.
"""

from __future__ import annotations

import importlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from types import FrameType

INTERRUPTED_STATUS = 130
"""Exit status after Ctrl-C (128 + SIGINT), as shells report a program killed by it."""

COMMANDS = {
    "hkpd-predict": "hkpd.prediction.cli",
    "hkpd-eval": "hkpd.evaluation.cli",
    "hkpd-train": "hkpd.training.cli",
    "hkpd-explore": "hkpd.explorer.cli",
}
"""Program name -> the module whose ``main(argv) -> int`` runs it."""

HEAVY_IMPORTS = ("torch", "cv2", "trimesh")
"""Imported (deferred) before a command's module, so none of them runs later with the default
handler in place (trimesh catches BaseException in its imports)."""


_received = threading.Event()
"""Set by every SIGINT that reached a handler of this module (see :func:`raise_if_interrupted`)."""


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if a Ctrl-C arrived since :func:`run_command` started (one that
    some library code caught and dropped); a no-op when the command runs without it."""
    if _received.is_set():
        raise KeyboardInterrupt


def _remember_and_raise(signum: int, frame: FrameType | None) -> None:
    _received.set()
    raise KeyboardInterrupt


@contextmanager
def deferred_interrupts() -> Iterator[None]:
    """Within the block a SIGINT is noted, not raised; it is raised as KeyboardInterrupt when
    the block ends (normally or not). Outside the main thread nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:
        received.append(signum)
        _received.set()

    previous = signal.signal(signal.SIGINT, note)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if received:
            raise KeyboardInterrupt


def interrupted(program: str, detail: str = "") -> int:
    """Print the one line for an interrupted ``program`` and return :data:`INTERRUPTED_STATUS`.

    Further Ctrl-C are ignored from here on (the program is already on its way out)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    print(f"{program}: interrupted{'; ' + detail if detail else ''}", file=sys.stderr, flush=True)
    return INTERRUPTED_STATUS


def run_command(program: str, argv: Sequence[str] | None = None) -> int:
    """Import ``program``'s module with Ctrl-C deferred, run its ``main(argv)``; a Ctrl-C that
    reaches here gives one line and :data:`INTERRUPTED_STATUS`."""
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, _remember_and_raise) if main_thread else None
    _received.clear()
    try:
        with deferred_interrupts():
            for name in HEAVY_IMPORTS:
                importlib.import_module(name)
            main: Callable[[Sequence[str] | None], int] = importlib.import_module(
                COMMANDS[program]
            ).main
        status = main(argv)
        if _received.is_set() and status != INTERRUPTED_STATUS:  # swallowed after the last check
            return interrupted(program, "after the work was done")
        return status
    except KeyboardInterrupt:
        return interrupted(program)
    finally:
        _received.clear()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def predict() -> int:
    """The ``hkpd-predict`` entry point."""
    return run_command("hkpd-predict")


def evaluate() -> int:
    """The ``hkpd-eval`` entry point."""
    return run_command("hkpd-eval")


def train() -> int:
    """The ``hkpd-train`` entry point."""
    return run_command("hkpd-train")


def explore() -> int:
    """The ``hkpd-explore`` entry point."""
    return run_command("hkpd-explore")
