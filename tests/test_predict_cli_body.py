"""``hkpd-predict --sex/--height/--mass ...``: what the user knows of the body, and what the files
say about it (the sex's probabilities, the measurements with stds, what was stated).

Same set-up as ``test_predict_cli.py`` (a rendered photo, a fake detector returning its true
keypoints, a tiny untrained network saved as a real checkpoint); two runs serve all the tests
that need one.
"""

from __future__ import annotations

import json
import shutil
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from PIL import Image
from test_predict_cli import checkpoint, fake_predictor_factory, scene  # noqa: F401 (fixtures)

from hkpd.body.measurements import MEASUREMENT_NAMES
from hkpd.body_flags import stated_body
from hkpd.prediction import cli
from hkpd.prediction.exports.body_summary import body_caption, sex_statement
from hkpd.prediction.exports.overview import BACKGROUND
from hkpd.prediction.quality import ReadingQuality
from hkpd.prediction.sex_latent import SexEvidence, SexShapes

STATED = ["--sex", "male", "--height", "1.85", "--mass", "80", "2"]


def _run(arguments, monkeypatch, factory):
    """``hkpd-predict arguments`` with ``factory`` as the model loader; the exit code and the
    captured stderr."""
    import contextlib
    import io

    monkeypatch.setattr(cli, "load_predictor", factory)
    stderr = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(stderr):
        code = cli.main([str(a) for a in arguments])
    return code, stderr.getvalue()


@pytest.fixture(scope="module")
def runs(tmp_path_factory, scene, checkpoint, fake_predictor_factory):  # noqa: F811
    """One photo with nothing stated ("auto") and with ``--no-evidence`` ("network"), and two
    copies of it with ``STATED`` and ``--same-person`` ("stated")."""
    root = tmp_path_factory.mktemp("body")
    photo = root / "photos" / "person.png"
    photo.parent.mkdir()
    Image.fromarray(scene.image).save(photo)
    shutil.copy(photo, photo.with_name("again.png"))
    common = ["--model", checkpoint, "--samples", "1", "--uncertainty-samples", "4", "--format",
              "npz"]  # fmt: skip
    monkeypatch = pytest.MonkeyPatch()
    codes = {
        "auto": _run([photo, "--out", root / "auto", *common], monkeypatch,
                     fake_predictor_factory)[0],
        "network": _run([photo, "--out", root / "network", *common, "--no-evidence"],
                        monkeypatch, fake_predictor_factory)[0],
        "stated": _run([photo, photo.with_name("again.png"), "--out", root / "stated", *common,
                        "--same-person", *STATED], monkeypatch, fake_predictor_factory)[0],
    }  # fmt: skip
    monkeypatch.undo()
    return {"root": root, "codes": codes}


def _summary(runs, name: str, photo: str = "person") -> dict:
    return json.loads((runs["root"] / name / photo / "summary.json").read_text())


def test_the_flags_are_parsed_into_what_is_stated():
    args = cli.build_parser().parse_args(
        ["a.jpg", "--out", "r", "--sex", "female", "--height", "1.62", "--mass", "55", "1.5",
         "--shoulder-width", "0.36"]
    )  # fmt: skip
    stated = stated_body(args)
    assert stated.sex == "female"
    assert dict(stated.measurements) == {
        "height_m": (1.62, 0.01),  # the default std
        "mass_kg": (55.0, 1.5),
        "shoulder_width_m": (0.36, 0.01),
    }
    nothing = stated_body(cli.build_parser().parse_args(["a.jpg", "--out", "r"]))
    assert nothing.empty


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--height", "5"], "--height 5: '5' is not plausible (height_m = 5 m is outside"),
        (["--mass", "eighty"], "--mass eighty: not a number"),
        (["--waist", "0.8", "0.02", "3"], "--waist 0.8 0.02 3: give a value in metres"),
        (["--height", "1.8", "-0.01"], "height_m's std must be > 0"),
        (["--hip", "nan"], "--hip nan: not a number"),
        (["--mass", "80cm"], "give mass in kg"),
        (["--sex", "male", "--mass", "70", "--no-evidence"], "--sex --mass condition the body"),
    ],
)
def test_bad_body_flags_are_usage_errors_before_the_model_loads(
    tmp_path, capsys, monkeypatch, arguments, message
):
    def no_model(*_):
        raise AssertionError("the model was loaded")

    monkeypatch.setattr(cli, "load_predictor", no_model)
    code = cli.main(["photo.jpg", "--out", str(tmp_path / "out"), *arguments])
    error = capsys.readouterr().err
    assert code == 2
    assert message in error and "usage: hkpd-predict" in error and "Traceback" not in error
    assert not (tmp_path / "out").exists()


def test_an_unknown_sex_is_refused_by_argparse(tmp_path, capsys):
    with pytest.raises(SystemExit) as stopped:
        cli.main(["photo.jpg", "--out", str(tmp_path), "--sex", "other"])
    assert stopped.value.code == 2
    assert "invalid choice: 'other'" in capsys.readouterr().err


def test_a_body_without_sex_priors_is_refused_once(tmp_path, monkeypatch):
    closed = []
    predictor = SimpleNamespace(
        body=SimpleNamespace(has_sex_priors=False), close=lambda: closed.append(True)
    )
    code, error = _run(
        ["photo.jpg", "--out", tmp_path / "out", "--height", "1.7"],
        monkeypatch,
        lambda model, device: predictor,
    )
    assert code == 2 and closed == [True]
    assert "no sex-specific shape priors" in error and "--sex" in error


def test_the_summary_says_the_sexes_and_the_measurements(runs):
    assert runs["codes"]["auto"] == 0
    summary = _summary(runs, "auto")
    probabilities = summary["sex_probabilities"]
    assert set(probabilities) == {"female", "male"}
    assert all(0.0 <= p <= 1.0 for p in probabilities.values())
    assert probabilities["female"] + probabilities["male"] == pytest.approx(1.0, abs=1e-5)
    assert summary["drawn_sex"] == max(probabilities, key=probabilities.get)
    assert summary["stated"] is None
    measurements = summary["measurements"]
    assert list(measurements) == list(MEASUREMENT_NAMES)
    assert all(set(item) == {"mean", "std"} and item["std"] > 0 for item in measurements.values())
    assert 1.2 < measurements["height_m"]["mean"] < 2.2
    assert 30 < measurements["mass_kg"]["mean"] < 150


def test_the_npz_holds_each_sexs_shape_and_probability(runs):
    summary = _summary(runs, "auto")
    arrays = np.load(runs["root"] / "auto" / "person" / "prediction.npz")
    assert list(arrays["sex_names"]) == ["female", "male"]
    np.testing.assert_allclose(
        arrays["sex_probabilities"],
        [summary["sex_probabilities"]["female"], summary["sex_probabilities"]["male"]],
        atol=1e-5,
    )
    assert arrays["sex_shape_means"].shape == (2, 10)
    covariances = arrays["sex_shape_covariances"]
    assert covariances.shape == (2, 10, 10)
    np.testing.assert_allclose(covariances, covariances.transpose(0, 2, 1), atol=1e-6)
    assert (np.linalg.eigvalsh(covariances.astype(np.float64)) > 0).all()
    # The distribution's own shape is the drawn sex's.
    drawn = ["female", "male"].index(summary["drawn_sex"])
    np.testing.assert_allclose(arrays["shape_mean"], arrays["sex_shape_means"][drawn], atol=1e-5)
    assert list(arrays["measurement_names"]) == list(MEASUREMENT_NAMES)
    np.testing.assert_allclose(
        arrays["measurement_mean"],
        [summary["measurements"][name]["mean"] for name in MEASUREMENT_NAMES],
        rtol=1e-5,
    )
    assert not bool(arrays["sex_stated"])


def test_stated_values_reach_the_posterior_and_are_reported(runs):
    assert runs["codes"]["stated"] == 0
    summary = _summary(runs, "stated")
    assert summary["sex_probabilities"] == {"female": 0.0, "male": 1.0}
    assert summary["drawn_sex"] == "male"
    assert summary["stated"] == {
        "sex": "male",
        "measurements": {
            "height_m": {"value": 1.85, "std": 0.01},
            "mass_kg": {"value": 80.0, "std": 2.0},
        },
    }
    height, mass = summary["measurements"]["height_m"], summary["measurements"]["mass_kg"]
    assert abs(height["mean"] - 1.85) < 0.015 and height["std"] <= 0.0105
    assert abs(mass["mean"] - 80.0) < 3.0 and mass["std"] <= 2.05
    arrays = np.load(runs["root"] / "stated" / "person" / "prediction.npz")
    assert bool(arrays["sex_stated"])
    np.testing.assert_array_equal(arrays["sex_probabilities"], [0.0, 1.0])
    assert np.isnan(arrays["sex_shape_means"][0]).all()  # the female shape was not fitted
    assert np.isfinite(arrays["sex_shape_means"][1]).all()


def test_the_same_person_shape_counts_the_stated_values_once(runs):
    folder = runs["root"] / "stated" / "same_person_shape"
    shape = json.loads((folder / "shape.json").read_text())
    assert shape["count"] == 2
    assert shape["photo_sex_probabilities"] == [{"female": 0.0, "male": 1.0}] * 2
    assert shape["sex_probabilities"] == {"female": 0.0, "male": 1.0}
    assert shape["drawn_sex"] == "male" and shape["stated"]["sex"] == "male"
    assert "counted once" in shape["method"]
    assert list(shape["measurements"]) == list(MEASUREMENT_NAMES)
    photo = _summary(runs, "stated")["measurements"]
    height, mass = shape["measurements"]["height_m"], shape["measurements"]["mass_kg"]
    # Two copies of one photo: the stated height (1 cm) and mass (2 kg) count once, not twice
    # (which would give 0.71 cm and 1.41 kg); what the photos alone say is halved in variance.
    assert abs(height["mean"] - 1.85) < 0.015 and 0.008 < height["std"] <= 0.0105
    assert abs(mass["mean"] - 80.0) < 3.0 and 1.6 < mass["std"] <= 2.05
    assert shape["measurements"]["chest_m"]["std"] < photo["chest_m"]["std"]
    arrays = np.load(folder / "shape.npz")
    np.testing.assert_array_equal(arrays["sex_probabilities"], [0.0, 1.0])
    assert arrays["sex_shape_covariances"].shape == (2, 10, 10)
    np.testing.assert_allclose(arrays["betas_mean"], arrays["sex_shape_means"][1], atol=1e-5)
    np.testing.assert_allclose(
        arrays["measurement_mean"],
        [shape["measurements"][name]["mean"] for name in MEASUREMENT_NAMES],
        rtol=1e-5,
    )


def test_the_networks_own_posterior_has_no_sexes_but_measurements(runs):
    assert runs["codes"]["network"] == 0
    summary = _summary(runs, "network")
    assert summary["posterior"]["source"] == "network"
    assert summary["sex_probabilities"] is None and summary["drawn_sex"] is None
    assert summary["stated"] is None
    assert list(summary["measurements"]) == list(MEASUREMENT_NAMES)
    assert all(item["std"] > 0 for item in summary["measurements"].values())
    arrays = np.load(runs["root"] / "network" / "person" / "prediction.npz")
    assert "sex_probabilities" not in arrays.files and "measurement_mean" in arrays.files


def test_the_overview_footer_has_a_line_about_the_body(runs):
    folder = runs["root"] / "auto" / "person"
    image = np.asarray(Image.open(folder / "overview.png"))
    quality = json.loads((folder / "summary.json").read_text())["quality"]
    warned = ReadingQuality(quality["score"], tuple(quality["flags"]), {}).low  # a red 3rd line
    # 480 px panels, a 30 px title row and two 26 px footer rows (one without the body line).
    assert image.shape[0] == 480 + 30 + (3 if warned else 2) * 26
    dark = np.abs(image.astype(int) - np.asarray(BACKGROUND)).max(-1) > 120
    right = slice(image.shape[1] // 2, None)
    assert dark[510:536, right].sum() > 100  # the body line
    assert dark[536:562, right].sum() > 100  # the uncertainty and run line
    if warned:
        red = (image[562:588, right, 0] > 150) & (image[562:588, right, 1] < 90)
        assert red.sum() > 50  # the quality warning


@pytest.mark.parametrize(
    "probabilities, stated, measurements, expected",
    [
        ({"female": 0.13, "male": 0.87}, False, {"height_m": (1.781, 0.052),
         "mass_kg": (73.4, 6.2)}, "body: male 87 %, height 1.78 ± 0.05 m, mass 73 ± 6 kg"),
        ({"female": 0.0, "male": 1.0}, True, {"height_m": (1.85, 0.0099)},
         "body: male (stated), height 1.85 ± 0.01 m"),
        ({"female": 0.998, "male": 0.002}, False, {"mass_kg": (58.04, 0.4)},
         "body: female > 99 %, mass 58.0 ± 0.4 kg"),
        ({"female": 0.5, "male": 0.5}, False, {}, "body: female 50 %"),
        (None, False, {"height_m": (1.7, 0.003)}, "body: height 1.700 ± 0.003 m"),
        (None, False, {}, ""),
    ],
)  # fmt: skip
def test_the_body_caption(probabilities, stated, measurements, expected):
    assert body_caption(probabilities, stated, measurements) == expected


def _sexes(p_male: float, face: float | None, stated: bool = False, doubted: bool = False):
    means = {"female": torch.zeros(10), "male": torch.ones(10)}
    covariances = {sex: torch.eye(10) for sex in means}
    evidence = None if stated else SexEvidence(keypoints=0.41, face=face)
    probabilities = {"female": 1 - p_male, "male": p_male}
    return SexShapes(probabilities, means, covariances, stated, evidence=evidence,
                     doubted=doubted)  # fmt: skip


@pytest.mark.parametrize(
    "sexes, expected",
    [
        (_sexes(0.96, 0.98), "male 96 % from the face"),
        (_sexes(0.85, None), "male 85 % from the body's proportions"),
        (_sexes(0.42, None), "not sure (female 58 % from the body's proportions)"),
        (_sexes(0.93, 0.97, doubted=True),
         "not sure (male 93 % from the face, but this reading is in doubt)"),
        (_sexes(1.0, None, stated=True), "male (stated)"),
        (None, None),
    ],
)  # fmt: skip
def test_the_sex_says_where_it_came_from(sexes, expected):
    assert sex_statement(sexes) == expected
    if sexes is not None:
        caption = body_caption(sexes.probabilities, sexes.stated, {}, sex_statement(sexes))
        assert caption == f"body: {expected}"


def test_the_stated_body_flags_are_listed_in_the_help(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    shown = capsys.readouterr().out
    for flag in ("--sex", "--height", "--mass", "--chest", "--waist", "--hip", "--shoulder-width"):
        assert flag in shown


def test_a_height_in_centimetres_is_read_as_such_with_a_note(capsys):
    """Issue 58: the explorer's Body fields take cm, the flags metres; both read both: a bare
    length too large for metres is centimetres (a note says so), and units may be typed."""
    from hkpd.body_flags import stated_body

    parser = cli.build_parser()
    for flags, expected in (
        (["--height", "182"], (1.82, 0.01)),
        (["--height", "182cm", "2cm"], (1.82, 0.02)),
        (["--height", "1.82", "m"], (1.82, 0.01)),  # "1.82 m": a unit, not a std
        (["--height", "1.82", "x"], None),
        (["--waist", "80", "2"], (0.8, 0.02)),
        (["--height", "1.82"], (1.82, 0.01)),
    ):
        args = parser.parse_args(["a.jpg", "--out", "r", *flags])
        if expected is None:  # neither a std nor a unit
            with pytest.raises(ValueError, match="not a number"):
                stated_body(args)
            continue
        name = "waist_m" if "--waist" in flags else "height_m"
        assert stated_body(args).measurements[name] == pytest.approx(expected), flags
    notes = capsys.readouterr().err
    assert "note: --height 182 read as centimetres: 1.82 m" in notes
    assert "note: --waist 80 read as centimetres: 0.8 m" in notes
    assert "1.82 read as" not in notes  # metres and typed units need no note
