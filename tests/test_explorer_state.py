"""Unit tests of the explorer's pure parts: state rules, the coalescing worker, geometry, colours,
uploads and exports. No browser and no server."""

from __future__ import annotations

import io
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import trimesh
from PIL import Image

from hkpd.explorer.colour_map import (
    HeatmapScale,
    change_colours,
    legend_image,
    uncertainty_colours,
)
from hkpd.explorer.export import meshes_file, png_bytes
from hkpd.explorer.photo_geometry import (
    HALF_TURN_ABOUT_X,
    PhotoPlacement,
    quaternion_to_matrix,
    screen_rect_to_box,
)
from hkpd.explorer.state import MAX_OCCLUDERS, ExplorerState, clamp_box
from hkpd.explorer.upload import MAX_UPLOAD_BYTES, UploadError, decode_upload
from hkpd.explorer.worker import CoalescingWorker
from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.prediction.exports.uncertainty_colours import UncertaintyColourScale


def make_state() -> ExplorerState:
    state = ExplorerState()
    state.set_image(400, 300)
    return state


# ---------------------------------------------------------------------------- occluders
def test_clamp_box_orders_corners_and_clips_to_the_photo():
    assert clamp_box((120, 80, 20, -30), 100, 50) == (20.0, 0.0, 100.0, 50.0)
    assert clamp_box((-50, -50, -10, -10), 100, 50) is None  # entirely off the photo
    assert clamp_box((10, 10, 11, 40), 100, 50) is None  # thinner than 2 px
    assert clamp_box((0, 0, float("nan"), 4), 100, 50) is None


def test_add_move_toggle_delete_occluders_bump_prediction_version():
    state = make_state()
    v0 = state.snapshot().prediction_version
    first = state.add_occluder((350, 250, 450, 350))
    assert first is not None and first.box == (350.0, 250.0, 400.0, 300.0)
    second = state.add_occluder((10, 10, 50, 60))
    assert second is not None and second.ident != first.ident
    assert state.snapshot().prediction_version == v0 + 2

    assert state.move_occluder(first.ident, (0, 0, 30, 30))
    assert state.occluder(first.ident).box == (0.0, 0.0, 30.0, 30.0)
    assert not state.move_occluder(first.ident, (0, 0, 30, 30))  # unchanged: no new work
    assert not state.move_occluder(first.ident, (-90, -90, -50, -50))  # clamped away: refused
    assert state.occluder(first.ident).box == (0.0, 0.0, 30.0, 30.0)

    assert state.set_occluder_enabled(second.ident, False)
    assert state.snapshot().active_boxes == [(0.0, 0.0, 30.0, 30.0)]
    assert state.delete_occluder(first.ident)
    assert not state.delete_occluder(first.ident)  # a second tab clicking delete: no error
    assert [o.ident for o in state.snapshot().occluders] == [second.ident]
    assert state.snapshot().prediction_version == v0 + 5
    with pytest.raises(KeyError):
        state.occluder(first.ident)


def test_occluder_limit_and_new_photo_clears_occluders():
    state = make_state()
    for _ in range(MAX_OCCLUDERS):
        assert state.add_occluder((0, 0, 10, 10)) is not None
    assert state.add_occluder((0, 0, 10, 10)) is None
    state.set_joint_exponent("left_knee", 0.5)
    state.set_image(64, 64)
    snapshot = state.snapshot()
    assert snapshot.occluders == () and snapshot.image_size == (64, 64)
    assert snapshot.joint_exponents[BODY_JOINT_NAMES.index("left_knee")] == 0.5


def test_concurrent_edits_from_two_tabs_keep_state_consistent():
    state = make_state()

    def tab(offset: int) -> None:
        for i in range(200):
            occluder = state.add_occluder((offset, i % 50, offset + 20, i % 50 + 20))
            if occluder is not None:
                state.move_occluder(occluder.ident, (offset + 1, 0, offset + 30, 30))
                state.delete_occluder(occluder.ident)
            state.set_joint_exponent("left_elbow", (i % 20) / 10 - 1)

    threads = [threading.Thread(target=tab, args=(k * 100,)) for k in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    snapshot = state.snapshot()
    assert snapshot.occluders == ()
    assert snapshot.prediction_version == 1 + 2 * 200 * 3  # set_image + add/move/delete each


# ---------------------------------------------------------------------------- concentration
def test_concentration_factors_combine_joint_and_global_exponents_and_clip():
    state = make_state()
    assert state.set_joint_exponent("left_elbow", 0.5)
    assert state.set_global_exponent(-0.25)
    assert not state.set_global_exponent(-0.25)
    assert state.set_shape_std_exponent(5.0)  # clipped to 10x
    snapshot = state.snapshot()
    factors = snapshot.concentration_factors
    assert factors[BODY_JOINT_NAMES.index("left_elbow")] == pytest.approx(10**0.25)
    assert factors[BODY_JOINT_NAMES.index("right_elbow")] == pytest.approx(10**-0.25)
    assert snapshot.shape_std_factor == pytest.approx(10.0)
    with pytest.raises(ValueError, match="unknown joint"):
        state.set_joint_exponent("tail", 0.1)
    version = snapshot.sampling_version
    assert state.reset_concentrations()
    assert not state.reset_concentrations()
    assert state.snapshot().sampling_version == version + 1
    assert set(state.snapshot().concentration_factors) == {1.0}


def test_sample_controls_are_bounded_and_resample_moves_the_seed():
    state = make_state()
    assert state.set_num_samples(10_000) and state.num_samples == 200
    assert state.set_num_displayed(-3) and state.num_displayed == 0
    seed = state.seed
    assert state.next_seed() == seed + 1


# ---------------------------------------------------------------------------- worker
def test_worker_coalesces_a_burst_into_few_runs_and_runs_the_latest():
    worker = CoalescingWorker(("sample",)).start()
    seen: list[int] = []
    gate = threading.Event()

    def job(value: int):
        def run() -> None:
            gate.wait(1.0)
            seen.append(value)

        return run

    for value in range(50):
        worker.submit("sample", job(value))
    gate.set()
    assert worker.wait_idle(5.0)
    worker.stop()
    assert seen[-1] == 49  # the newest request always runs
    assert len(seen) <= 2  # at most the one already running, plus the latest
    assert worker.stats["sample"].superseded >= 48


def test_worker_debounce_waits_for_a_pause_and_priority_orders_lanes():
    worker = CoalescingWorker(("predict", "sample")).start()
    order: list[str] = []
    started = time.monotonic()
    for _ in range(5):
        worker.submit("predict", lambda: order.append("predict"), delay_s=0.2)
        time.sleep(0.02)
    worker.submit("sample", lambda: order.append("sample"))
    assert worker.wait_idle(5.0)
    elapsed = time.monotonic() - started
    worker.stop()
    assert order == ["sample", "predict"]  # sample was due first; predict ran once
    assert elapsed >= 0.2 + 4 * 0.02 - 0.01


def test_worker_runs_an_isolated_leading_submission_at_once_and_debounces_a_burst():
    worker = CoalescingWorker(("predict",)).start()
    ran: list[tuple[int, float]] = []
    started = time.monotonic()
    worker.submit("predict", lambda: ran.append((0, time.monotonic())), 0.5, leading=True)
    assert worker.wait_idle(5.0)
    assert ran[0][1] - started < 0.25  # isolated: no 0.5 s wait (issue 58)
    time.sleep(0.6)
    burst_start = time.monotonic()
    for value in range(1, 6):
        worker.submit("predict", lambda v=value: ran.append((v, time.monotonic())), 0.3,
                      leading=True)  # fmt: skip
        time.sleep(0.02)
    assert worker.wait_idle(5.0)
    worker.stop()
    values = [value for value, _ in ran[1:]]
    assert values == [1, 5]  # the burst's first at once, then its last after the pause
    assert ran[1][1] - burst_start < 0.2 and ran[2][1] - burst_start >= 0.3 + 4 * 0.02 - 0.01


def test_worker_survives_a_failing_job():
    errors: list[str] = []
    worker = CoalescingWorker(("a",), on_error=lambda lane, e: errors.append(str(e))).start()
    worker.submit("a", lambda: 1 / 0)
    assert worker.wait_idle(5.0)
    done = []
    worker.submit("a", lambda: done.append(True))
    assert worker.wait_idle(5.0)
    worker.stop()
    assert errors and done == [True] and worker.stats["a"].failed == 1


# ---------------------------------------------------------------------------- geometry
def test_screen_rectangle_maps_back_to_the_photo_pixels_it_covers():
    placement = PhotoPlacement(400, 300, (-1.0, 0.2, 0.0), 1.5)
    # A camera on +z looking at -z: OpenCV camera axes right = +x, down = -y, forward = -z.
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    position = np.array([-0.5, 0.0, 3.0])
    fov, aspect = np.deg2rad(40.0), 1.5
    target = np.array([[100.0, 60.0], [260.0, 200.0]])  # photo pixels (top-left, bottom-right)
    local = placement.pixels_to_local(target)
    world = np.stack(
        [local[:, 0] + placement.centre[0], placement.centre[1] - local[:, 1], np.zeros(2)], axis=1
    )
    cam = (world - position) @ rotation  # camera-frame points
    half = np.tan(fov / 2)
    screen = np.stack(
        [(cam[:, 0] / cam[:, 2] / (half * aspect) + 1) / 2, (cam[:, 1] / cam[:, 2] / half + 1) / 2],
        axis=1,
    )
    box = screen_rect_to_box(
        tuple(screen[0]), tuple(screen[1]), position, rotation, fov, aspect, placement
    )
    np.testing.assert_allclose(box, [100, 60, 260, 200], atol=1e-6)
    # Looking away from the photo gives no box.
    assert (
        screen_rect_to_box((0.4, 0.4), (0.6, 0.6), position, -rotation, fov, aspect, placement)
        is None
    )


def test_half_turn_quaternion_matches_the_opencv_axes():
    np.testing.assert_allclose(
        quaternion_to_matrix(np.array(HALF_TURN_ABOUT_X)), np.diag([1.0, -1.0, -1.0]), atol=1e-12
    )


# ---------------------------------------------------------------------------- colours
def test_uncertainty_colours_match_hkpd_predict_and_saturate():
    values = np.array([0.0, 0.075, 0.15, 0.5])
    colours = uncertainty_colours(values, max_cm=15.0)
    assert colours.dtype == np.uint8 and colours.shape == (4, 3)
    assert colours[0, 2] > colours[0, 1]  # certain: dark purple-blue
    assert colours[2, 0] > colours[2, 2] and colours[2, 1] > colours[2, 2]  # top: yellow
    np.testing.assert_array_equal(colours[2], colours[3])
    # The same ramp as hkpd-predict's renders, at the same default scale.
    np.testing.assert_array_equal(
        uncertainty_colours(values), UncertaintyColourScale().colours_uint8(values)
    )
    legend = legend_image(15.0)
    assert legend.shape == (64, 320, 3) and legend.std() > 20


def test_the_log_scale_keeps_chain_ends_apart_and_the_change_map_diverges():
    # The shipped photo's range (2.5 .. 22.5 cm): distinct colours, none at the top colour.
    values_m = np.array([0.025, 0.067, 0.15, 0.225])
    log = HeatmapScale("log").colours(values_m)
    assert len({tuple(c) for c in log}) == 4
    top = HeatmapScale("log").colours(np.array([1.0]))[0]
    assert not any(np.array_equal(c, top) for c in log)
    linear = HeatmapScale("linear", 10.0).colours(values_m)
    np.testing.assert_array_equal(linear[2], linear[3])  # the old linear scale saturates
    change = change_colours(np.array([1 / 3, 0.7, 1.0, 1.5, 3.0, 10.0]))
    assert abs(int(change[2, 0]) - int(change[2, 2])) < 10  # 1x: neutral grey
    assert change[3, 0] > change[3, 2] + 30 and change[1, 2] > change[1, 0] + 20  # red / blue
    np.testing.assert_array_equal(change[4], change[5])  # saturates at 3x
    legends = [HeatmapScale(kind).legend() for kind in ("log", "linear", "change")]
    assert all(legend.shape == (64, 320, 3) for legend in legends)
    assert not np.array_equal(legends[0], legends[2])
    with pytest.raises(ValueError, match="unknown colouring"):
        HeatmapScale("rainbow")


# ---------------------------------------------------------------------------- uploads / export
def _png(width: int, height: int) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(np.full((height, width, 3), 120, np.uint8)).save(buffer, format="PNG")
    return buffer.getvalue()


def test_upload_validation():
    image = decode_upload("person.png", _png(80, 60))
    assert image.shape == (60, 80, 3) and image.dtype == np.uint8
    with pytest.raises(UploadError, match="not a supported photo"):
        decode_upload("notes.txt", b"hello")
    with pytest.raises(UploadError, match="empty"):
        decode_upload("a.jpg", b"")
    with pytest.raises(UploadError, match="could not be read"):
        decode_upload("a.jpg", b"\xff\xd8 this is not a jpeg")
    with pytest.raises(UploadError, match="limit"):
        decode_upload("a.jpg", b"0" * (MAX_UPLOAD_BYTES + 1))
    with pytest.raises(UploadError, match="at least"):
        decode_upload("tiny.png", _png(40, 20))


def test_mesh_export_round_trips_through_trimesh():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    samples = np.stack([vertices + 0.1, vertices + 0.2])
    scene = trimesh.load(io.BytesIO(meshes_file(vertices, samples, faces, "glb")), file_type="glb")
    assert len(scene.geometry) == 3
    ply = trimesh.load(io.BytesIO(meshes_file(vertices, samples, faces, "ply")), file_type="ply")
    assert len(ply.vertices) == 12 and len(ply.faces) == 12
    np.testing.assert_allclose(ply.vertices[:4], vertices * [1, -1, -1], atol=1e-6)  # y up
    with pytest.raises(ValueError, match="unknown mesh format"):
        meshes_file(vertices, samples, faces, "obj")
    png = png_bytes(np.zeros((4, 5, 3), np.uint8))
    assert png.startswith(b"\x89PNG")


SCIPY_FREE_EXPORT = """
import io, sys
sys.modules["scipy"] = None  # the README's main install has no scipy (only the dev extra)
import numpy as np, trimesh
from hkpd.explorer.export import MODE_RGBA, meshes_file
vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
glb = meshes_file(vertices, vertices[None] + 0.1, faces, "glb")
scene = trimesh.load(io.BytesIO(glb), file_type="glb")
mode = scene.geometry["mode"]
assert tuple(mode.visual.vertex_colors[0]) == MODE_RGBA, mode.visual.vertex_colors[0]
meshes_file(vertices, vertices[None] + 0.1, faces, "ply")
print("exported", len(glb))
"""


def test_mesh_export_needs_no_scipy():
    """GLB and PLY export work where scipy cannot be imported (trimesh's face colours need
    scipy.sparse; the explorer writes vertex colours)."""
    done = subprocess.run(
        [sys.executable, "-c", SCIPY_FREE_EXPORT], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("exported")


def test_uploads_decode_one_at_a_time(monkeypatch):
    import hkpd.explorer.upload as upload

    running, most = [0], [0]
    lock = threading.Lock()
    real_load_image = upload.load_image

    def slow_load_image(content):
        with lock:
            running[0] += 1
            most[0] = max(most[0], running[0])
        time.sleep(0.1)
        try:
            return real_load_image(content)
        finally:
            with lock:
                running[0] -= 1

    monkeypatch.setattr(upload, "load_image", slow_load_image)
    threads = [
        threading.Thread(target=decode_upload, args=(f"p{i}.png", _png(80, 60))) for i in range(3)
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert most[0] == 1


def test_every_colour_bar_names_its_scale_in_the_same_words(monkeypatch) -> None:
    """Issue 58: the explorer's default bar is log 1-32 cm, hkpd-predict's overview linear
    0-10 cm; each bar now says which in the same words, so a class compares colours only
    between pictures whose bars match (the explorer's *linear* colouring is the overview's)."""
    from hkpd.explorer import colour_map
    from hkpd.prediction.exports import overview

    assert UncertaintyColourScale().label == "linear 0-10 cm"
    assert colour_map.LOG_LABEL == "log 1-32 cm"
    titles: list[str] = []
    monkeypatch.setattr(colour_map, "_bar_image", lambda _r, _t, title, *_: titles.append(title))
    colour_map.legend_image()
    colour_map.log_legend_image()
    assert titles == ["Uncertainty over samples, linear 0-10 cm (saturates above)",
                      "Uncertainty over samples, log 1-32 cm"]  # fmt: skip
    drawn: list[str] = []
    real_text = overview.ImageDraw.ImageDraw.text

    def text(self, xy, words, *args, **kwargs):
        drawn.append(words)
        return real_text(self, xy, words, *args, **kwargs)

    monkeypatch.setattr(overview.ImageDraw.ImageDraw, "text", text)
    overview.draw_colour_bar(UncertaintyColourScale(), 400)
    assert "linear 0-10 cm" in drawn
