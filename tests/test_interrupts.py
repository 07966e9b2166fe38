"""Ctrl-C: never swallowed by imports that catch BaseException, and hkpd-predict stopped at a few
moments (during the imports, once the model is loaded, between photos) with one line, status
130 and no partial output. The shipped model and the shipped CC0 photo; no shared data."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import weakref
from collections.abc import Iterator
from pathlib import Path

import pytest

from hkpd import interrupts
from hkpd.interrupts import INTERRUPTED_STATUS, deferred_interrupts

LAUNCH = (
    "import sys; from hkpd.interrupts import run_program; "
    "sys.exit(run_program(sys.argv[1], sys.argv[2:]))"
)
"""What the installed ``hkpd-predict`` (``hkpd.interrupts:predict``) runs, with the program
name as the first argument."""


def default_sigint() -> None:
    """Popen's ``preexec_fn``: the child starts with SIGINT's default action, as a program
    started from a terminal does, whatever this process has (pytest started with SIGINT
    ignored, by ``nohup ... &`` or a script's ``&``, passes the ignoring on to its children)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture(autouse=True)
def python_sigint_handler() -> Iterator[None]:
    """Python's own SIGINT handler during each test (pytest started with SIGINT ignored has
    none), and pytest's own again afterwards."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def swallowing_import() -> None:
    """What trimesh's imports do: ``except BaseException`` around something slow."""
    try:  # noqa: SIM105 (written out as trimesh writes it)
        time.sleep(0.5)
    except BaseException:
        pass


def test_a_sigint_inside_a_swallowing_import_is_raised_after_it() -> None:
    with pytest.raises(KeyboardInterrupt), deferred_interrupts():
        signal.setitimer(signal.ITIMER_REAL, 0.1)
        previous = signal.signal(signal.SIGALRM, lambda *_: os.kill(os.getpid(), signal.SIGINT))
        try:
            swallowing_import()
        finally:
            signal.signal(signal.SIGALRM, previous)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_without_one_the_block_leaves_the_handler_as_it_was() -> None:
    with deferred_interrupts():
        pass
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def main(argv: list[str] | None) -> int:
    """A command whose library swallows the Ctrl-C (for run_command), then finishes."""
    signal.setitimer(signal.ITIMER_REAL, 0.05)
    previous = signal.signal(signal.SIGALRM, lambda *_: os.kill(os.getpid(), signal.SIGINT))
    try:
        swallowing_import()
    finally:
        signal.signal(signal.SIGALRM, previous)
    return 0


def test_a_ctrl_c_swallowed_by_the_command_still_ends_in_130(monkeypatch, capsys) -> None:
    monkeypatch.setitem(interrupts.COMMANDS, "hkpd-swallow", __name__)
    assert interrupts.run_command("hkpd-swallow", []) == INTERRUPTED_STATUS
    assert capsys.readouterr().err == "hkpd-swallow: interrupted after the work was done\n"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    interrupts.raise_if_interrupted()  # forgotten once the command has returned


def test_an_import_broken_by_a_swallowed_ctrl_c_ends_in_130(monkeypatch, tmp_path, capsys):
    """numpy interrupted half-way through its import, caught by torch's importer, fails the next
    time with "cannot load module more than once per process": found by the [import] case
    below at load 2 (exit 1 with a traceback). Such an error after a Ctrl-C is the Ctrl-C."""
    (tmp_path / "hkpd_test_broken_import.py").write_text(
        "import os, signal\n"
        "try:\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "except KeyboardInterrupt:\n"
        "    pass\n"
        "raise ImportError('cannot load module more than once per process')\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(interrupts, "HEAVY_IMPORTS", ("hkpd_test_broken_import",))
    assert interrupts.run_command("hkpd-predict", []) == INTERRUPTED_STATUS
    assert capsys.readouterr().err == "hkpd-predict: interrupted\n"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_ctrl_c_inside_the_import_machinery_is_noted_and_raised_after_the_import() -> None:
    """A SIGINT landing in importlib's own frames (a module lock's weakref callback, where an
    exception is printed as "Exception ignored in ..." and dropped: seen in the [hkpd-explore]
    case below) is only noted there, and raised at the next check."""
    from types import SimpleNamespace

    machinery = SimpleNamespace(
        f_code=SimpleNamespace(co_filename="<frozen importlib._bootstrap>", co_name="_get")
    )
    user_code = SimpleNamespace(f_code=SimpleNamespace(co_filename=__file__, co_name="main"))
    interrupts._received.clear()
    try:
        interrupts._remember_and_raise(signal.SIGINT, machinery)  # no raise here
        with pytest.raises(KeyboardInterrupt):
            interrupts.raise_if_interrupted()  # but at the next check
        with pytest.raises(KeyboardInterrupt):
            interrupts._remember_and_raise(signal.SIGINT, user_code)
    finally:
        interrupts._received.clear()


@pytest.mark.parametrize(
    "filename, name",
    [(weakref.__file__, "remove"), (__file__, "__del__")],
    ids=["weakref-callback", "__del__"],
)
def test_a_ctrl_c_where_it_would_be_dropped_is_noted_and_raised_later(filename, name) -> None:
    """A KeyboardInterrupt raised in a weakref callback or a ``__del__`` is printed as
    "Exception ignored in ..." with a traceback and dropped (seen 2 times in 20 Ctrl-Cs just
    after hkpd-predict's last photo, in WeakKeyDictionary's ``remove``): only noted there."""
    from types import SimpleNamespace

    frame = SimpleNamespace(f_code=SimpleNamespace(co_filename=filename, co_name=name))
    interrupts._received.clear()
    try:
        interrupts._remember_and_raise(signal.SIGINT, frame)  # no raise here
        with pytest.raises(KeyboardInterrupt):
            interrupts.raise_if_interrupted()
    finally:
        interrupts._received.clear()


def test_an_import_error_without_a_ctrl_c_is_not_hidden(monkeypatch, tmp_path) -> None:
    (tmp_path / "hkpd_test_failing_import.py").write_text("raise ImportError('no such thing')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(interrupts, "HEAVY_IMPORTS", ("hkpd_test_failing_import",))
    with pytest.raises(ImportError, match="no such thing"):
        interrupts.run_command("hkpd-predict", [])


@pytest.fixture(scope="module")
def photos(tmp_path_factory) -> Path:
    from hkpd.explorer.demo_photo import shipped_photo

    folder = tmp_path_factory.mktemp("photos")
    for index in range(4):
        shutil.copy(shipped_photo(), folder / f"photo_{index}.jpg")
    return folder


def interrupt_predict(photos: Path, out: Path, when: str) -> subprocess.CompletedProcess:
    """Run hkpd-predict on ``photos`` and send one SIGINT ``when``: "import" (0.3 s after the
    start), "loaded" (the progress bar appears: the model is loaded, the first photo under
    way), "between" (the first photo is reported)."""
    command = [sys.executable, "-c", LAUNCH, "hkpd-predict", str(photos), "--out", str(out),
               "--samples", "1", "--uncertainty-samples", "10"]  # fmt: skip
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=default_sigint
    )
    seen = b""  # what was read while waiting (kept in the result for the failure messages)
    try:
        if when == "import":
            time.sleep(0.3)
        else:
            stream = process.stderr if when == "loaded" else process.stdout
            wanted = b"hkpd-predict:" if when == "loaded" else b"person at bbox"
            while wanted not in seen and process.poll() is None:
                seen += os.read(stream.fileno(), 256)
        process.send_signal(signal.SIGINT)
        out_bytes, err_bytes = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    if when == "loaded":
        err_bytes = seen + err_bytes
    elif when == "between":
        out_bytes = seen + out_bytes
    return subprocess.CompletedProcess(command, process.returncode, out_bytes, err_bytes)


@pytest.mark.parametrize("when", ["import", "loaded", "between"])
def test_ctrl_c_stops_hkpd_predict_with_one_line_and_no_partial_output(photos, tmp_path, when):
    out = tmp_path / "out"
    result = interrupt_predict(photos, out, when)
    stderr = result.stderr.decode(errors="replace")
    assert result.returncode == INTERRUPTED_STATUS, stderr
    assert "Traceback" not in stderr
    lines = [line for line in stderr.replace("\r", "\n").splitlines() if "interrupted" in line]
    assert len(lines) == 1 and lines[0].startswith("hkpd-predict: interrupted"), stderr
    assert stderr.rstrip().endswith(lines[0])
    left = sorted(path.name for path in out.iterdir()) if out.exists() else []
    assert not any(name.startswith(".") for name in left)  # no .photo_N.partial folder
    folders = [name for name in left if name != "index.jsonl"]
    for name in folders:  # every folder there is a finished one
        assert (out / name / "summary.json").is_file() and (out / name / "overview.png").is_file()
    if when == "between":
        assert folders  # the reported photo stays, and is in the index
        indexed = [json.loads(line) for line in (out / "index.jsonl").read_text().splitlines()]
        assert {record["folder"] for record in indexed if record["status"] == "ok"} >= set(folders)
    if when == "import":
        assert not out.exists()


@pytest.mark.parametrize(
    "program, arguments",
    [
        ("hkpd-eval", ["missing.pt", "--count", "1"]),
        ("hkpd-train", ["--steps", "1"]),
        ("hkpd-explore", ["--no-browser", "--port", "0", "--demo", "synthetic"]),
    ],
)
def test_ctrl_c_while_the_other_programs_start_is_one_line_and_130(tmp_path, program, arguments):
    if program == "hkpd-train":
        arguments = [*arguments, "--out", str(tmp_path / "run")]
    process = subprocess.Popen(
        [sys.executable, "-c", LAUNCH, program, *arguments],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path, preexec_fn=default_sigint,
    )  # fmt: skip
    try:
        time.sleep(0.5)  # in the imports (torch alone takes longer)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    stderr = err.decode(errors="replace")
    assert process.returncode == INTERRUPTED_STATUS, stderr
    assert stderr.strip() == f"{program}: interrupted" and "Traceback" not in stderr
    assert list(tmp_path.iterdir()) == []


LATE_COMMAND = """
import sys, threading, time

def main(argv):
    behaviour = argv[0]
    print("work done")  # not flushed: the exit must flush it
    if behaviour == "late":  # Python's shutdown waits for this thread; SIGINT meanwhile
        threading.Thread(target=time.sleep, args=(1.0,)).start()
        print("ready", file=sys.stderr, flush=True)
    if behaviour == "usage":
        raise SystemExit(2)
    return 3 if behaviour == "three" else 0
"""
"""A command for :func:`run_program` that returns at once (and, for ``late``, leaves Python's
shutdown a non-daemon thread to wait for)."""


def run_late_command(tmp_path: Path, behaviour: str) -> subprocess.CompletedProcess:
    """Run :data:`LATE_COMMAND` as the program ``hkpd-late`` through :func:`run_program` (no
    heavy imports); for ``late``, send one SIGINT once its ``main`` has returned."""
    (tmp_path / "hkpd_late_command.py").write_text(LATE_COMMAND)
    launch = (
        "import sys; from hkpd import interrupts; interrupts.HEAVY_IMPORTS = (); "
        "interrupts.COMMANDS['hkpd-late'] = 'hkpd_late_command'; "
        "sys.exit(interrupts.run_program('hkpd-late', sys.argv[1:]))"
    )
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    process = subprocess.Popen(
        [sys.executable, "-c", launch, behaviour], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        env=env, preexec_fn=default_sigint,
    )  # fmt: skip
    try:
        if behaviour == "late":
            seen = b""
            while b"ready" not in seen and process.poll() is None:
                seen += os.read(process.stderr.fileno(), 256)
            time.sleep(0.2)  # main() has returned: Python's shutdown joins the thread
            process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    err = (seen if behaviour == "late" else b"") + err
    return subprocess.CompletedProcess(launch, process.returncode, out, err)


def test_a_ctrl_c_during_pythons_shutdown_is_one_line_and_130(tmp_path) -> None:
    """Python 3.11 gives SIGINT its default action back early in its shutdown: a Ctrl-C in
    hkpd-predict's last ~0.6 s (all photos done) ended the process by the signal (status -2, no
    line). run_program notes it until the process ends."""
    result = run_late_command(tmp_path, "late")
    assert result.returncode == INTERRUPTED_STATUS, result.stderr
    assert result.stderr.decode() == "ready\nhkpd-late: interrupted after the work was done\n"
    assert result.stdout.decode() == "work done\n"


@pytest.mark.parametrize("behaviour, status", [("three", 3), ("usage", 2), ("zero", 0)])
def test_run_program_ends_with_the_commands_status(tmp_path, behaviour, status) -> None:
    result = run_late_command(tmp_path, behaviour)
    assert result.returncode == status, result.stderr
    assert result.stdout.decode() == "work done\n" and result.stderr == b""
