"""``hkpd-explore``: start the explorer web app on a photo (default: the shipped CC0 photo).

Usage::

    hkpd-explore [IMAGE] [--bbox X0 Y0 X1 Y1] [--occluder X0 Y0 X1 Y1]... [--demo photo|synthetic]
                 [--port 8080] [--host 127.0.0.1] [--no-browser] [--model PATH] [--device auto]
                 [--samples 100] [--meshes 10] [--export-html OUT.html [--force]]
                 [--sex {female,male}] [--height M [STD]] [--mass KG [STD]] ...

The server binds to 127.0.0.1 unless ``--host`` says otherwise (anyone who can reach the port
can drive the app and upload files, so a warning is printed). A busy ``--port`` is an error;
``--port 0`` takes any free port. Ctrl-C stops it.

With ``--export-html OUT.html`` no server is started for anyone: the first view (with the
``--occluder`` boxes hidden) is written to one self-contained page and the command exits; an
existing OUT.html is kept unless ``--force``.

``--sex`` and the measurement flags (``--height``, ``--mass``, ``--chest``, ``--waist``,
``--hip``, ``--shoulder-width``, each ``VALUE [STD]``) are hkpd-predict's
(:mod:`hkpd.body_flags`): they state what is known of the first photo's person, as
the Body section does, and are checked before the model loads.

Start-up order: the heavy modules (torch, the model) are imported only once the arguments and
the photo's path are checked; the model, then the app (see docs/benchmarks.md, "Explorer
start-up").
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
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hkpd.explorer.demo_photo import shipped_photo
from hkpd.explorer.state import MAX_DISPLAYED_SAMPLES, MAX_SAMPLES
from hkpd.interrupts import interrupted, raise_if_interrupted

if TYPE_CHECKING:
    from hkpd.explorer.app import ExplorerApp
    from hkpd.explorer.body_settings import BodyStatement
    from hkpd.explorer.provider import PosteriorProvider
    from hkpd.explorer.scene_file import SceneFile

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
        "--occluder",
        nargs=4,
        type=float,
        action="append",
        default=[],
        metavar=("X0", "Y0", "X1", "Y1"),
        help="hide this box of the photo (photo pixels) from the start; repeat for more boxes",
    )
    parser.add_argument(
        "--silhouette-evidence",
        action="store_true",
        help="start with 'Fit the person mask' on: the body's outline is fitted to BlazePose's "
        "person mask as well as to the keypoints (best for one person in close-fitting clothes)",
    )
    parser.add_argument(
        "--export-html",
        metavar="OUT.html",
        default=None,
        help="write the first view as one self-contained HTML page (no server) and exit",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="with --export-html or --save-scene: replace an existing file",
    )
    _add_scene_arguments(parser)
    from hkpd.body_flags import add_body_arguments

    add_body_arguments(parser)
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


def _add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    """The scene options: keep and reopen a scene, compare, and the settings a scene holds."""
    parser.add_argument(
        "--save-scene", metavar="FILE.json", default=None,
        help="write the scene (photo by path and checksum, boxes, settings) to FILE.json and "
        "exit without serving; reopen it with --scene",
    )  # fmt: skip
    parser.add_argument(
        "--embed-photo", action="store_true",
        help="with --save-scene: put the photo itself into the scene file (base64)",
    )  # fmt: skip
    parser.add_argument(
        "--scene", metavar="FILE", default=None,
        help="open a scene saved with --save-scene or the panel (or a page exported by hkpd)",
    )  # fmt: skip
    parser.add_argument(
        "--compare", metavar="SETTING", default=None,
        help="a second set of columns for SETTING: network, no-occluders, "
        "default-concentrations, or a model checkpoint's path",
    )  # fmt: skip
    parser.add_argument(
        "--colouring", choices=("log", "linear", "change"), default="log",
        help="how the uncertainty body is coloured (default log)",
    )  # fmt: skip
    parser.add_argument(
        "--concentration", nargs=2, action="append", default=[], metavar=("JOINT", "FACTOR"),
        help="scale one joint's concentration (e.g. left_elbow 0.1); repeat for more joints",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="seed of the sample draw (>= 0)")
    parser.add_argument(
        "--no-evidence", action="store_true",
        help="show the network alone (no conditioning on the 2D keypoints)",
    )  # fmt: skip
    parser.add_argument(
        "--turn-around", action="store_true",
        help="show the turned-around reading: the same keypoints fitted by a body facing the "
        "other way (for a person seen from behind; Photo › Facing)",
    )  # fmt: skip


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
    from hkpd.explorer.provider import PredictorProvider

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


def _box_argument(option: str, box: Sequence[float]) -> tuple[float, float, float, float]:
    x0, y0, x1, y1 = box
    if not (x1 > x0 and y1 > y0) or not all(map(math.isfinite, box)):
        raise SystemExit(f"hkpd-explore: {option} needs x0 y0 x1 y1 with x1 > x0 and y1 > y0")
    return (x0, y0, x1, y1)


def _photo_name(args: argparse.Namespace) -> str:
    if args.image is not None:
        return Path(args.image).name
    return "the synthetic demo scene" if args.demo == "synthetic" else "the shipped CC0 photo"


def _model_name(args: argparse.Namespace) -> str:
    if args.provider is not None:
        return f"provider {args.provider}"
    return Path(args.model).name if args.model else "the shipped model"


def _stated_body(args: argparse.Namespace) -> BodyStatement:
    """What ``--sex`` and the measurement flags state, checked before the model loads (a
    usage error names the flag; ``--turn-around`` is checked here too: it needs the
    keypoint evidence, as a stated body does)."""
    from hkpd.body_flags import stated_body
    from hkpd.explorer.body_settings import BodyStatement

    try:
        stated = BodyStatement.from_stated(stated_body(args))
    except ValueError as error:
        raise SystemExit(f"hkpd-explore: {error}") from None
    if args.turn_around and args.no_evidence:
        raise SystemExit("hkpd-explore: --turn-around refits the keypoints: drop --no-evidence")
    if not stated.empty and args.no_evidence:
        raise SystemExit(
            "hkpd-explore: --sex and the measurement flags condition the shape, which needs "
            "the keypoint evidence: drop --no-evidence"
        )
    return stated


def _load_provider_and_app(args: argparse.Namespace) -> tuple[PosteriorProvider, type[ExplorerApp]]:
    """The provider (the model), then the app class. Loading the model in a thread while the
    app's modules import was measured slower (its first prediction then cost ~4 CPU seconds
    more), so they load one after the other."""
    provider = _build_provider(args)
    from hkpd.explorer.app import ExplorerApp

    return provider, ExplorerApp


def _scene_and_photo(
    args: argparse.Namespace,
    person_box: tuple[float, float, float, float] | None,
    occluders: list[tuple[float, float, float, float]],
    photo: bool = True,
) -> tuple[SceneFile, np.ndarray | None, str]:
    """The scene to show (``--scene FILE``, or the command line's settings), its photo
    ``(H, W, 3)`` uint8 RGB (not read unless ``photo``) and the scene file's name ("" without
    one). ``--scene`` sets ``args.model`` to the scene's model unless ``--model`` is given;
    ``--save-scene`` writes the scene too."""
    from hkpd.explorer.cli_scene import open_scene_file, save_scene_file, scene_from_arguments

    image: np.ndarray | None = None
    if args.scene is None:
        scene = scene_from_arguments(args, _photo_name(args), person_box, occluders)
        image, source = (_load_photo(args.image, args.demo) if photo else None), ""
    else:
        scene, image = open_scene_file(args.scene)
        if image is None and photo:
            image = _load_photo(None, "synthetic")
        source = Path(args.scene).name
        if args.model is None:
            args.model = scene.model
    if args.save_scene is not None:
        save_scene_file(scene, args.save_scene, args.force)
    return scene, image, source


def _export_page(
    args: argparse.Namespace,
    person_box: tuple[float, float, float, float] | None,
    occluders: list[tuple[float, float, float, float]],
    stated: BodyStatement,
) -> int:
    """``--export-html``: write the first view as one page and exit (no server for users);
    ``stated``: what the body flags state (the caption says it)."""
    target = Path(args.export_html)
    if target.exists() and not args.force:
        raise SystemExit(
            f"hkpd-explore: {target} exists: choose another name, or pass --force to replace it"
        )
    if not target.parent.is_dir():
        raise SystemExit(f"hkpd-explore: folder {target.parent} does not exist: create it first")
    scene, image, source = _scene_and_photo(args, person_box, occluders)
    assert image is not None
    if stated.empty:  # a --scene's stated body, unless the flags state one
        from hkpd.explorer.body_settings import BodyStatement

        stated = BodyStatement.from_stated(scene.stated())
    provider = _build_provider(args)

    from hkpd.explorer.html_page import PageExistsError
    from hkpd.explorer.saved_scene import render_scene_page

    try:
        page = render_scene_page(
            provider, image, photo_name=scene.photo.name, model_name=_model_name(args),
            scene=scene, scene_source=source, stated=stated,
        )  # fmt: skip
        written = page.save(target, force=args.force)
    except (ValueError, RuntimeError, OSError) as error:
        if isinstance(error, PageExistsError):
            raise SystemExit(f"hkpd-explore: {error}") from None
        raise SystemExit(f"hkpd-explore: no page written: {error}") from None
    print(f"wrote {written} ({written.stat().st_size / 1e6:.1f} MB): {page.caption}")
    return 0


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
    person_box = _box_argument("--bbox", args.bbox) if args.bbox is not None else None
    occluders = [_box_argument("--occluder", box) for box in args.occluder]
    if args.scene is not None and (args.image is not None or args.occluder or args.bbox):
        raise SystemExit("hkpd-explore: give either a photo and its options or --scene FILE")
    stated = _stated_body(args)
    if args.save_scene is not None and args.export_html is None:  # a scene, no server
        _scene_and_photo(args, person_box, occluders, photo=False)
        return 0
    if args.export_html is not None:
        try:
            return _export_page(args, person_box, occluders, stated)
        except KeyboardInterrupt:
            return interrupted("hkpd-explore")
    if args.port != 0:
        _refuse_busy_port(args.host, args.port)
    try:
        scene, image, source = _scene_and_photo(args, person_box, occluders)
        assert image is not None
        provider, app_class = _load_provider_and_app(args)
        raise_if_interrupted()  # one noted inside the import machinery (hkpd.interrupts)
    except KeyboardInterrupt:
        return interrupted("hkpd-explore")
    # From here Ctrl-C and SIGTERM only set a flag, so a signal that lands anywhere (while the
    # server starts, inside the banner's print) cannot interrupt half-done work; a second
    # Ctrl-C while stopping does.
    stop, by_ctrl_c = threading.Event(), threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: (by_ctrl_c.set(), stop.set()))
    try:
        app = app_class(
            provider,
            image,
            host=args.host,
            port=args.port,
            num_samples=scene.display.num_samples,
            num_displayed=scene.display.num_displayed,
            person_box=scene.person_box,
            occluders=scene.active_boxes,
            evidence=scene.evidence,
            silhouette=scene.person_mask,
            photo_name=scene.photo.name,
            model_name=_model_name(args),
            stated=stated,
        )
        app.keeper.photo, app.keeper.model, app.keeper.source = scene.photo, scene.model, source
        app.keeper.apply(scene)
    except ValueError as error:
        raise SystemExit(f"hkpd-explore: {error}") from None
    if stop.is_set():  # Ctrl-C while the server was starting
        app.stop()
        return interrupted("hkpd-explore")
    status = _serve(app, args, stop)
    return interrupted("hkpd-explore", "; stopped") if by_ctrl_c.is_set() else status


def _serve(app: ExplorerApp, args: argparse.Namespace, stop: threading.Event) -> int:
    """Serve until ``stop`` is set (Ctrl-C or SIGTERM, the normal ways to stop; ``main`` then
    returns 130 after Ctrl-C, as for an interrupt at any other moment, and 0 after SIGTERM)."""
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
