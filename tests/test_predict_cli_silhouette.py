"""``hkpd-predict --silhouette-evidence``: the person mask joins the keypoints in the fit, and
summary.json and the console say which evidence each photo's fit weighed.

Same set-up as ``test_predict_cli.py`` (a rendered photo, a fake detector returning its true
keypoints and a box-shaped mask, a tiny untrained network saved as a real checkpoint).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from PIL import Image
from test_predict_cli import (  # noqa: F401 (fixtures)
    TruthDetector,
    checkpoint,
    fake_predictor_factory,
    scene,
)

from hkpd.prediction import cli


@pytest.fixture()
def photo(tmp_path, scene):  # noqa: F811 (the imported fixture)
    path = tmp_path / "person.png"
    Image.fromarray(scene.image).save(path)
    return path


def _predict(photo, out, checkpoint, factory, monkeypatch, *flags):  # noqa: F811
    monkeypatch.setattr(cli, "load_predictor", factory)
    arguments = [photo, "--out", out, "--model", checkpoint, "--samples", "0", "--format", "npz",
                 "--uncertainty-samples", "4", *flags]  # fmt: skip
    code = cli.main([str(a) for a in arguments])
    summary = json.loads((out / "person" / "summary.json").read_text()) if code == 0 else None
    return code, summary


def test_the_mask_is_weighed_only_when_asked_and_summary_says_so(
    photo,
    tmp_path,
    checkpoint,  # noqa: F811
    fake_predictor_factory,  # noqa: F811
    monkeypatch,
    capsys,
) -> None:
    code, plain = _predict(photo, tmp_path / "a", checkpoint, fake_predictor_factory, monkeypatch)
    assert code == 0
    assert plain["posterior"]["silhouette_requested"] is False
    assert plain["posterior"]["fit"]["terms"] == ["keypoints"]
    code, masked = _predict(photo, tmp_path / "b", checkpoint, fake_predictor_factory,
                            monkeypatch, "--silhouette-evidence")  # fmt: skip
    assert code == 0
    assert masked["posterior"]["silhouette_requested"] is True
    assert masked["posterior"]["fit"]["terms"] == ["keypoints", "silhouette"]
    assert "silhouette_note" not in masked["posterior"]
    shapes = [np.load(tmp_path / run / "person" / "prediction.npz")["shape_mean"] for run in "ab"]
    assert not np.array_equal(*shapes)  # the mask moved the fit
    assert "keypoints only" not in capsys.readouterr().out


def test_without_a_mask_the_photo_says_keypoints_only(
    photo,
    tmp_path,
    checkpoint,  # noqa: F811
    scene,  # noqa: F811
    monkeypatch,
    capsys,
) -> None:
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    class MasklessDetector(TruthDetector):
        def detect(self, image, bbox=None):
            return dataclasses.replace(super().detect(image, bbox), person_mask=None)

    def factory(model, device):
        network, _ = load_network(model, "cpu")
        return Predictor(network, "cpu", detector=MasklessDetector(scene.keypoints2d))

    code, summary = _predict(photo, tmp_path / "out", checkpoint, factory, monkeypatch,
                             "--silhouette-evidence")  # fmt: skip
    assert code == 0
    assert summary["posterior"]["fit"]["terms"] == ["keypoints"]
    assert "no person mask" in summary["posterior"]["silhouette_note"]
    assert "[no person mask: keypoints only" in capsys.readouterr().out


def test_silhouette_with_no_evidence_is_a_usage_error(
    photo,
    tmp_path,
    checkpoint,  # noqa: F811
    fake_predictor_factory,  # noqa: F811
    monkeypatch,
    capsys,
) -> None:
    code, _ = _predict(photo, tmp_path / "out", checkpoint, fake_predictor_factory, monkeypatch,
                       "--silhouette-evidence", "--no-evidence")  # fmt: skip
    assert code == 2
    assert "--silhouette-evidence" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
