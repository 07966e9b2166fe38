"""Benchmark the explorer's server side: what a user waits for after moving a control.

Runs the app in-process on the demo photo with the test double of the predictor
(``tests/test_explorer_double.py``: a hand-built posterior, the real body model, sampler,
heatmap and viser scene; only the network is missing), on the real 13,492-vertex mesh, and
connects a plain websocket client so that "sent" means *delivered to a client on localhost*:
the time from the change to the last websocket frame of the update (frames followed by
150 ms of quiet).

Tables (markdown, for docs/explorer.md):

1. concentration slider change -> 100 new samples + heatmap + 10 meshes delivered;
2. occluder change -> new prediction displayed (each edit isolated, so it starts at once: the
   120 ms debounce holds only edits that follow one closely, issue 58);
3. a burst of 40 slider events in 0.4 s: sampling jobs actually run (coalescing);
4. heatmap transport: coloured point cloud vs per-vertex-coloured GLB (bytes, encode time).

With ``--real`` it runs the shipped ``Predictor`` (BlazePose, network, keypoint-evidence fit)
on the shipped CC0 photo instead, with the occluder over the person's right shin, and
``--uploads N`` then uploads N photos (the shipped one at other sizes) and reports the server's
resident memory after each batch of uploads; then hostile uploads, all at once from four threads
(as four browser tabs would): a 30000x30000 PNG bomb and three 13300x13300 PNGs (solid colour,
valid files of a few hundred KB, written to a temporary folder at run time), with the peak
resident memory sampled every 5 ms and the message each upload got.

With ``--startup N`` it measures start-up instead, N times: the time from starting the
``hkpd-explore`` command (the shipped model, ``--no-browser``) to the server holding the photo,
and to it holding the first complete view (photo, mode body, heatmap). A plain websocket client
polls the port from the moment the process starts; the server sends a new client every scene
node it holds, so the client sees a node as soon as the server has it (no browser involved).

With ``--paired SETTING`` it runs two apps in one process on the same provider, one plain and
one comparing against SETTING, and alternates every slider move and occluder edit between them,
so that both see the same load (the shared VM's load moves by a factor of two within minutes);
it prints both medians and their ratio, and the CPU time the process used per move (all
threads, the websocket client's included), which the load disturbs far less than wall time.

Usage: python benchmarks/bench_explorer.py [--threads 2] [--repeats 15] [--real] [--uploads 20]
       python benchmarks/bench_explorer.py --startup 5 [--photo PATH]
       python benchmarks/bench_explorer.py --real --paired network [--repeats 15]
"""

from __future__ import annotations

import argparse
import asyncio
import io
import os
import platform
import signal
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
import zlib
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
import trimesh
import viser
import websockets
import zstandard
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.colour_map import uncertainty_colours
from hkpd.explorer.compare import parse_compare
from hkpd.explorer.demo_photo import shipped_photo
from hkpd.explorer.provider import PredictorProvider
from hkpd.prediction.image_input import load_image

QUIET_S = 0.15
SETTLE_S = 0.4
"""``--paired``: pause before each move, so that one app's tail (frames still being compressed
and sent) does not fall into the other app's measurement."""
STARTUP_NODES = {"photo": "/photo", "mode": "/body/mode", "heatmap": "/heat/points"}
"""Scene nodes of the first complete view, by what they show."""


class FrameRecorder:
    """A websocket client in its own thread that timestamps every frame it receives."""

    def __init__(self, url: str) -> None:
        self.frames: list[tuple[float, int]] = []
        self._lock = threading.Lock()
        self._url = url.replace("http://", "ws://")
        self._ready = threading.Event()
        threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True).start()
        if not self._ready.wait(10):
            raise RuntimeError("websocket client did not connect")

    async def _run(self) -> None:
        protocol = f"viser-v{viser.__version__}"
        async with websockets.connect(self._url, subprotocols=[protocol], max_size=None) as ws:
            self._ready.set()
            async for message in ws:
                with self._lock:
                    self.frames.append((time.perf_counter(), len(message)))

    def delivered_after(
        self, start: float, drawn: float, timeout: float = 10.0
    ) -> tuple[float, int]:
        """(seconds from ``start`` to the last frame, bytes received since ``start``).

        The last frame is the last one before a quiet gap that arrived after ``drawn`` (when the
        worker began pushing the final update), so early frames (the occluder's box is drawn
        at once, the prediction only after the debounce) do not end the measurement.
        """
        deadline = time.perf_counter() + timeout
        while time.perf_counter() < deadline:
            time.sleep(0.02)
            with self._lock:
                after = [f for f in self.frames if f[0] >= start]
            if after and after[-1][0] >= drawn and time.perf_counter() - after[-1][0] > QUIET_S:
                return after[-1][0] - start, sum(size for _, size in after)
        raise TimeoutError("no update reached the client")


def median_ms(values: list[float]) -> str:
    return f"{statistics.median(values) * 1000:.0f}"


def best_ms(values: list[float]) -> str:
    return f"{min(values) * 1000:.0f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--real", action="store_true", help="the shipped model on its photo")
    parser.add_argument("--uploads", type=int, default=0, help="then upload this many photos")
    parser.add_argument("--startup", type=int, default=0, help="measure start-up this many times")
    parser.add_argument("--photo", default=None, help="photo for --startup (default: shipped)")
    parser.add_argument(
        "--compare", default=None, metavar="SETTING",
        help="with the compare columns on (network, no-occluders, default-concentrations, or a "
        "checkpoint path)",
    )  # fmt: skip
    parser.add_argument(
        "--paired", default=None, metavar="SETTING",
        help="plain and compare SETTING alternated in one process (see the module docstring)",
    )  # fmt: skip
    args = parser.parse_args()
    if args.paired is not None:
        report_paired(args.paired, args.repeats, args.threads, args.real)
        return
    if args.startup:
        report_startup(args.startup, args.photo, args.threads)
        return
    torch.set_num_threads(args.threads)
    if args.real:
        provider, image = PredictorProvider(device="cpu"), load_image(shipped_photo()).pixels
    else:
        provider = OcclusionAwareDouble()
        image = provider.scene.image
    memory_before = resident_megabytes()
    app = ExplorerApp(provider, image, port=0, num_samples=100, num_displayed=10)
    recorder = FrameRecorder(app.url)
    app.wait_idle(120)
    if args.compare is not None:
        app.set_compare(parse_compare(args.compare))
        app.wait_idle(120)
    time.sleep(0.5)
    load = os.getloadavg()[0]
    box = shin_box(app) if args.real else (250, 210, 300, 260)

    # 1. Concentration slider.
    delivered, computed, sampling, drawing, sizes = [], [], [], [], []
    for i in range(args.repeats + 2):
        start = time.perf_counter()
        app.sampling_changed(app.state.set_joint_exponent("left_elbow", -0.05 * (i % 10 + 1)))
        app.wait_idle(30)
        done = time.perf_counter() - start
        pushed = start + done - app.timings.draw - app.timings.compare  # A's push began
        seconds, size = recorder.delivered_after(start, pushed)
        if i >= 2:  # warm-up
            delivered.append(seconds)
            computed.append(done)
            sampling.append(app.timings.sample)
            drawing.append(app.timings.draw)
            sizes.append(size)

    # 2. Occluder change.
    occluder = app.state.add_occluder(box)
    app.occluders_changed(True)
    app.wait_idle(30)
    time.sleep(0.3)
    occ_delivered, occ_predict, occ_cpu = [], [], []
    for i in range(max(args.repeats // 2, 5)):
        start, cpu = time.perf_counter(), time.process_time()
        x0, y0, x1, y1 = box
        moved = (x0 - 1 - i, y0, x1, y1 + 1 + i)
        app.occluders_changed(app.state.move_occluder(occluder.ident, moved))
        app.wait_idle(30)
        idle = time.perf_counter()
        occ_cpu.append(time.process_time() - cpu)
        seconds, _ = recorder.delivered_after(start, idle - app.timings.draw - app.timings.compare)
        occ_delivered.append(seconds)
        occ_predict.append(app.timings.predict)

    # 3. Burst of slider events.
    runs_before = app.worker.stats["sample"].run
    start = time.perf_counter()
    for i in range(40):
        app.sampling_changed(app.state.set_global_exponent(-0.5 + 0.025 * i))
        time.sleep(0.01)
    last_event = time.perf_counter()
    app.wait_idle(30)
    idle = time.perf_counter()
    burst_runs = app.worker.stats["sample"].run - runs_before
    pushed = idle - app.timings.draw - app.timings.compare
    burst_tail, _ = recorder.delivered_after(last_event, pushed)

    # 4. Heatmap transport.
    view = app.view
    faces = app.result.posterior.body.faces.numpy()
    colours = uncertainty_colours(view.uncertainty)
    encode_cloud, encode_glb = [], []
    for _ in range(5):
        t = time.perf_counter()
        cloud_bytes = len(view.mode_vertices.astype(np.float16).tobytes()) + colours.nbytes
        encode_cloud.append(time.perf_counter() - t)
        t = time.perf_counter()
        rgba = np.concatenate([colours, np.full((len(colours), 1), 255, np.uint8)], axis=1)
        mesh = trimesh.Trimesh(view.mode_vertices, faces, vertex_colors=rgba, process=False)
        glb_bytes = len(mesh.export(file_type="glb"))
        encode_glb.append(time.perf_counter() - t)

    # 5. Server memory over uploads.
    memory = [(0, resident_megabytes())]
    for index in range(args.uploads):
        scale = 0.6 + 0.4 * (index % 5) / 4
        app.load_upload(f"photo_{index}.jpg", jpeg_bytes(image, scale), None)
        app.wait_idle(120)
        if (index + 1) % 5 == 0 or index + 1 == args.uploads:
            memory.append((index + 1, resident_megabytes()))
    hostile = hostile_uploads(app) if args.uploads else None
    app.stop()

    model = "shipped Predictor on the shipped photo" if args.real else "test double"
    if args.compare is not None:
        model += f", compare {args.compare}"
    print(f"# hkpd explorer benchmark ({model}) — {time.strftime('%Y-%m-%d %H:%M %Z')}")
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"torch threads {args.threads}, load average {load:.1f} (shared machine)"
    )
    print()
    print("| action | median ms | best ms | target ms |")
    print("|---|---:|---:|---:|")
    print(
        f"| slider: adjust + sample 100 + heatmap (worker) | {median_ms(sampling)} | "
        f"{best_ms(sampling)} | |"
    )
    print(
        f"| slider: push 10 meshes + heatmap + axes to viser | {median_ms(drawing)} | "
        f"{best_ms(drawing)} | |"
    )
    print(f"| slider: change -> worker idle | {median_ms(computed)} | {best_ms(computed)} | |")
    print(
        f"| **slider: change -> delivered to a websocket client** | {median_ms(delivered)} | "
        f"{best_ms(delivered)} | 100 |"
    )
    print(
        f"| occluder: prediction ({model}) | {median_ms(occ_predict)} | {best_ms(occ_predict)} | |"
    )
    print(
        f"| occluder: CPU of the edit, all threads (change -> worker idle) | "
        f"{median_ms(occ_cpu)} | {best_ms(occ_cpu)} | |"
    )
    print(
        f"| **occluder: change -> delivered (isolated edits)** | "
        f"{median_ms(occ_delivered)} | {best_ms(occ_delivered)} | {1000 if args.real else 500} |"
    )
    print()
    print(
        f"slider update size: {statistics.median(sizes) / 1e6:.2f} MB per update (10 meshes + "
        "heatmap + axes + reprojection)"
    )
    print(
        f"burst: 40 slider events in {last_event - start:.2f} s ran {burst_runs} sampling jobs; "
        f"last event -> delivered {burst_tail * 1000:.0f} ms"
    )
    print(
        f"heatmap as point cloud: {cloud_bytes / 1e3:.0f} kB, encode "
        f"{median_ms(encode_cloud)} ms; as per-vertex GLB: {glb_bytes / 1e3:.0f} kB, encode "
        f"{median_ms(encode_glb)} ms"
    )
    if args.uploads:
        print()
        print(f"server resident memory: {memory_before:.0f} MB before the app started")
        print("| uploads | resident MB |")
        print("|---:|---:|")
        for count, megabytes in memory:
            print(f"| {count} | {megabytes:.0f} |")
    for title, batch in hostile or ():
        print()
        print(
            f"uploads at once, {title}: resident {batch.before:.0f} MB before, peak "
            f"{batch.peak:.0f} MB, {batch.after:.0f} MB after, {batch.seconds:.2f} s"
        )
        print("| upload | file KB | message |")
        print("|---|---:|---|")
        for name, kilobytes, message in batch.messages:
            print(f"| {name} | {kilobytes:.0f} | {message} |")


def track_pushes(app: ExplorerApp) -> None:
    """Keep in ``app.pushed_at`` when the worker last began pushing a view (A's; B follows)."""
    show_view = app.scene.show_view

    def tracked(*args, **kwargs) -> None:
        app.pushed_at = time.perf_counter()  # type: ignore[attr-defined]
        show_view(*args, **kwargs)

    app.scene.show_view = tracked  # type: ignore[method-assign]


def slider_move(app: ExplorerApp, recorder: FrameRecorder, exponent: float) -> tuple[float, float]:
    """Seconds from a left-elbow slider move to its last frame delivered, and the CPU seconds
    the process used meanwhile (all threads: the worker, viser's sending, the client)."""
    start, cpu = time.perf_counter(), time.process_time()
    app.sampling_changed(app.state.set_joint_exponent("left_elbow", exponent))
    app.wait_idle(60)
    seconds = recorder.delivered_after(start, app.pushed_at)[0]  # type: ignore[attr-defined]
    return seconds, time.process_time() - cpu


def occluder_move(
    app: ExplorerApp, recorder: FrameRecorder, ident: int, box
) -> tuple[float, float]:
    """As :func:`slider_move`, for an occluder edit (a new prediction)."""
    start, cpu = time.perf_counter(), time.process_time()
    app.occluders_changed(app.state.move_occluder(ident, box))
    app.wait_idle(60)
    assert not app.errors, app.errors
    seconds = recorder.delivered_after(start, app.pushed_at)[0]  # type: ignore[attr-defined]
    return seconds, time.process_time() - cpu


def report_paired(setting: str, repeats: int, threads: int, real: bool) -> None:
    """Plain vs compare ``setting``, alternated move by move (see the module docstring)."""
    torch.set_num_threads(threads)
    if real:
        provider, image = PredictorProvider(device="cpu"), load_image(shipped_photo()).pixels
    else:
        provider = OcclusionAwareDouble()
        image = provider.scene.image
    apps = {name: ExplorerApp(provider, image, port=0) for name in ("plain", "compare")}
    for app in apps.values():
        track_pushes(app)
    recorders = {name: FrameRecorder(app.url) for name, app in apps.items()}
    for app in apps.values():
        app.wait_idle(120)
    apps["compare"].set_compare(parse_compare(setting))
    apps["compare"].wait_idle(120)
    time.sleep(0.5)
    loads = [os.getloadavg()[0]]
    slider: dict[str, list[tuple[float, float]]] = {name: [] for name in apps}
    for i in range(repeats + 2):
        for name, app in apps.items() if i % 2 else reversed(apps.items()):
            time.sleep(SETTLE_S)  # the other app's last frames are sent and compressed
            seconds = slider_move(app, recorders[name], -0.05 * (i % 10 + 1))
            if i >= 2:
                slider[name].append(seconds)
    box = shin_box(apps["plain"]) if real else (250, 210, 300, 260)
    idents = {name: app.state.add_occluder(box).ident for name, app in apps.items()}
    for app in apps.values():
        app.occluders_changed(True)
        app.wait_idle(60)
    occluder: dict[str, list[tuple[float, float]]] = {name: [] for name in apps}
    for i in range(max(repeats // 2, 5)):
        x0, y0, x1, y1 = box
        for name, app in apps.items() if i % 2 else reversed(apps.items()):
            moved = (x0 - 1 - i, y0, x1, y1 + 1 + i)
            time.sleep(SETTLE_S)
            occluder[name].append(occluder_move(app, recorders[name], idents[name], moved))
    loads.append(os.getloadavg()[0])
    for app in apps.values():
        app.stop()
    model = "shipped Predictor on the shipped photo" if real else "test double"
    when = time.strftime("%Y-%m-%d %H:%M %Z")
    print(f"# explorer plain vs compare {setting}, alternated ({model}) — {when}")
    machine = platform.processor() or platform.machine()
    print(
        f"machine: {machine}, {os.cpu_count()} CPUs, torch threads {threads}, "
        f"load average {min(loads):.1f}-{max(loads):.1f} (shared)"
    )
    print()
    print(
        "| change -> delivered | plain median ms (best) | compare median ms (best) | ratio "
        "| CPU ms plain / compare (median) | CPU ratio |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for what, values in (("slider", slider), ("occluder (isolated edits)", occluder)):
        plain, compare = ([v[0] for v in values[n]] for n in ("plain", "compare"))
        cpu_plain, cpu_compare = ([v[1] for v in values[n]] for n in ("plain", "compare"))
        ratio = statistics.median(compare) / statistics.median(plain)
        cpu_ratio = statistics.median(cpu_compare) / statistics.median(cpu_plain)
        print(
            f"| {what} | {median_ms(plain)} ({best_ms(plain)}) | {median_ms(compare)} "
            f"({best_ms(compare)}) | {ratio:.2f}× | {median_ms(cpu_plain)} / "
            f"{median_ms(cpu_compare)} | {cpu_ratio:.2f}× |"
        )


class HostileResult(NamedTuple):
    """Resident MB before, peak and after; wall seconds; (name, file KB, message) per upload."""

    before: float
    peak: float
    after: float
    seconds: float
    messages: list[tuple[str, float, str]]


def hostile_uploads(app: ExplorerApp) -> list[tuple[str, HostileResult]]:
    """Two batches, each uploaded at once: a 30000^2 bomb with three 13300^2 PNGs (refused
    from the header), then three 7000^2 PNGs (49 Mpx, under the limit: decoded one at a time)."""
    batches = []
    with tempfile.TemporaryDirectory() as folder:
        colour = (90, 120, 160)
        big, large = solid_png(13300, 13300, colour), solid_png(7000, 7000, colour)
        hostile = [("bomb_30000.png", solid_png(30000, 30000, colour))]
        hostile += [(f"big_13300_{i}.png", big) for i in range(3)]
        allowed = [(f"large_7000_{i}.png", large) for i in range(3)]
        for title, files in (("bomb + three 13300^2", hostile), ("three 7000^2", allowed)):
            contents = []
            for name, data in files:
                path = Path(folder) / name
                path.write_bytes(data)
                contents.append((name, path.read_bytes()))
            batches.append((title, uploads_at_once(app, contents)))
    return batches


def uploads_at_once(app: ExplorerApp, contents: list[tuple[str, bytes]]) -> HostileResult:
    """Upload ``(name, bytes)`` from one thread each; sample resident memory meanwhile."""
    client = NotificationRecorder()
    before, peak, stop = resident_megabytes(), [0.0], threading.Event()

    def sample() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], resident_megabytes())
            time.sleep(0.005)

    sampler = threading.Thread(target=sample)
    sampler.start()
    start = time.perf_counter()
    threads = [
        threading.Thread(target=app.load_upload, args=(name, content, client))
        for name, content in contents
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    app.wait_idle(120)
    seconds = time.perf_counter() - start
    stop.set()
    sampler.join()
    sizes = {name: len(content) / 1024 for name, content in contents}
    messages = [
        (name, sizes[name], f"{title}: {body}")
        for title, body in client.notifications
        for name in sizes
        if repr(name) in body or name in body
    ]
    return HostileResult(before, peak[0], resident_megabytes(), seconds, sorted(messages))


class NotificationRecorder:
    """Stands in for a browser tab's client: keeps every notification ``(title, body)``."""

    def __init__(self) -> None:
        self.notifications: list[tuple[str, str]] = []
        self._lock = threading.Lock()

    def add_notification(self, title: str, body: str, **_: object) -> None:
        with self._lock:
            self.notifications.append((title, body))


def solid_png(width: int, height: int, colour: tuple[int, int, int]) -> bytes:
    """A valid ``width x height`` RGB PNG of one colour, compressed row by row (a few KB per
    thousand rows), without ever holding the pixels."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    row = b"\x00" + bytes(colour) * width
    compressor = zlib.compressobj(6)
    block = row * 64
    parts = [compressor.compress(block) for _ in range(height // 64)]
    parts.append(compressor.compress(row * (height % 64)))
    data = b"".join(parts) + compressor.flush()
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data) + chunk(b"IEND", b"")
    )


def msgpack_name(name: str) -> bytes:
    """How a short node name appears inside viser's msgpack frames (a fixstr)."""
    assert len(name) < 32
    return bytes([0xA0 | len(name)]) + name.encode()


def frame_messages(frame: bytes | str) -> bytes:
    """The msgpack part of one viser websocket frame (``[8 B size][8 B zstd size][zstd]...``)."""
    if isinstance(frame, str):
        return frame.encode()
    size = int.from_bytes(frame[:8], "little")
    compressed = int.from_bytes(frame[8:16], "little")
    return zstandard.ZstdDecompressor().decompress(frame[16 : 16 + compressed], size)


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def process_cpu_seconds(pid: int) -> float:
    """User + system CPU seconds process ``pid`` has used so far (all its threads)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


async def _watch_startup(port: int, started: float, timeout: float, pid: int) -> dict[str, float]:
    """Seconds from ``started`` until each of :data:`STARTUP_NODES` reached a client, and
    ``"cpu"``: the CPU seconds the explorer had used by the first complete view."""
    protocol = f"viser-v{viser.__version__}"
    seen: dict[str, float] = {}
    deadline = started + timeout
    while time.perf_counter() < deadline:
        try:
            ws = await websockets.connect(
                f"ws://127.0.0.1:{port}", subprotocols=[protocol], max_size=None
            )
        except OSError:
            await asyncio.sleep(0.05)
            continue
        async with ws:
            async for message in ws:
                now = time.perf_counter() - started
                data = frame_messages(message)
                for what, name in STARTUP_NODES.items():
                    if what not in seen and msgpack_name(name) in data:
                        seen[what] = now
                if len(seen) == len(STARTUP_NODES):
                    return {**seen, "cpu": process_cpu_seconds(pid)}
                if time.perf_counter() > deadline:
                    break
    raise TimeoutError(f"the explorer did not show its first view within {timeout:.0f} s")


def startup_once(photo: str | None, threads: int) -> dict[str, float]:
    """Start ``hkpd-explore`` once and time its first view (see the module docstring)."""
    port = free_port()
    command = [sys.executable, "-m", "hkpd.explorer.cli", "--no-browser", "--port", str(port)]
    command += [photo] if photo else []
    env = {**os.environ, "OMP_NUM_THREADS": str(threads)}
    started = time.perf_counter()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        return asyncio.run(_watch_startup(port, started, 120.0, process.pid))
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()


def report_startup(repeats: int, photo: str | None, threads: int) -> None:
    loads, runs = [os.getloadavg()[0]], []
    for _ in range(repeats):
        runs.append(startup_once(photo, threads))
        loads.append(os.getloadavg()[0])
    when = time.strftime("%Y-%m-%d %H:%M %Z")
    print(f"# hkpd-explore start-up ({photo or 'the shipped photo'}) — {when}")
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"OMP_NUM_THREADS={threads}, load average {min(loads):.1f}-{max(loads):.1f} (shared)"
    )
    print()
    print("| command -> server holds | median s | best s | runs (s) |")
    print("|---|---:|---:|---|")
    labels = {
        "photo": "the photo",
        "heatmap": "**first complete view** (photo, bodies, heatmap)",
        "cpu": "CPU seconds used by the first complete view (all threads)",
    }
    for what, label in labels.items():
        values = [run[what] for run in runs]
        print(
            f"| {label} | {statistics.median(values):.2f} | {min(values):.2f} | "
            + ", ".join(f"{v:.1f}" for v in values)
            + " |"
        )


def resident_megabytes() -> float:
    """This process's resident memory (VmRSS), MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def jpeg_bytes(image: np.ndarray, scale: float) -> bytes:
    """``image`` resized by ``scale``, as JPEG file contents (a new upload each time)."""
    height, width = image.shape[:2]
    resized = Image.fromarray(image).resize((round(width * scale), round(height * scale)))
    buffer = io.BytesIO()
    resized.save(buffer, format="JPEG", quality=90)
    return buffer.getvalue()


def shin_box(app: ExplorerApp) -> tuple[float, float, float, float]:
    """A box around the detected right knee and ankle of the first photo's person."""
    keypoints = app.result.posterior.keypoints.numpy()
    knee, ankle = keypoints[14], keypoints[16]
    pad = 0.25 * float(np.hypot(*(knee - ankle)))
    low, high = np.minimum(knee, ankle) - pad, np.maximum(knee, ankle) + pad
    return (float(low[0]), float(low[1]), float(high[0]), float(high[1]))


if __name__ == "__main__":
    main()
