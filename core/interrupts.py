"""Ctrl-C in the command-line programs: at any moment one line, exit status 130, never swallowed.

Three things stand in the way of that in a plain ``main()``:

- **Code that swallows it.** ``import trimesh`` wraps optional imports in
  ``except BaseException``, so a KeyboardInterrupt raised inside one is caught and the program
  runs on as if nothing happened (2 of 13 tries in issue 44; other library code can do the
  same). So the programs start in :func:`run_command` (through :func:`run_program`, their
  console-script entry points are below), which installs a SIGINT handler that *remembers*
  the Ctrl-C before raising it; after each heavy import, and at the commands' safe points
  (before each photo, before a folder is committed, before a report is written),
  :func:`raise_if_interrupted` raises a swallowed one again, and a command that returns
  normally after one still ends in status 130.
- **The imports before** ``main()``: the command's module pulls in torch, OpenCV and trimesh
  before ``main`` runs, so a Ctrl-C there would be a traceback. :func:`run_command` imports the
  command itself and turns a KeyboardInterrupt from anywhere into ``PROGRAM: interrupted`` on
  stderr and status 130.
- **Python's own shutdown.** After ``main()`` returns, Python 3.11 gives SIGINT its default
  action back early in its shutdown, before it tears the modules down (about 0.6 s for
  ``hkpd-predict`` with torch and OpenCV loaded), so a Ctrl-C then killed the process by the
  signal (status -2, no line). The programs' entry points run :func:`run_program`, which keeps
  noting Ctrl-C until its last exit callback and ends the process there with ``os._exit``.

:func:`deferred_interrupts` holds a Ctrl-C back for the few statements that must not be cut in
half (renaming a finished folder into place, removing a partial one, writing a report).

The commands' own ``main`` catch KeyboardInterrupt where they have something to clean up or to
say (which photos are done, the checkpoint written) and return :data:`INTERRUPTED_STATUS`.
This module imports nothing of hkpd; the commands are imported by name.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib
import os
import signal
import sys
import threading
import weakref
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
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


@dataclass
class _ProgramState:
    """What :func:`run_program`'s exit callback needs to end the process."""

    program: str = ""
    finished: bool = False
    """The command has returned (or was stopped): a Ctrl-C from now on is only noted."""
    status: int | None = None
    """The command's exit status; None until it is known."""
    said: bool = False
    """An "interrupted" line was printed (by :func:`interrupted`)."""


_program = _ProgramState()


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if a Ctrl-C arrived since :func:`run_command` started (one that
    some library code caught and dropped); a no-op when the command runs without it."""
    if _received.is_set():
        raise KeyboardInterrupt


IMPORT_MACHINERY = "<frozen importlib"
"""The file name of Python's own import machinery's frames (``<frozen importlib._bootstrap>``)."""


WEAKREF_MODULE = weakref.__file__
"""The standard library's ``weakref.py``: its dictionaries' and ``finalize``'s callbacks run
whenever an object is freed, and an exception raised in them is "unraisable"."""


def _unraisable(frame: FrameType) -> bool:
    """Whether a KeyboardInterrupt raised in ``frame`` would be printed as "Exception ignored
    in ..." with a traceback and dropped: the import machinery's own code (a module lock's
    weakref callback), a weakref callback of the standard library (``WeakKeyDictionary``'s
    ``remove``, seen when hkpd-predict frees its predictor after the last photo), a ``__del__``."""
    code = frame.f_code
    return (
        code.co_filename.startswith(IMPORT_MACHINERY)
        or code.co_filename == WEAKREF_MODULE
        or code.co_name == "__del__"
    )


def _remember_and_raise(signum: int, frame: FrameType | None) -> None:
    """The SIGINT handler of :func:`run_command`: remember the Ctrl-C, and raise it unless it
    landed where the exception would be dropped with a traceback (:func:`_unraisable`), or half
    way through the import machinery, which can leave a module half-registered. There it is
    only remembered: :func:`raise_if_interrupted` raises it at the command's next safe point,
    and a command that returns after one still ends in status 130."""
    _received.set()
    if _program.finished:
        return  # the program is ending: its exit callback says it and sets the status
    if frame is not None and _unraisable(frame):
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
    _program.said = True
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
    that some library swallowed) gives one line and :data:`INTERRUPTED_STATUS`. The SIGINT
    handler is put back as it was when it returns (for callers in Python; a program's entry
    point is :func:`run_program`)."""
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, _remember_and_raise) if main_thread else None
    _received.clear()
    try:
        return _run(program, argv)
    finally:
        _received.clear()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _run(program: str, argv: Sequence[str] | None) -> int:
    """The heavy imports, ``program``'s module and its ``main(argv)``; a KeyboardInterrupt from
    any of them is one line and :data:`INTERRUPTED_STATUS`."""
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


def run_program(program: str, argv: Sequence[str] | None = None) -> int:
    """The entry point of the process ``program``: :func:`run_command`, with a Ctrl-C noted
    until the process is gone, so that one at any moment, Python's shutdown included, ends
    in one line and :data:`INTERRUPTED_STATUS`.

    Registers :func:`_exit_process` as an exit callback: it runs after the non-daemon threads
    are joined and after the callbacks registered later (the libraries' own), flushes the
    standard streams and ends the process with ``os._exit`` and the command's status, or 130
    (and the line, once) when a Ctrl-C came after the command returned. Python's teardown of
    the modules is skipped: it only frees memory, and the commands close their files in
    ``with`` blocks. Only for a process's entry point: called in a Python session, it ends that
    session's interpreter with the command's status. Off the main thread it is
    :func:`run_command`.
    """
    if threading.current_thread() is not threading.main_thread():
        return run_command(program, argv)
    _program.program = program
    atexit.register(_exit_process)
    signal.signal(signal.SIGINT, _remember_and_raise)
    _received.clear()
    try:
        status = _run(program, argv)
    except KeyboardInterrupt:  # landed as main() returned; said at exit
        status = INTERRUPTED_STATUS
    except SystemExit as exiting:  # argparse's --help and usage errors
        _program.finished = True
        _program.status = _exit_code(exiting.code)
        raise
    finally:
        _program.finished = True
    _program.status = status
    return status


def _exit_code(code: object) -> int:
    """The exit status Python gives ``SystemExit(code)``: 0 for None, the int, else 1 (the
    message is printed by Python)."""
    if code is None:
        return 0
    return code if isinstance(code, int) else 1


def _exit_process() -> None:
    """:func:`run_program`'s exit callback: flush, say a Ctrl-C that came after the command
    returned, and end the process with its status (130 after a Ctrl-C). Does nothing when
    the command's status is unknown (an exception escaped: Python reports it as usual)."""
    status = _program.status
    if status is None:
        return
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError, AttributeError):  # closed, broken, None
            stream.flush()
    if _received.is_set():  # checked last: a Ctrl-C after this is one after the end
        if not _program.said:
            interrupted(_program.program, " after the work was done")
        status = INTERRUPTED_STATUS
    os._exit(status)


def predict() -> int:
    """The ``hkpd-predict`` entry point."""
    return run_program("hkpd-predict")


def evaluate() -> int:
    """The ``hkpd-eval`` entry point."""
    return run_program("hkpd-eval")


def train() -> int:
    """The ``hkpd-train`` entry point."""
    return run_program("hkpd-train")


def explore() -> int:
    """The ``hkpd-explore`` entry point."""
    return run_program("hkpd-explore")
