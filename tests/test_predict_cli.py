"""End-to-end tests of ``hkpd-predict`` on a photo the project renders itself.

The keypoint detector is replaced by a fake one that returns the rendered person's true COCO
keypoints (BlazePose on a synthetic render is not reliable enough for a test), and the network
is a tiny untrained one saved as a real checkpoint, so everything else (checkpoint loading, crop,
proxy, network, posterior, exports, overview) runs for real.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from PIL import Image

from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.prediction import cli
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.detection.keypoint_detector import KeypointDetection, NoPersonFoundError
from hkpd.prediction.detection.person_mask import PersonMask
from hkpd.prediction.exports.uncertainty_colours import UncertaintyColourScale
from hkpd.prediction.exports.writers import to_display_frame
from hkpd.prediction.image_input import load_image

SAMPLES = 3
NUM_VERTICES = 13492


class TruthDetector:
    """Returns fixed keypoints for any photo with content; raises on a blank photo."""

    def __init__(self, keypoints: np.ndarray, confidences: np.ndarray | None = None) -> None:
        self.keypoints = keypoints
        self.confidences = np.linspace(0.3, 1.0, 17) if confidences is None else confidences
        self.calls: list[object] = []

    def detect(self, image, bbox=None) -> KeypointDetection:
        loaded = load_image(image)
        self.calls.append(bbox)
        if loaded.pixels.std() < 1.0:
            raise NoPersonFoundError(f"{loaded.source}: no person found in the photo")
        box = np.concatenate([self.keypoints.min(0), self.keypoints.max(0)])
        return KeypointDetection(
            person_mask=box_mask(box, loaded.original_size),
            keypoints=self.keypoints.copy(),
            confidences=self.confidences.copy(),
            person_box=box,
            mask_box=None,
            search_box=None if bbox is None else np.asarray(bbox, np.float64),
            image_size=loaded.original_size,
            seconds=0.0,
        )

    def close(self) -> None:
        pass


def box_mask(box: np.ndarray, image_size: tuple[int, int]) -> PersonMask:
    """A 64 × 64 mask, probability 1 inside ``box`` (a stand-in for BlazePose's): its pixels
    map onto the box's photo pixels."""
    probability = np.zeros((64, 64), np.float32)
    probability[8:56, 8:56] = 1.0
    x0, y0, x1, y1 = box
    scale_x, scale_y = (x1 - x0) / 48, (y1 - y0) / 48
    to_photo = np.array([[scale_x, 0, x0 - 7.5 * scale_x], [0, scale_y, y0 - 7.5 * scale_y]])
    return PersonMask(probability, to_photo, image_size)


@pytest.fixture(scope="module")
def scene():
    from hkpd.explorer.demo_scene import render_demo_scene

    return render_demo_scene()


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    from hkpd.network import DistributionNetwork, NetworkConfig
    from hkpd.network.checkpoint import save_checkpoint

    torch.manual_seed(0)
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    network = DistributionNetwork(config)
    path = tmp_path_factory.mktemp("model") / "tiny.pt"
    return save_checkpoint(path, network, config.to_dict(), 0, {}, 0)


@pytest.fixture(scope="module")
def fake_predictor_factory(scene):
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    def factory(model, device):
        network, _ = load_network(model, "cpu")
        return Predictor(network, "cpu", detector=TruthDetector(scene.keypoints2d))

    return factory


@pytest.fixture(scope="module")
def photos(tmp_path_factory, scene) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("photos")
    nested = root / "folder" / "inner"
    nested.mkdir(parents=True)
    person = nested / "person.png"
    Image.fromarray(scene.image).save(person)
    blank = root / "folder" / "blank.jpg"
    Image.new("RGB", (200, 300), (128, 128, 128)).save(blank)
    corrupt = root / "folder" / "corrupt.jpg"
    corrupt.write_bytes(b"\xff\xd8\xff\xe0 this is not really a jpeg" * 10)
    (root / "folder" / "notes.md").write_text("not an image, and not picked from the folder")
    text = root / "notes.txt"
    text.write_text("hello")
    return {
        "folder": root / "folder",
        "person": person,
        "blank": blank,
        "corrupt": corrupt,
        "text": text,
        "missing": root / "missing.jpg",
    }


@pytest.fixture(scope="module")
def run_result(tmp_path_factory, photos, checkpoint, fake_predictor_factory):
    out = tmp_path_factory.mktemp("out")
    monkeypatch = pytest.MonkeyPatch()
    monkeypatch.setattr(cli, "load_predictor", fake_predictor_factory)
    import contextlib
    import io

    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = cli.main(
            [str(photos["folder"]), str(photos["missing"]), str(photos["text"]),
             "--out", str(out), "--model", str(checkpoint), "--samples", str(SAMPLES),
             "--format", "ply", "glb", "--format", "obj,npz", "--seed", "3",
             "--uncertainty-samples", "20"]
        )  # fmt: skip
    monkeypatch.undo()
    return {"code": code, "out": out, "stdout": stdout.getvalue(), "stderr": stderr.getvalue()}


def test_failures_are_one_line_each_and_exit_code_is_one(run_result, photos):
    assert run_result["code"] == 1
    stderr = run_result["stderr"]
    assert "Traceback" not in stderr
    failed = [line for line in stderr.splitlines() if "FAILED" in line]
    failed_names = sorted(Path(line.split("FAILED ")[1].split(": ")[0]).name for line in failed)
    assert failed_names == ["blank.jpg", "corrupt.jpg", "missing.jpg", "notes.txt"]
    assert any("no person" in line for line in failed if "blank.jpg" in line)
    assert "notes.md" not in stderr + run_result["stdout"]
    assert "1 of 5 photos done, 4 failed; wrote" in run_result["stdout"]
    # The one detector we have sees one person: no "several people?" hint after every photo.
    assert "several people" not in run_result["stdout"]
    assert not [p for p in run_result["out"].iterdir() if p.name.endswith(".partial")]


def test_files_written(run_result):
    folder = run_result["out"] / "person"
    for fmt in ("ply", "glb", "obj"):
        assert (folder / f"mode.{fmt}").is_file()
        assert (folder / f"mode_uncertainty.{fmt}").is_file()
        assert sorted(p.name for p in (folder / "samples").glob(f"*.{fmt}")) == [
            f"sample_{k:03d}.{fmt}" for k in range(SAMPLES)
        ]
    assert {"overview.png", "prediction.npz", "summary.json", "person_mask.png"} <= {
        p.name for p in folder.iterdir()
    }
    # Failed photos leave no folder behind: only the result folder and the index.
    assert sorted(p.name for p in run_result["out"].iterdir()) == ["index.jsonl", "person"]


def test_the_index_has_a_line_per_photo_with_its_status(run_result, photos):
    lines = (run_result["out"] / "index.jsonl").read_text().splitlines()
    records = {record["photo"]: record for record in map(json.loads, lines)}
    assert len(lines) == 5 and set(records) == {
        "inner/person.png", "blank.jpg", "corrupt.jpg", str(photos["missing"]), str(photos["text"])
    }  # fmt: skip
    person = records["inner/person.png"]
    summary = json.loads((run_result["out"] / "person" / "summary.json").read_text())
    assert person["folder"] == "person" and person["status"] == "ok"
    assert person["quality"] == summary["quality"]["score"]
    assert person["flags"] == summary["quality"]["flags"]
    assert person["sex_probabilities"] == summary["sex_probabilities"]
    assert person["files"] == len(summary["files"]) and person["seconds"] > 0
    assert records["blank.jpg"]["status"] == "no person"
    assert records["corrupt.jpg"]["status"].startswith("error: ")
    assert records["corrupt.jpg"]["quality"] is None and records["corrupt.jpg"]["folder"]


def test_meshes_are_in_the_display_frame_with_uncertainty_colours(run_result):
    folder = run_result["out"] / "person"
    arrays = np.load(folder / "prediction.npz")
    mode = trimesh.load(folder / "mode.ply", process=False)
    assert mode.vertices.shape == (NUM_VERTICES, 3)
    np.testing.assert_allclose(mode.vertices, to_display_frame(arrays["mode_vertices"]), atol=1e-5)
    np.testing.assert_array_equal(mode.faces, arrays["faces"])
    obj = trimesh.load(folder / "mode.obj", process=False)
    assert obj.vertices.shape == (NUM_VERTICES, 3)
    glb = trimesh.load(folder / "mode.glb", force="mesh", process=False)
    assert glb.vertices.shape == (NUM_VERTICES, 3)
    sample = trimesh.load(folder / "samples" / "sample_002.ply", process=False)
    np.testing.assert_allclose(
        sample.vertices, to_display_frame(arrays["sample_vertices"][2]), atol=1e-5
    )
    coloured = trimesh.load(folder / "mode_uncertainty.ply", process=False)
    colours = coloured.visual.vertex_colors[:, :3]
    expected = UncertaintyColourScale().colours_uint8(arrays["uncertainty"].astype(np.float64))
    np.testing.assert_array_equal(colours, expected)


def test_npz_holds_the_distribution(run_result):
    arrays = np.load(run_result["out"] / "person" / "prediction.npz")
    expected = {
        "F": (23, 3, 3), "shape_mean": (10,), "shape_std": (10,), "global_orient": (3, 3),
        "camera": (3,), "crop_centre": (2,), "crop_side": (), "crop_size": (),
        "keypoints": (17, 2), "confidences": (17,), "uncertainty": (NUM_VERTICES,),
        "mode_vertices": (NUM_VERTICES, 3), "mode_keypoints3d": (17, 3),
        "mode_keypoints2d": (17, 2), "sample_vertices": (SAMPLES, NUM_VERTICES, 3),
        "sample_keypoints2d": (SAMPLES, 17, 2), "sample_body_pose": (SAMPLES, 23, 3, 3),
    }  # fmt: skip
    for key, shape in expected.items():
        assert arrays[key].shape == shape, key
    assert int(arrays["crop_size"]) == 64
    assert (arrays["shape_std"] > 0).all()
    assert (arrays["uncertainty"] > 0).all()
    rotation = arrays["global_orient"].astype(np.float64)
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-4)


def test_reprojected_keypoints_round_trip_through_the_crop(run_result, scene):
    folder = run_result["out"] / "person"
    arrays = np.load(folder / "prediction.npz")
    summary = json.loads((folder / "summary.json").read_text())
    crop = CropTransform(
        tuple(summary["crop"]["centre"]), summary["crop"]["side"], summary["crop"]["size"]
    )
    # The crop is the training rule applied to the (true) detected keypoints.
    expected_crop = CropTransform.from_keypoints(scene.keypoints2d, size=64, image_size=(384, 512))
    np.testing.assert_allclose(crop.centre, expected_crop.centre, atol=1e-4)
    assert crop.side == pytest.approx(expected_crop.side, abs=1e-4)
    # Photo pixels -> crop pixels gives back the network's own weak-perspective projection.
    camera = torch.from_numpy(arrays["camera"]).double()[None]
    points = torch.from_numpy(arrays["mode_keypoints3d"]).double()[None]
    in_crop = ndc_to_pixels(weak_perspective_project(points, camera), 64)[0].numpy()
    photo = np.asarray(summary["keypoints"]["mode_reprojected"])
    np.testing.assert_allclose(crop.image_to_crop(photo), in_crop, atol=2e-3)
    np.testing.assert_allclose(crop.crop_to_image(in_crop), photo, atol=2e-2)
    np.testing.assert_allclose(arrays["mode_keypoints2d"], photo, atol=1e-3)


def test_summary_json(run_result, checkpoint, photos):
    summary = json.loads((run_result["out"] / "person" / "summary.json").read_text())
    assert summary["image"] == str(photos["person"])
    assert Path(summary["image_absolute"]) == photos["person"].resolve()
    assert summary["image_size"] == {"width": 384, "height": 512}
    assert len(summary["person"]["detected_bbox"]) == 4
    assert "--bbox" in summary["person"]["note"]
    assert np.asarray(summary["keypoints"]["detected"]).shape == (17, 2)
    assert len(summary["keypoints"]["confidences"]) == 17
    second = summary["keypoints"]["second_reader"]  # MoveNet Thunder's reading (issue 59)
    assert second is not None and np.asarray(second["keypoints"]).shape == (17, 2)
    assert len(second["scores"]) == 17 and len(second["distances"]) == 17
    assert all(0 <= k < 17 for k in second["disputed"])
    uncertainty = np.load(run_result["out"] / "person" / "prediction.npz")["uncertainty"]
    assert summary["uncertainty"]["mean_m"] == pytest.approx(uncertainty.mean(), rel=1e-4)
    assert summary["uncertainty"]["max_m"] == pytest.approx(uncertainty.max(), rel=1e-4)
    assert summary["uncertainty"]["colour_scale"]["maximum_m"] == pytest.approx(0.10)
    assert summary["model"] == str(checkpoint)
    assert summary["samples"] == SAMPLES and summary["seed"] == 3
    assert summary["uncertainty"]["samples"] == 20
    assert "y up" in summary["frames"].lower()
    assert set(summary["timings"]) >= {"predict_s", "sample_s", "overview_s", "total_s"}
    for name in summary["files"]:
        assert (run_result["out"] / "person" / name).is_file(), name
    assert "samples/sample_000.glb" in summary["files"]
    quality = summary["quality"]  # BodyPosterior.quality (hkpd.prediction.quality)
    assert set(quality) == {"score", "flags"} and 0.0 <= quality["score"] <= 1.0
    assert isinstance(quality["flags"], list) and all(isinstance(f, str) for f in quality["flags"])


def test_overview_png(run_result):
    image = np.asarray(Image.open(run_result["out"] / "person" / "overview.png"))
    height, width, channels = image.shape
    assert channels == 3
    assert 480 < height < 600 and 900 < width < 1800
    # The renders contain mesh colours from the viridis ramp, not only background.
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 500


def test_the_person_mask_is_written_in_photo_pixels_and_outlined(run_result, scene):
    folder = run_result["out"] / "person"
    written = np.asarray(Image.open(folder / "person_mask.png"))
    assert written.shape == (512, 384) and written.dtype == np.uint8
    box = np.concatenate([scene.keypoints2d.min(0), scene.keypoints2d.max(0)])
    centre = np.round((box[:2] + box[2:]) / 2).astype(int)
    assert written[centre[1], centre[0]] == 255
    # Bilinear resampling blurs the edge over one mask pixel (box side / 48 photo pixels).
    x0, y0, x1, y1 = box
    blur = int(np.ceil(max(x1 - x0, y1 - y0) / 48)) + 1
    inside = written[int(y0) + blur : int(y1) - blur, int(x0) + blur : int(x1) - blur]
    assert inside.size > 0 and (inside == 255).all()
    outside = np.ones_like(written, bool)
    outside[int(y0) - blur : int(y1) + blur + 1, int(x0) - blur : int(x1) + blur + 1] = False
    assert (written[outside] == 0).all()
    summary = json.loads((folder / "summary.json").read_text())
    assert "person_mask.png" in summary["files"]
    # The overview outlines the mask in its colour.
    from hkpd.prediction.exports.overview import MASK_COLOUR

    overview = np.asarray(Image.open(folder / "overview.png")).astype(int)
    near = np.abs(overview - np.asarray(MASK_COLOUR)).max(axis=-1) < 40
    assert near.sum() > 100


def test_missing_model_exits_2_without_traceback(photos, tmp_path, capsys, fake_predictor_factory,
                                                monkeypatch):  # fmt: skip
    monkeypatch.setattr(cli, "load_predictor", fake_predictor_factory)
    code = cli.main([str(photos["person"]), "--out", str(tmp_path), "--model", "nope.pt"])
    captured = capsys.readouterr()
    assert code == 2
    assert "cannot load the model" in captured.err and "nope.pt" in captured.err
    assert "Traceback" not in captured.err
    assert not any(tmp_path.iterdir())


def test_real_loader_reports_a_missing_model(photos, tmp_path, capsys):
    code = cli.main([str(photos["person"]), "--out", str(tmp_path), "--model", "nope.pt"])
    assert code == 2
    assert "nope.pt" in capsys.readouterr().err


def test_a_silhouette_model_is_refused_with_the_reason(photos, tmp_path, capsys):
    from hkpd.network import DistributionNetwork
    from hkpd.network.checkpoint import save_checkpoint
    from hkpd.network.config import NetworkConfig

    config = NetworkConfig(backbone_base_width=8, image_size=64, image_proxy="silhouette")
    model = save_checkpoint(
        tmp_path / "silhouette.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    out = tmp_path / "out"
    code = cli.main([str(photos["person"]), "--out", str(out), "--model", str(model)])
    assert code == 2
    assert "reads person silhouettes" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


def test_missing_input_only_exits_1(photos, tmp_path, capsys, fake_predictor_factory,
                                    checkpoint, monkeypatch):  # fmt: skip
    monkeypatch.setattr(cli, "load_predictor", fake_predictor_factory)
    code = cli.main([str(photos["missing"]), "--out", str(tmp_path), "--model", str(checkpoint)])
    captured = capsys.readouterr()
    assert code == 1
    assert "missing.jpg" in captured.err and "Traceback" not in captured.err


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--format", "stl"], "--format"),
        (["--bbox", "1", "2", "3"], "--bbox"),
        (["--bbox", "10,10,5,20"], "x1 > x0"),
        (["--samples", "-1"], "--samples"),
        (["--uncertainty-samples", "1"], "--uncertainty-samples"),
    ],
)
def test_usage_errors_exit_2(photos, tmp_path, capsys, arguments, message):
    code = cli.main([str(photos["person"]), "--out", str(tmp_path), *arguments])
    assert code == 2
    assert message in capsys.readouterr().err


def test_an_unusable_out_is_one_line_before_the_model_loads(photos, tmp_path, capsys, monkeypatch):
    def no_model(*_):
        raise AssertionError("the model was loaded")

    monkeypatch.setattr(cli, "load_predictor", no_model)
    a_file = tmp_path / "results.txt"
    a_file.write_text("keep me")
    for out, message in ((a_file, "is a file"), (a_file / "sub", f"is below the file {a_file}")):
        code = cli.main([str(photos["person"]), "--out", str(out)])
        err = capsys.readouterr().err
        assert code == 2 and message in err and "Traceback" not in err
        assert [line for line in err.splitlines() if "error" in line] == [
            next(line for line in err.splitlines() if message in line)
        ]
    assert a_file.read_text() == "keep me"
    monkeypatch.setattr(cli.os, "access", lambda path, mode: False)  # as for a non-root user
    code = cli.main([str(photos["person"]), "--out", str(tmp_path / "new" / "deeper")])
    assert code == 2 and f"cannot write in {tmp_path}" in capsys.readouterr().err


def test_bbox_reaches_the_detector(photos, tmp_path, checkpoint, scene, monkeypatch, capsys):
    detectors = []

    def factory(model, device):
        predictor = cli_factory(model, device)
        detectors.append(predictor.detector)
        return predictor

    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    def cli_factory(model, device):
        network, _ = load_network(model, "cpu")
        return Predictor(network, "cpu", detector=TruthDetector(scene.keypoints2d))

    monkeypatch.setattr(cli, "load_predictor", factory)
    code = cli.main(
        [str(photos["person"]), "--out", str(tmp_path), "--model", str(checkpoint),
         "--samples", "0", "--format", "npz", "--bbox", "100,120", "290", "480",
         "--uncertainty-samples", "2"]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert detectors[0].calls == [(100.0, 120.0, 290.0, 480.0)]
    summary = json.loads((tmp_path / "person" / "summary.json").read_text())
    assert summary["person"]["search_bbox"] == [100.0, 120.0, 290.0, 480.0]
    assert not list(tmp_path.glob("person/*.ply"))
    assert "sample_vertices" not in np.load(tmp_path / "person" / "prediction.npz")


@pytest.fixture(autouse=True)
def autograd_stays_on():
    """hkpd-predict's main() runs without autograd but must hand it back to its caller."""
    yield
    assert torch.is_grad_enabled()


@pytest.mark.parametrize("flags, source", [([], "evidence"), (["--no-evidence"], "network")])
def test_summary_says_which_posterior_was_written(
    photos, tmp_path, checkpoint, fake_predictor_factory, monkeypatch, capsys, flags, source
):
    monkeypatch.setattr(cli, "load_predictor", fake_predictor_factory)
    code = cli.main(
        [str(photos["person"]), "--out", str(tmp_path), "--model", str(checkpoint),
         "--samples", "0", "--format", "npz", "--uncertainty-samples", "2", *flags]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    posterior = json.loads((tmp_path / "person" / "summary.json").read_text())["posterior"]
    assert posterior["source"] == source
    assert posterior["evidence_requested"] is (not flags)
    assert posterior["fallback_reason"] is None
    assert len(posterior["evidence_keypoints"]) >= 4
    assert ("fit" in posterior) is (source == "evidence")


def test_evidence_false_returns_the_networks_own_output_and_evidence_keeps_it(
    scene, checkpoint, fake_predictor_factory
):
    predictor = fake_predictor_factory(checkpoint, "cpu")
    network_only = predictor.predict(scene.image, evidence=False)
    with torch.no_grad():
        direct = predictor.reading.network(network_only.network_input.proxy[None])
    assert network_only.source == "network" and network_only.evidence_fit is None
    torch.testing.assert_close(network_only.F, direct.F[0], rtol=0, atol=0)
    torch.testing.assert_close(network_only.camera, direct.camera[0], rtol=0, atol=0)
    conditioned = predictor.predict(scene.image)
    assert conditioned.source == "evidence" and conditioned.prior is not None
    torch.testing.assert_close(conditioned.prior.F, network_only.F, rtol=0, atol=0)
    assert torch.isfinite(conditioned.F).all() and not torch.equal(conditioned.F, network_only.F)


def test_the_predictor_keeps_the_reading_of_the_crop_or_of_its_mirror_image(scene, checkpoint):
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor
    from hkpd.prediction.readings import ReadingConfig
    from hkpd.prediction.readings.mirror import mirror_proxy, unmirror_output

    network, _ = load_network(checkpoint, "cpu")
    detector = TruthDetector(scene.keypoints2d, confidences=np.ones(17))
    once = Predictor(network, "cpu", detector=detector, reading_config=ReadingConfig(mirror=False))
    twice = Predictor(network, "cpu", detector=detector)
    read_once = once.predict(scene.image, evidence=False)
    read_twice = twice.predict(scene.image, evidence=False)
    assert not read_once.mirror_read
    proxy = read_once.network_input.proxy[None]
    with torch.no_grad():
        direct, mirrored = network(proxy), unmirror_output(network(mirror_proxy(proxy)))
    torch.testing.assert_close(read_once.F, direct.F[0], rtol=0, atol=0)
    kept = mirrored if read_twice.mirror_read else direct
    assert read_twice.mirror_read == bool(twice.reading.network.last_mirrored[0])
    torch.testing.assert_close(read_twice.F, kept.F[0], rtol=1e-5, atol=1e-4)
    torch.testing.assert_close(read_twice.camera, kept.camera[0], rtol=1e-5, atol=1e-6)
    # The evidence posterior records which reading its fit started from.
    conditioned = twice.predict(scene.image)
    assert conditioned.mirror_read == conditioned.prior.mirror_read == read_twice.mirror_read


def test_too_little_evidence_falls_back_to_the_network_and_says_why(
    scene, checkpoint, fake_predictor_factory
):
    from hkpd.conditioning import EvidenceConfig

    predictor = fake_predictor_factory(checkpoint, "cpu")
    predictor.evidence_config = EvidenceConfig(min_keypoints=17)
    posterior = predictor.predict(scene.image)
    assert posterior.source == "network"
    assert (
        posterior.fallback_reason is not None and "needs at least 17" in posterior.fallback_reason
    )
    reference = predictor.predict(scene.image, evidence=False)
    torch.testing.assert_close(posterior.F, reference.F, rtol=0, atol=0)


def test_an_occluder_removes_its_keypoints_from_the_evidence_not_from_the_detection(
    scene, checkpoint, fake_predictor_factory
):
    predictor = fake_predictor_factory(checkpoint, "cpu")
    knee, ankle = scene.keypoints2d[14], scene.keypoints2d[16]  # right lower leg
    pad = 6.0
    box = (min(knee[0], ankle[0]) - pad, min(knee[1], ankle[1]) - pad,
           max(knee[0], ankle[0]) + pad, max(knee[1], ankle[1]) + pad)  # fmt: skip
    clean = predictor.predict(scene.image)
    covered = predictor.predict(scene.image, occluders=[box])
    assert clean.evidence[[14, 16]].all() and not covered.evidence[[14, 16]].any()
    assert covered.evidence.sum() == clean.evidence.sum() - 2
    assert covered.source == "evidence"
    # the detector saw the same photo both times: its raw keypoints did not move
    np.testing.assert_array_equal(
        covered.network_input.detection.keypoints, clean.network_input.detection.keypoints
    )
    assert not covered.network_input.proxy[1 + 16].any()  # no heatmap for the hidden ankle


def test_fit_overlay_draws_the_mode_where_its_keypoints_reproject(
    scene, checkpoint, fake_predictor_factory
):
    from hkpd.prediction.exports.fit_overlay import render_fit_overlay

    posterior = fake_predictor_factory(checkpoint, "cpu").predict(scene.image)
    overlay = render_fit_overlay(posterior, size=200)
    assert overlay.rgba.shape == (200, 200, 4) and overlay.box == posterior.crop.box
    alpha = overlay.rgba[..., 3]
    assert 0.02 < (alpha > 0).mean() < 0.9
    x0, y0, x1, _ = overlay.box
    torso = posterior.mode().keypoints2d[0, [5, 6, 11, 12]].numpy()
    pixels = np.floor((torso - [x0, y0]) / (x1 - x0) * 200).astype(int)
    assert all(alpha[v, u] > 0 for u, v in pixels)  # shoulders and hips fall on the body
    assert (overlay.with_opacity(0.5)[..., 3].max()) == 128


def test_existing_results_are_refused_unless_overwrite_replaces_them(
    photos, tmp_path, checkpoint, fake_predictor_factory, monkeypatch, capsys
):
    monkeypatch.setattr(cli, "load_predictor", fake_predictor_factory)
    flags = [str(photos["person"]), "--out", str(tmp_path), "--model", str(checkpoint),
             "--samples", "2", "--format", "ply", "--uncertainty-samples", "2"]  # fmt: skip
    assert cli.main(flags) == 0
    folder = tmp_path / "person"
    stale = folder / "samples" / "sample_009.ply"
    stale.write_text("an old file")
    capsys.readouterr()
    assert cli.main(flags) == 2  # nothing the user has is overwritten silently
    assert "--overwrite" in capsys.readouterr().err and stale.exists()
    assert cli.main([*flags, "--overwrite"]) == 0
    assert not stale.exists()  # the old results went, the new ones are all that is there
    summary = json.loads((folder / "summary.json").read_text())
    on_disk = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    assert sorted(summary["files"]) == on_disk
    assert cli.main([str(photos["blank"]), "--out", str(tmp_path / "b"), "--model",
                     str(checkpoint)]) == 1  # fmt: skip
    assert "nothing written" in capsys.readouterr().out
    assert not (tmp_path / "b" / "blank").exists()  # a failed photo leaves no folder


class ConstantOrientation(torch.nn.Module):
    """A network whose global rotation is always the identity (the rest is the wrapped one's)."""

    def __init__(self, network: torch.nn.Module) -> None:
        super().__init__()
        self.network, self.config = network, network.config

    def forward(self, proxy: torch.Tensor):
        from dataclasses import replace

        output = self.network(proxy)
        return replace(output, global_orient=torch.eye(3).expand(proxy.shape[0], 3, 3).clone())


def test_a_lying_person_is_read_by_the_network_from_an_upright_copy(scene, checkpoint):
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    height = scene.image.shape[0]
    lying = np.ascontiguousarray(np.rot90(scene.image, k=-1))  # turned 90° clockwise
    u, v = scene.keypoints2d[:, 0], scene.keypoints2d[:, 1]
    keypoints = np.stack([height - 1 - v, u], -1)
    network, _ = load_network(checkpoint, "cpu")
    detector = TruthDetector(keypoints, confidences=np.ones(17))
    predictor = Predictor(ConstantOrientation(network), "cpu", detector=detector)

    as_is = predictor.predict(lying, evidence=False, upright=False)
    assert as_is.upright_tilt_degrees is None
    torch.testing.assert_close(as_is.global_orient, torch.eye(3), rtol=0, atol=0)
    read_upright = predictor.predict(lying, evidence=False)
    assert read_upright.source == "network"
    assert abs(abs(read_upright.upright_tilt_degrees) - 90.0) < 10.0
    # The copy's answer (identity) comes back turned about the optical axis by the lean.
    rotation = read_upright.global_orient.double()
    turned = math.degrees(math.atan2(float(rotation[1, 0]), float(rotation[0, 0])))
    assert abs(turned - read_upright.upright_tilt_degrees) < 1e-3, turned
    assert abs(float(rotation[2, 2]) - 1.0) < 1e-5
    # An upright person is read as is.
    predictor.detector = TruthDetector(scene.keypoints2d, confidences=np.ones(17))
    standing = predictor.predict(scene.image, evidence=False)
    assert standing.upright_tilt_degrees is None
    torch.testing.assert_close(standing.global_orient, torch.eye(3), rtol=0, atol=0)


def test_without_a_torso_in_the_evidence_the_lean_is_the_one_that_fits_what_is_shown(scene):
    from limb_lean_network import LimbLeanNetwork

    from hkpd.prediction.predictor import Predictor

    height = scene.image.shape[0]
    lying = np.ascontiguousarray(np.rot90(scene.image, k=-1))  # turned 90° clockwise
    u, v = scene.keypoints2d[:, 0], scene.keypoints2d[:, 1]
    keypoints = np.stack([height - 1 - v, u], -1)
    limbs_only = np.zeros(17)
    limbs_only[[7, 8, 9, 10, 15, 16]] = 1.0  # elbows, wrists, ankles: no torso, no stand-in
    network = LimbLeanNetwork(64, reads_within_degrees=40.0)  # reads lying people as upright
    predictor = Predictor(network, "cpu", detector=TruthDetector(keypoints, limbs_only))

    read = predictor.predict(lying, evidence=False)
    assert abs(read.upright_tilt_degrees - 90.0) <= 40.0, read.upright_tilt_degrees
    assert abs(network.leans[-1][-1]) <= 40.0  # the copy read showed the person near upright
    rotation = read.global_orient.double()
    turned = math.degrees(math.atan2(float(rotation[1, 0]), float(rotation[0, 0])))
    assert abs(abs(turned) - 90.0) < 10.0  # the upright answer, mapped back: lying
    as_is = predictor.predict(lying, evidence=False, upright=False)
    assert as_is.upright_tilt_degrees is None
    predictor.detector = TruthDetector(scene.keypoints2d, limbs_only)
    standing = predictor.predict(scene.image, evidence=False).global_orient.double()
    # Whichever copy fits best, the standing person comes back standing.
    assert abs(math.degrees(math.atan2(float(standing[1, 0]), float(standing[0, 0])))) < 10.0
