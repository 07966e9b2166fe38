"""Ctrl-C in the command-line programs: at any moment one line, exit status 130, never swallowed.

Two things stand in the way of that in a plain ``main()``:

- **Code that swallows it.** ``import trimesh`` wraps optional imports in
  ``except BaseException``, so a KeyboardInterrupt raised inside one is caught and the program
  runs on as if nothing happened (2 of 13 tries in issue 44; other library code can do the
  same). So the programs start in :func:`run_command` (their console-script entry points are
  below), which installs a SIGINT handler that *remembers* the Ctrl-C before raising it; after
  each heavy import, and at the commands' safe points (before each photo, before a folder is
  committed, before a report is written), :func:`raise_if_interrupted` raises a swallowed one
  again, and a command that returns normally after one still ends in status 130.
- **The imports before** ``main()``: the command's module pulls in torch, OpenCV and trimesh
  before ``main`` runs, so a Ctrl-C there would be a traceback. :func:`run_command` imports the
  command itself and turns a KeyboardInterrupt from anywhere into ``PROGRAM: interrupted`` on
  stderr and status 130.

:func:`deferred_interrupts` holds a Ctrl-C back for the few statements that must not be cut in
half (renaming a finished folder into place, removing a partial one, writing a report).

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
from types import FrameType, ModuleType

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
"""Imported one by one before a command's module, each followed by :func:`raise_if_interrupted`
(trimesh catches BaseException in its imports)."""

LAZY_IMPORTS = {"hkpd-explore": ("trimesh",)}
"""Heavy imports a command makes only later, off the main thread, where no Ctrl-C lands: the
explorer imports trimesh on its first mesh export (about 1 s of its start-up otherwise)."""


_received = threading.Event()
"""Set by every SIGINT that reached a handler of this module (see :func:`raise_if_interrupted`)."""


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if a Ctrl-C arrived since :func:`run_command` started (one that
    some library code caught and dropped); a no-op when the command runs without it."""
    if _received.is_set():
        raise KeyboardInterrupt


IMPORT_MACHINERY = "<frozen importlib"
"""The file name of Python's own import machinery's frames (``<frozen importlib._bootstrap>``)."""


def _remember_and_raise(signum: int, frame: FrameType | None) -> None:
    """The SIGINT handler of :func:`run_command`: remember the Ctrl-C, and raise it unless it
    landed in the import machinery's own code. There it is only remembered, and
    :func:`raise_if_interrupted` raises it once the import is done: a KeyboardInterrupt raised
    in a module lock's weakref callback is printed as "Exception ignored in ..." with a
    traceback and dropped, and one raised half-way through the machinery can leave a module
    half-registered."""
    _received.set()
    if frame is not None and frame.f_code.co_filename.startswith(IMPORT_MACHINERY):
        return
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
    """Print ``PROGRAM: interrupted<detail>`` (``detail`` brings its own leading "; " or " ")
    on stderr and return :data:`INTERRUPTED_STATUS`."""
    print(f"{program}: interrupted{detail}", file=sys.stderr, flush=True)
    return INTERRUPTED_STATUS


def _import_or_interrupted(name: str) -> ModuleType:
    """Import ``name``; a Ctrl-C during it is a KeyboardInterrupt, also when the library
    turned it into another error (an import interrupted half-way, caught by its importer,
    leaves e.g. numpy's "cannot load module more than once per process" behind)."""
    try:
        module = importlib.import_module(name)
    except Exception:
        if _received.is_set():
            raise KeyboardInterrupt from None
        raise
    raise_if_interrupted()
    return module


def run_command(program: str, argv: Sequence[str] | None = None) -> int:
    """Import ``program``'s module, run its ``main(argv)``; a Ctrl-C at any moment (also one
    that some library swallowed) gives one line and :data:`INTERRUPTED_STATUS`."""
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, _remember_and_raise) if main_thread else None
    _received.clear()
    try:
        for name in HEAVY_IMPORTS:
            if name not in LAZY_IMPORTS.get(program, ()):
                _import_or_interrupted(name)
        module = _import_or_interrupted(COMMANDS[program])
        main: Callable[[Sequence[str] | None], int] = module.main
        status = main(argv)
        if _received.is_set() and status != INTERRUPTED_STATUS:  # swallowed after the last check
            return interrupted(program, " after the work was done")
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
