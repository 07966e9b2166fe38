"""``hkpd-predict --same-person``: each photo's results plus the shape combined from all of them.

Same set-up as ``test_predict_cli.py`` (a rendered photo, a fake detector returning its true
keypoints, a tiny untrained network saved as a real checkpoint).
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import trimesh
from PIL import Image
from test_predict_cli import checkpoint, fake_predictor_factory, scene  # noqa: F401 (fixtures)

from hkpd.prediction import cli

NUM_VERTICES = 13492


@pytest.fixture()
def three_photos(tmp_path, scene):  # noqa: F811 (the imported fixture)
    folder = tmp_path / "photos"
    folder.mkdir()
    Image.fromarray(scene.image).save(folder / "front.png")
    shutil.copy(folder / "front.png", folder / "again.png")
    Image.new("RGB", (200, 300), (128, 128, 128)).save(folder / "blank.png")  # no person
    return [folder / "front.png", folder / "again.png", folder / "blank.png"]


def _run(arguments, monkeypatch, capsys, factory):
    monkeypatch.setattr(cli, "load_predictor", factory)
    code = cli.main([str(a) for a in arguments])
    return code, capsys.readouterr()


def test_same_person_writes_the_combined_shape(
    three_photos,
    tmp_path,
    checkpoint,  # noqa: F811
    fake_predictor_factory,  # noqa: F811
    monkeypatch,
    capsys,
):
    out = tmp_path / "out"
    flags = [*three_photos, "--out", out, "--model", checkpoint, "--samples", "1", "--format",
             "ply", "obj", "npz", "--uncertainty-samples", "4", "--same-person"]  # fmt: skip
    code, output = _run(flags, monkeypatch, capsys, fake_predictor_factory)
    assert code == 1  # the blank photo failed; the other two were combined
    last = output.out.strip().splitlines()[-1]
    assert "2 of 3 photos done, 1 failed" in last
    assert "combined shape of 2 photo(s)" in last and str(out / "same_person_shape") in last
    left = sorted(p.name for p in out.iterdir())
    assert left == ["again", "front", "index.jsonl", "same_person_shape"]

    folder = out / "same_person_shape"
    summary = json.loads((folder / "shape.json").read_text())
    on_disk = sorted(p.name for p in folder.iterdir())
    assert sorted(summary["files"]) == on_disk
    assert {"tpose.ply", "tpose.obj", "tpose_uncertainty.ply", "shape.npz"} <= set(on_disk)
    assert [p.split("/")[-1] for p in summary["photos"]] == ["front.png", "again.png"]
    assert summary["count"] == 2

    arrays = np.load(folder / "shape.npz")
    photo = np.load(out / "front" / "prediction.npz")
    np.testing.assert_allclose(arrays["photo_betas_mean"][0], photo["shape_mean"], rtol=1e-6)
    # Two identical photos: the same mean, the variance halved.
    np.testing.assert_allclose(arrays["betas_mean"], photo["shape_mean"], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(arrays["betas_std"], photo["shape_std"] / np.sqrt(2), rtol=1e-5)
    np.testing.assert_allclose(summary["betas_std"], arrays["betas_std"], atol=1e-6)
    assert arrays["tpose_vertices"].shape == (NUM_VERTICES, 3)
    assert arrays["uncertainty"].shape == (NUM_VERTICES,) and (arrays["uncertainty"] > 0).all()

    mesh = trimesh.load(folder / "tpose_uncertainty.ply", force="mesh", process=False)
    assert mesh.vertices.shape == (NUM_VERTICES, 3)
    assert mesh.vertices[:, 1].max() > 0.4  # Y-up display frame: the head is up
    assert len(np.unique(mesh.visual.vertex_colors[:, :3], axis=0)) > 1

    # The combined folder counts as existing results: refused without --overwrite.
    code, output = _run(flags[:2] + flags[3:], monkeypatch, capsys, fake_predictor_factory)
    assert code == 2 and "same_person_shape" in output.err and "--overwrite" in output.err
    stale = folder / "old.txt"
    stale.write_text("from an earlier run")
    code, output = _run([*flags, "--overwrite"], monkeypatch, capsys, fake_predictor_factory)
    assert code == 1 and not stale.exists()
    assert not [p for p in out.iterdir() if p.name.endswith(".partial")]


def test_a_photo_named_like_the_combined_folder_keeps_its_own_folder(
    three_photos,
    tmp_path,
    checkpoint,  # noqa: F811
    fake_predictor_factory,  # noqa: F811
    monkeypatch,
    capsys,
):
    named = three_photos[0].with_name("same_person_shape.png")
    shutil.copy(three_photos[0], named)
    out = tmp_path / "out"
    flags = [named, three_photos[1], "--out", out, "--model", checkpoint, "--samples", "0",
             "--format", "ply", "--uncertainty-samples", "2", "--same-person"]  # fmt: skip
    code, output = _run(flags, monkeypatch, capsys, fake_predictor_factory)
    assert code == 0
    assert (out / "same_person_shape" / "summary.json").is_file()  # the photo's results
    assert (out / "same_person_shape_2" / "shape.json").is_file()  # the combined shape
    assert "same_person_shape_2" in output.out.strip().splitlines()[-1]


def test_without_photos_that_succeed_no_combined_folder_is_written(
    three_photos,
    tmp_path,
    checkpoint,  # noqa: F811
    fake_predictor_factory,  # noqa: F811
    monkeypatch,
    capsys,
):
    out = tmp_path / "out"
    flags = [three_photos[2], "--out", out, "--model", checkpoint, "--same-person"]
    code, output = _run(flags, monkeypatch, capsys, fake_predictor_factory)
    assert code == 1
    assert "no combined shape (no photo succeeded)" in output.out
    assert not (out / "same_person_shape").exists()
