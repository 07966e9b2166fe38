"""Unit tests of the pieces behind ``hkpd-predict``: colour scale, exports, input collection."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from hkpd.prediction.cli import UsageError, collect_images, output_names, parse_bbox, parse_formats
from hkpd.prediction.exports.overview import draw_colour_bar
from hkpd.prediction.exports.uncertainty_colours import (
    VIRIDIS_ANCHORS,
    UncertaintyColourScale,
    ramp_colours,
    vertex_to_face_values,
)
from hkpd.prediction.exports.writers import (
    DISPLAY_FROM_CAMERA,
    to_display_frame,
    write_distribution_npz,
    write_json,
    write_mesh,
)


def test_colour_scale_ends_clips_and_interpolates():
    scale = UncertaintyColourScale()
    np.testing.assert_allclose(scale.colours(0.0), VIRIDIS_ANCHORS[0])
    np.testing.assert_allclose(scale.colours(0.10), VIRIDIS_ANCHORS[-1])
    np.testing.assert_allclose(scale.colours(0.5), VIRIDIS_ANCHORS[-1])  # above the top
    np.testing.assert_allclose(scale.colours(-1.0), VIRIDIS_ANCHORS[0])
    np.testing.assert_allclose(scale.colours(0.05), VIRIDIS_ANCHORS[4])  # the middle anchor
    halfway = ramp_colours(np.array(1 / 16))
    np.testing.assert_allclose(halfway, (VIRIDIS_ANCHORS[0] + VIRIDIS_ANCHORS[1]) / 2)
    # Brightness grows monotonically along the ramp (readable in greyscale).
    luminance = ramp_colours(np.linspace(0, 1, 200)) @ np.array([0.2126, 0.7152, 0.0722])
    assert (np.diff(luminance) > 0).all()
    assert scale.colours_uint8(np.zeros((4, 5))).shape == (4, 5, 3)
    assert scale.ticks_cm() == [0, 2, 4, 6, 8, 10]
    with pytest.raises(ValueError, match="maximum > minimum"):
        UncertaintyColourScale(0.1, 0.1)


def test_vertex_to_face_values_averages_corners():
    values = np.array([0.0, 3.0, 6.0, 9.0])
    faces = np.array([[0, 1, 2], [1, 2, 3]])
    np.testing.assert_allclose(vertex_to_face_values(values, faces), [3.0, 6.0])


def test_colour_bar_runs_from_top_colour_to_bottom_colour():
    bar = draw_colour_bar(UncertaintyColourScale(), 400)
    assert bar.shape == (400, 110, 3)
    column = bar[:, 24].astype(int)
    top = np.abs(column - VIRIDIS_ANCHORS[-1] * 255).sum(1).argmin()
    bottom = np.abs(column - VIRIDIS_ANCHORS[0] * 255).sum(1).argmin()
    assert top < bottom


def test_display_frame_is_a_half_turn_about_x():
    assert np.linalg.det(DISPLAY_FROM_CAMERA) == pytest.approx(1.0)
    points = torch.tensor([[1.0, 2.0, 3.0]])
    np.testing.assert_allclose(to_display_frame(points), [[1.0, -2.0, -3.0]])


@pytest.mark.parametrize("fmt", ["ply", "obj", "glb"])
def test_write_mesh_round_trip_keeps_winding_and_colours(tmp_path, fmt):
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # outward normals
    colours = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]], dtype=np.uint8)
    path = write_mesh(tmp_path / f"tet.{fmt}", vertices, faces, colours)
    mesh = trimesh.load(path, force="mesh", process=False)
    np.testing.assert_allclose(mesh.vertices, to_display_frame(vertices), atol=1e-6)
    assert mesh.volume > 0  # a rotation keeps the outward winding
    if fmt != "obj":
        np.testing.assert_array_equal(mesh.visual.vertex_colors[:, :3], colours)
    with pytest.raises(ValueError, match="mesh format"):
        write_mesh(tmp_path / "tet.stl", vertices, faces)


def test_npz_and_json_writers(tmp_path):
    path = write_distribution_npz(
        tmp_path / "a.npz", {"x": torch.ones(2, 3, dtype=torch.float64), "n": np.int64(4)}
    )
    arrays = np.load(path)
    assert arrays["x"].dtype == np.float32 and arrays["x"].shape == (2, 3)
    assert int(arrays["n"]) == 4
    written = write_json(
        tmp_path / "s.json",
        {"t": torch.tensor([1.23456789]), "p": Path("x/y"), "bad": float("nan"), "i": np.int32(3)},
    )
    assert json.loads(written.read_text()) == {"t": [1.234568], "p": "x/y", "bad": None, "i": 3}


def test_collect_images_recursive_sorted_by_extension(tmp_path):
    (tmp_path / "b" / "c").mkdir(parents=True)
    for name in ("b/c/z.JPG", "b/a.png", "b/skip.txt", "a.jpeg"):
        (tmp_path / name).write_bytes(b"x")
    found = collect_images([tmp_path, tmp_path / "given.txt"])
    relative = [p.relative_to(tmp_path).as_posix() for p in found]
    assert relative == ["a.jpeg", "b/a.png", "b/c/z.JPG", "given.txt"]


def test_output_names_are_unique():
    names = output_names([Path("a/x.jpg"), Path("b/x.jpg"), Path("c/x.png"), Path("d/y.jpg")])
    assert names == ["x", "x_jpg", "x_png", "y"]


def test_parse_bbox_and_formats():
    assert parse_bbox(["1", "2", "3", "4"]) == (1, 2, 3, 4)
    assert parse_bbox(["1,2,3,4"]) == (1, 2, 3, 4)
    assert parse_bbox(None) is None
    with pytest.raises(UsageError):
        parse_bbox(["1", "2", "three", "4"])
    assert parse_formats(None) == ("ply", "npz")
    assert parse_formats(["GLB", "obj,glb"]) == ("glb", "obj")
    with pytest.raises(UsageError, match="stl"):
        parse_formats(["stl"])


def test_no_images_in_folder_is_a_usage_error(tmp_path, capsys):
    from hkpd.prediction.cli import main

    (tmp_path / "empty").mkdir()
    assert main([str(tmp_path / "empty"), "--out", str(tmp_path / "out")]) == 2
    assert "no images found" in capsys.readouterr().err


def test_ctrl_c_stops_cleanly(tmp_path, capsys, monkeypatch):
    from hkpd.prediction import cli

    closed = []

    class Dummy:
        def close(self):
            closed.append(True)

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "load_predictor", lambda model, device: Dummy())
    monkeypatch.setattr(cli, "predict_photo", interrupt)
    (tmp_path / "a.jpg").write_bytes(b"x")
    assert cli.main([str(tmp_path / "a.jpg"), "--out", str(tmp_path / "out")]) == 130
    assert "interrupted after 0 of 1" in capsys.readouterr().err
    assert closed == [True]
    assert not (tmp_path / "out").exists()  # created by the run, nothing in it: removed
