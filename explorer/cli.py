"""``hkpd-explore``: start the explorer web app on a photo (default: the shipped CC0 photo).

Usage::

    hkpd-explore [IMAGE] [--bbox X0 Y0 X1 Y1] [--demo photo|synthetic] [--port 8080]
                 [--host 127.0.0.1] [--no-browser] [--model PATH] [--device auto]
                 [--samples 100] [--meshes 10]

The server binds to 127.0.0.1 unless ``--host`` says otherwise (anyone who can reach the port
can drive the app and upload files, so a warning is printed). A busy ``--port`` is an error;
``--port 0`` takes any free port. Ctrl-C stops it.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import math
import signal
import socket
import sys
import threading
import webbrowser
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hkpd.explorer.demo_photo import shipped_photo
from hkpd.explorer.provider import PosteriorProvider, PredictorProvider
from hkpd.explorer.state import MAX_DISPLAYED_SAMPLES, MAX_SAMPLES
from hkpd.interrupts import interrupted

if TYPE_CHECKING:
    from hkpd.explorer.app import ExplorerApp

LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hkpd-explore",
        description="See how occlusion and concentration shape the predicted 3D body "
        "distribution, in your browser.",
    )
    parser.add_argument(
        "image", nargs="?", help="photo of one person (default: the shipped CC0 photo)"
    )
    parser.add_argument(
        "--demo",
        choices=("photo", "synthetic"),
        default="photo",
        help="without an image: the shipped photo (default) or a scene hkpd renders itself",
    )
    parser.add_argument(
        "--bbox",
        nargs=4,
        type=float,
        metavar=("X0", "Y0", "X1", "Y1"),
        help="look for the person only inside this box (photo pixels): to pick one of several "
        "people, or when none is found",
    )
    parser.add_argument(
        "--port", type=int, default=8080, help="TCP port (default 8080; 0: any free port)"
    )
    parser.add_argument("--host", default="127.0.0.1", help="interface to bind (default local)")
    parser.add_argument("--no-browser", action="store_true", help="do not open a browser tab")
    parser.add_argument("--model", default=None, help="trained model checkpoint (default: shipped)")
    parser.add_argument("--device", default="auto", help="torch device: auto, cpu, cuda, ...")
    parser.add_argument(
        "--samples", type=int, default=100, help=f"samples for the heatmap (2..{MAX_SAMPLES})"
    )
    parser.add_argument(
        "--meshes", type=int, default=10, help=f"sample meshes drawn (0..{MAX_DISPLAYED_SAMPLES})"
    )
    parser.add_argument(
        "--provider",
        default=None,
        metavar="MODULE:CALLABLE",
        help="developer option: build the posterior provider with this callable instead of "
        "loading the trained Predictor (used by the test suite)",
    )
    return parser


def _load_photo(path: str | None, demo: str = "photo") -> np.ndarray:
    if path is None and demo == "synthetic":
        from hkpd.explorer.demo_scene import render_demo_scene

        return render_demo_scene().image
    if path is None:
        try:
            path = str(shipped_photo())
        except FileNotFoundError as error:
            raise SystemExit(
                f"hkpd-explore: {error}; give a photo or use --demo synthetic"
            ) from None
    from hkpd.prediction.image_input import ImageInputError, load_image

    try:
        return np.ascontiguousarray(load_image(path).pixels)
    except ImageInputError as error:
        raise SystemExit(f"hkpd-explore: cannot use {path!r}: {error}") from None


def _refuse_busy_port(host: str, port: int) -> None:
    """Exit with a clear message when ``host:port`` cannot be bound (viser itself would
    silently take the next free port)."""
    try:
        with socket.create_server((host, port)):
            pass
    except OSError as error:
        if error.errno == errno.EADDRINUSE:
            raise SystemExit(_busy_port_message(port)) from None
        raise SystemExit(f"hkpd-explore: cannot listen on {host}:{port} ({error})") from None


def _busy_port_message(port: int) -> str:
    return (
        f"hkpd-explore: port {port} is already in use; choose another with --port N, or "
        "--port 0 for any free port"
    )


def _build_provider(args: argparse.Namespace) -> PosteriorProvider:
    if args.provider is not None:
        module_name, _, attribute = args.provider.partition(":")
        try:
            factory = getattr(importlib.import_module(module_name), attribute)
        except (ImportError, AttributeError, ValueError) as error:
            raise SystemExit(f"hkpd-explore: --provider {args.provider!r}: {error}") from None
        return factory()
    try:
        return PredictorProvider(args.model, device=args.device)
    except Exception as error:
        raise SystemExit(
            f"hkpd-explore: could not load the predictor ({type(error).__name__}: {error}). "
            "Pass a trained checkpoint with --model PATH."
        ) from None


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not 2 <= args.samples <= MAX_SAMPLES:
        raise SystemExit(f"hkpd-explore: --samples must be in 2..{MAX_SAMPLES}, got {args.samples}")
    if not 0 <= args.meshes <= MAX_DISPLAYED_SAMPLES:
        raise SystemExit(
            f"hkpd-explore: --meshes must be in 0..{MAX_DISPLAYED_SAMPLES}, got {args.meshes}"
        )
    if not 0 <= args.port <= 65535:
        raise SystemExit(f"hkpd-explore: --port must be in 0..65535, got {args.port}")
    if args.host not in LOOPBACK_HOSTS:
        print(
            f"warning: binding to {args.host}: anyone who can reach this port can use the "
            "explorer and upload files to this machine",
            file=sys.stderr,
        )
    if args.port != 0:
        _refuse_busy_port(args.host, args.port)
    try:
        image = _load_photo(args.image, args.demo)
    except KeyboardInterrupt:
        return interrupted("hkpd-explore")
    person_box = None
    if args.bbox is not None:
        x0, y0, x1, y1 = args.bbox
        if not (x1 > x0 and y1 > y0) or not all(map(math.isfinite, args.bbox)):
            raise SystemExit("hkpd-explore: --bbox needs x0 y0 x1 y1 with x1 > x0 and y1 > y0")
        person_box = (x0, y0, x1, y1)
    try:
        provider = _build_provider(args)
        from hkpd.explorer.app import ExplorerApp
    except KeyboardInterrupt:
        return interrupted("hkpd-explore")
    # From here Ctrl-C and SIGTERM only set a flag, so a signal that lands anywhere (while the
    # server starts, inside the banner's print) cannot interrupt half-done work; a second
    # Ctrl-C while stopping does.
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    app = ExplorerApp(
        provider,
        image,
        host=args.host,
        port=args.port,
        num_samples=args.samples,
        num_displayed=args.meshes,
        person_box=person_box,
    )
    if stop.is_set():  # Ctrl-C while the server was starting
        app.stop()
        return interrupted("hkpd-explore")
    return _serve(app, args, stop)


def _serve(app: ExplorerApp, args: argparse.Namespace, stop: threading.Event) -> int:
    """Serve until ``stop`` is set (Ctrl-C or SIGTERM, the normal way to stop: status 0)."""
    if args.port not in (0, app.server.get_port()):  # taken between the check and the bind
        app.stop()
        raise SystemExit(_busy_port_message(args.port))
    print(f"hkpd explorer running at {app.url}  (Ctrl-C to stop)", flush=True)
    if not args.no_browser:
        webbrowser.open(app.url)
    while not stop.wait(0.5):
        pass
    signal.signal(signal.SIGINT, signal.default_int_handler)
    print("stopping…", flush=True)
    app.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
