"""hkpd-predict --all-people: one folder per person, larger people first (issue 51)."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json

import numpy as np
import pytest
from PIL import Image
from test_predict_cli import TruthDetector, checkpoint, scene  # noqa: F401 (fixtures)

from hkpd.prediction import cli


class TwoPeopleDetector(TruthDetector):
    """The truth detector, listing two people: a small one first, then the real one."""

    def detect_all(self, image):
        real = self.detect(image)
        small_box = np.asarray(real.person_box, np.float64) * 0.25
        small = dataclasses.replace(real, person_box=small_box)
        return [small, real] if np.asarray(image if isinstance(image, np.ndarray) else
                                           Image.open(image)).std() > 1 else []  # fmt: skip


def _run(arguments, factory, monkeypatch):
    monkeypatch.setattr(cli, "load_predictor", factory)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main([str(a) for a in arguments])
    return code, out.getvalue(), err.getvalue()


def test_all_people_writes_a_folder_per_person_larger_first(
    tmp_path, scene, checkpoint, monkeypatch  # noqa: F811
) -> None:  # fmt: skip
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    def factory(model, device):
        network, _ = load_network(model, "cpu")
        return Predictor(network, "cpu", detector=TwoPeopleDetector(scene.keypoints2d))

    photo = tmp_path / "group.png"
    Image.fromarray(scene.image).save(photo)
    blank = tmp_path / "blank.png"
    Image.new("RGB", (200, 300), (128, 128, 128)).save(blank)
    common = ["--model", checkpoint, "--samples", "0", "--uncertainty-samples", "4",
              "--format", "npz", "--all-people"]  # fmt: skip
    code, _, err = _run([photo, blank, "--out", tmp_path / "out", *common], factory, monkeypatch)
    assert code == 1 and "FAILED" in err and "blank.png" in err and "no person" in err
    folders = sorted(p.name for p in (tmp_path / "out" / "group").iterdir())
    assert folders == ["person_1", "person_2"]
    first = json.loads((tmp_path / "out" / "group" / "person_1" / "summary.json").read_text())
    second = json.loads((tmp_path / "out" / "group" / "person_2" / "summary.json").read_text())
    width = lambda s: s["person"]["search_bbox"][2] - s["person"]["search_bbox"][0]  # noqa: E731
    assert width(first) > 3 * width(second)  # the larger person first


@pytest.mark.parametrize("extra", [["--bbox", "0", "0", "9", "9"], ["--same-person"]])
def test_all_people_refuses_one_person_options(tmp_path, extra, capsys) -> None:
    assert cli.main(["photo.jpg", "--out", str(tmp_path / "o"), "--all-people", *extra]) == 2
    assert "--all-people predicts every person" in capsys.readouterr().err


def test_turn_around_writes_the_turned_reading(
    tmp_path, scene, checkpoint, monkeypatch, capsys  # noqa: F811
) -> None:  # fmt: skip
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    def factory(model, device):
        network, _ = load_network(model, "cpu")
        return Predictor(network, "cpu", detector=TruthDetector(scene.keypoints2d))

    photo = tmp_path / "person.png"
    Image.fromarray(scene.image).save(photo)
    common = ["--model", checkpoint, "--samples", "0", "--uncertainty-samples", "4",
              "--format", "npz"]  # fmt: skip
    summaries = {}
    for name, extra in (("as_read", []), ("turned", ["--turn-around"])):
        code, _, _ = _run([photo, "--out", tmp_path / name, *common, *extra], factory, monkeypatch)
        assert code == 0
        summary = json.loads((tmp_path / name / "person" / "summary.json").read_text())
        summaries[name] = summary["posterior"]
    assert not summaries["as_read"]["turned_around"] and summaries["turned"]["turned_around"]
    args = ["photo.jpg", "--out", str(tmp_path / "o"), "--turn-around", "--no-evidence"]
    assert cli.main(args) == 2
    assert "--turn-around refits" in capsys.readouterr().err
