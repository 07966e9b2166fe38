"""The explorer's Body section: the sex with its probability and a menu to state it, the
measurements with ± and fields to state them, the look of the drawn body; what is stated
reaches the provider (and the keys posteriors are kept under), bad input changes nothing.

Driven by a test double of a provider that takes stated values (built on the explorer's
``OcclusionAwareDouble``): its posterior carries sexes (female 62 % unless a sex is stated).
"""

from __future__ import annotations

import html
import io
import re
import threading
from dataclasses import replace

import numpy as np
import pytest
import torch
import viser
from PIL import Image
from test_explorer_double import OcclusionAwareDouble

from hkpd.body.asset import SEX_NAMES
from hkpd.explorer import cli
from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.body_settings import (
    NOTHING_STATED,
    BodyStatement,
    parse_field,
    parse_fields,
)
from hkpd.explorer.change_baseline import BaselineCache, BaselineKey
from hkpd.explorer.compare import CompareSetting, Comparison
from hkpd.explorer.html_page import CAPTION_ID
from hkpd.explorer.panels.body import LOOKS, SEX_CHOICES, build_body_section
from hkpd.explorer.panels.status import source_text
from hkpd.explorer.provider import PredictorProvider, body_arguments
from hkpd.explorer.scene import MODE_COLOUR, SKIN_COLOUR
from hkpd.explorer.state import ExplorerState
from hkpd.prediction.sex_latent import SexShapes
from hkpd.stated_body import StatedBody

AUTOMATIC_FEMALE = 0.62


class BodyStatingDouble:
    """The explorer's test double as a provider that takes a stated sex and measurements;
    records ``(evidence, sex, measurements)`` of every call."""

    states_body = True

    def __init__(self) -> None:
        self.double = OcclusionAwareDouble()
        self.calls: list[tuple[bool, str | None, dict | None]] = []

    def predict(self, image, occluders, evidence=True, bbox=None, sex=None, measurements=None):
        self.calls.append((evidence, sex, measurements))
        result = self.double.predict(image, occluders, evidence, bbox)
        if not evidence:  # the network alone has no sexes
            return result
        body = result.posterior.body
        if sex is None:
            probabilities = {"female": AUTOMATIC_FEMALE, "male": 1 - AUTOMATIC_FEMALE}
        else:
            probabilities = {name: float(name == sex) for name in SEX_NAMES}
        means = {name: body.sex_shape_prior(name)[0].float() for name in SEX_NAMES}
        covariances = {name: torch.eye(len(means[name])) * 0.3**2 for name in SEX_NAMES}
        sexes = SexShapes(probabilities, means, covariances, stated=sex is not None)
        drawn = sexes.most_probable
        distribution = replace(
            result.posterior.distribution, shape_mean=means[drawn],
            shape_std=torch.full_like(means[drawn], 0.3),
        )  # fmt: skip
        posterior = replace(
            result.posterior, distribution=distribution, sexes=sexes,
            stated=StatedBody.of(sex, measurements),
        )  # fmt: skip
        return replace(result, posterior=posterior)


@pytest.fixture(scope="module")
def app():
    provider = BodyStatingDouble()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0, num_displayed=2)
    explorer.provider_double = provider
    assert explorer.wait_idle(60)
    yield explorer
    explorer.stop()


def last_call(app) -> tuple[bool, str | None, dict | None]:
    return app.provider_double.calls[-1]


# ---------------------------------------------------------------------- the values typed


def test_fields_read_centimetres_and_kilograms_with_an_optional_std() -> None:
    assert parse_field("height_m", "") is None
    assert parse_field("height_m", " 175 ") == pytest.approx(1.75)
    assert parse_field("height_m", "175 ± 2") == pytest.approx((1.75, 0.02))
    assert parse_field("mass_kg", "70,5 +- 3") == pytest.approx((70.5, 3.0))
    # Metres typed into the centimetre field are read as metres (as on the command line);
    # units may be typed; a length plausible in neither is refused, saying what to type.
    assert parse_field("height_m", "1.75") == pytest.approx(1.75)
    assert parse_field("height_m", "1.75 m ± 2 cm") == pytest.approx((1.75, 0.02))
    assert parse_field("waist_m", "80 cm") == pytest.approx(0.8)
    with pytest.raises(ValueError, match=r"Height: '5' is not plausible.*type it in cm, e.g. 175"):
        parse_field("height_m", "5")
    with pytest.raises(ValueError, match=r"Mass: not a number: 'heavy'.*type it in kg"):
        parse_field("mass_kg", "heavy")
    with pytest.raises(ValueError, match=r"(?s)Height.*\n.*Mass"):  # every bad field, each named
        parse_fields(None, {"height_m": "abc", "mass_kg": "0"})


def test_a_statement_is_hashable_and_becomes_the_predictors_arguments() -> None:
    stated = parse_fields("male", {"height_m": "185", "mass_kg": "90 ± 3", "chest_m": ""})
    assert stated == BodyStatement.of("male", {"mass_kg": (90.0, 3.0), "height_m": 1.85})
    assert hash(stated) == hash(BodyStatement.of("male", {"height_m": 1.85, "mass_kg": (90, 3)}))
    assert stated.predict_arguments() == {
        "sex": "male", "measurements": {"height_m": (1.85, 0.01), "mass_kg": (90.0, 3.0)}
    }  # fmt: skip
    assert stated.summary() == "male, height 185 ± 1 cm, mass 90 ± 3 kg"
    assert NOTHING_STATED.predict_arguments() == {}
    # Only with the evidence, and only to a provider that takes them.
    taker = type("Taker", (), {"states_body": True})()
    assert body_arguments(taker, stated, evidence=True)["sex"] == "male"
    assert body_arguments(taker, stated, evidence=False) == {}
    assert body_arguments(object(), stated, evidence=True) == {}


def test_the_state_keeps_a_statement_per_photo() -> None:
    state = ExplorerState()
    state.set_image(400, 300)
    version = state.snapshot().prediction_version
    assert state.set_stated(BodyStatement.of("female"))
    assert not state.set_stated(BodyStatement.of("female"))  # unchanged: nothing to predict
    assert state.snapshot().prediction_version == version + 1
    assert state.snapshot().stated.sex == "female"
    state.set_image(200, 100)  # a new photo is a new person
    assert state.snapshot().stated == NOTHING_STATED
    with pytest.raises(TypeError):
        state.set_stated({"sex": "male"})  # type: ignore[arg-type]


def test_the_baseline_cache_never_mixes_stated_bodies() -> None:
    cache = BaselineCache()
    plain = BaselineKey(1, None, True)
    male = BaselineKey(1, None, True, stated=BodyStatement.of("male"))
    first, second = object(), object()
    cache.record(plain, first)  # type: ignore[arg-type]
    assert cache.posterior(male) is None  # another stated body: not this key's posterior
    cache.record(male, second)  # type: ignore[arg-type]
    assert cache.posterior(plain) is first and cache.posterior(male) is second


def test_the_predictor_adapter_passes_the_stated_body() -> None:
    calls = []

    class RecordingPredictor:
        body = type("Body", (), {"has_sex_priors": True})()
        silhouette_evidence = False

        def predict(self, image, **kwargs):
            calls.append(kwargs)
            raise RuntimeError("recorded")

    provider = PredictorProvider.__new__(PredictorProvider)
    provider.predictor = RecordingPredictor()  # type: ignore[assignment]
    provider._lock = threading.Lock()
    assert provider.states_body
    with pytest.raises(RuntimeError, match="recorded"):
        photo = np.zeros((8, 8, 3), np.uint8)
        provider.predict(photo, [], sex="male", measurements={"mass_kg": 80})
    assert calls[0]["sex"] == "male" and calls[0]["measurements"] == {"mass_kg": 80}


# ---------------------------------------------------------------------- the section alone


def click(button: viser.GuiButtonHandle) -> None:
    button.value = True  # what a click does: a button's callbacks always run


class RecordingBodyActions:
    def __init__(self) -> None:
        self.state = ExplorerState()
        self.state.set_image(400, 300)
        self.changed: list[bool] = []
        self.looks: list[str] = []

    def sampling_changed(self, changed: bool) -> None:
        pass

    def body_changed(self, changed: bool) -> None:
        self.changed.append(changed)

    def set_look(self, look: str) -> None:
        self.looks.append(look)


def test_the_section_states_the_sex_and_measurements_and_refuses_bad_input() -> None:
    server = viser.ViserServer(port=0, verbose=False)
    try:
        actions = RecordingBodyActions()
        section = build_body_section(server.gui, actions)
        assert section.chosen_sex is None and section.chosen_look == "clay"
        section.sex.value = SEX_CHOICES["male"]
        assert actions.state.stated == BodyStatement.of("male") and actions.changed == [True]
        section.fields["height_m"].value = "185"
        section.fields["mass_kg"].value = "90 ± 3"
        click(section.apply)
        expected = BodyStatement.of("male", {"height_m": 1.85, "mass_kg": (90.0, 3.0)})
        assert actions.state.stated == expected and actions.changed[-1] is True
        # Bad input: a message, nothing changed, the typed text kept to be fixed.
        section.fields["height_m"].value = "18.5"
        click(section.apply)
        assert "Not stated" in section.message.content and "Height" in section.message.content
        assert actions.state.stated == expected and section.fields["height_m"].value == "18.5"
        click(section.clear)
        assert actions.state.stated == NOTHING_STATED
        assert section.fields["height_m"].value == "" and section.chosen_sex is None
        section.look.value = LOOKS["skin"]
        assert actions.looks == ["skin"]
    finally:
        server.stop()


# ---------------------------------------------------------------------- the app


def test_the_app_shows_the_uncertain_sex_and_the_measurements(app) -> None:
    assert last_call(app) == (True, None, None)  # nothing stated: the photo decides
    body = app.panels.body
    assert "not sure (female 62 %) — pick the sex below" in body.sex_text.content
    assert "neither sex's" in body.sex_text.content
    table = body.measurements.content
    assert "| Height |" in table and " cm |" in table and "| Mass |" in table and " kg |" in table
    status = source_text(app.result.posterior)
    assert "Body drawn: not sure (female 62 %), neither sex drawn" in status
    assert "height" in status


def test_stating_a_sex_and_a_height_predicts_with_them(app) -> None:
    body = app.panels.body
    body.sex.value = SEX_CHOICES["male"]
    assert app.wait_idle(30)
    assert last_call(app) == (True, "male", None)
    assert "Sex: male (stated)" in body.sex_text.content
    mass_female = app.result.posterior.measurements()["mass_kg"][0]
    assert app.state_body(BodyStatement.of("male", {"height_m": 1.85}))
    assert app.wait_idle(30)
    assert last_call(app) == (True, "male", {"height_m": (1.85, 0.01)})
    assert body.fields["height_m"].value == "185"  # the field shows what is stated
    assert "| 185 ± 1 cm |" in body.measurements.content  # the stated column
    assert app._result_key.stated == app.state.stated  # the posterior's key names the body
    assert app.result.posterior.sex == "male" and mass_female > 0
    # The network alone cannot take stated values: none are sent, the section says why.
    app.set_evidence(False)
    assert app.wait_idle(30)
    assert last_call(app) == (False, None, None)
    assert "network alone" in body.sex_text.content
    app.set_evidence(True)
    assert app.wait_idle(30)
    assert last_call(app) == (True, "male", {"height_m": (1.85, 0.01)})


def test_a_new_photo_starts_with_nothing_stated(app) -> None:
    app.state_body(BodyStatement.of("female", {"mass_kg": 70.0}))
    assert app.wait_idle(30)
    buffer = io.BytesIO()
    Image.fromarray(app.provider_double.double.scene.image).save(buffer, format="PNG")
    app.load_upload("another.png", buffer.getvalue(), None)
    assert app.wait_idle(60)
    assert last_call(app) == (True, None, None)
    assert app.state.stated == NOTHING_STATED
    assert app.panels.body.chosen_sex is None and app.panels.body.fields["mass_kg"].value == ""


def test_the_drawn_body_is_clay_by_default_and_skin_on_request(app) -> None:
    assert MODE_COLOUR == (200, 194, 186)
    assert app.scene.mode_colour == MODE_COLOUR and app.scene._mode.color == MODE_COLOUR
    app.panels.body.look.value = LOOKS["skin"]
    assert app.scene._mode.color == SKIN_COLOUR
    app.set_look("clay")
    assert app.scene._mode.color == MODE_COLOUR
    with pytest.raises(ValueError, match="look must be one of clay, skin"):
        app.set_look("chrome")


# ---------------------------------------------------------------------- the command line


def test_the_body_flags_parse_as_hkpd_predicts() -> None:
    args = cli.build_parser().parse_args(["photo.jpg", "--sex", "male", "--height", "1.85",
                                          "--mass", "90", "2"])  # fmt: skip
    assert cli._stated_body(args) == BodyStatement.of(
        "male", {"height_m": 1.85, "mass_kg": (90.0, 2.0)}
    )
    assert cli._stated_body(cli.build_parser().parse_args([])) == NOTHING_STATED


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--height", "5"], r"--height 5: '5' is not plausible \(height_m = 5 m is outside"),
        (["--mass", "heavy"], r"--mass heavy: not a number"),
        (["--height", "1.8", "--no-evidence"], r"needs the keypoint evidence: drop --no-evidence"),
    ],
)
def test_bad_body_flags_are_refused_before_the_model_loads(flags, message) -> None:
    # A provider that cannot be built: the flags are refused before anyone tries.
    with pytest.raises(SystemExit, match=message):
        cli.main(["--no-browser", "--port", "0", "--provider", "no_such_module:x", *flags])


def test_an_unknown_sex_is_a_usage_error(capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--sex", "robot"])
    assert exit_info.value.code == 2 and "invalid choice: 'robot'" in capsys.readouterr().err


def test_the_exported_pages_caption_says_the_sex_and_measurements(tmp_path) -> None:
    page = tmp_path / "page.html"
    assert cli.main(
        ["--demo", "synthetic", "--provider", "test_explorer_body:BodyStatingDouble",
         "--samples", "20", "--meshes", "1", "--export-html", str(page), "--sex", "male",
         "--height", "1.85"]
    ) == 0  # fmt: skip
    text = html.unescape(page.read_text(encoding="utf-8"))
    caption = re.search(f'<div id="{CAPTION_ID}"[^>]*>(.*?)</div>', text, re.S).group(1)
    assert "Body drawn: male (stated); height " in caption and " cm, mass " in caption
    assert "Stated: male, height 185 ± 1 cm." in caption


def test_compare_with_another_model_predicts_the_same_stated_person() -> None:
    other = BodyStatingDouble()
    comparison = Comparison(lambda *args: None, load_model=lambda path: other)  # type: ignore[arg-type]
    comparison.set_setting(CompareSetting("model", "other.pt"))
    state = ExplorerState()
    state.set_image(*other.double.scene.image.shape[1::-1])
    state.set_stated(BodyStatement.of("female", {"height_m": 1.6}))
    result = other.predict(other.double.scene.image, [])
    comparison.predict(other.double.scene.image, state.snapshot(), result)
    assert comparison.error is None
    assert other.calls[-1] == (True, "female", {"height_m": (1.6, 0.01)})


def test_a_saved_scene_keeps_the_stated_body_and_reopens_it(app) -> None:
    stated = BodyStatement.of("female", {"mass_kg": (58.0, 1.5)})
    app.state_body(stated)
    assert app.wait_idle(30)
    scene = app.keeper.settings()
    assert scene.sex == "female" and scene.measurements == {"mass_kg": [58.0, 1.5]}
    app.state_body(BodyStatement())
    assert app.wait_idle(30)
    app.keeper.apply(scene)
    assert app.wait_idle(30)
    assert app.state.stated == stated
    assert last_call(app) == (True, "female", {"mass_kg": (58.0, 1.5)})
    app.state_body(BodyStatement())
    assert app.wait_idle(30)
