"""The explorer's *Fit the person mask* switch: offered only by providers that can fit the mask,
passed to them only while the keypoints are evidence too, and a change of it predicts again
(with its own change-colouring baseline)."""

from __future__ import annotations

from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp


class MaskFittingDouble:
    """The test double, plus the person-mask switch; records each call's evidence settings."""

    fits_person_mask = True

    def __init__(self) -> None:
        self.double = OcclusionAwareDouble()
        self.calls: list[tuple[bool, bool]] = []

    def predict(self, image, occluders, evidence=True, bbox=None, silhouette=False):
        self.calls.append((evidence, silhouette))
        return self.double.predict(image, occluders, evidence, bbox)


class KeypointsOnlyDouble:
    """The test double as a provider that knows nothing of person masks."""

    def __init__(self) -> None:
        self.double = OcclusionAwareDouble()
        self.calls = 0

    def predict(self, image, occluders, evidence=True, bbox=None):
        self.calls += 1
        return self.double.predict(image, occluders, evidence, bbox)


def test_the_switch_reaches_the_provider_only_with_the_keypoints_on() -> None:
    provider = MaskFittingDouble()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0, num_displayed=2)
    try:
        assert explorer.wait_idle(60)
        switch = explorer.panels.photo.silhouette
        assert switch.visible and not switch.value and not switch.disabled
        assert provider.calls == [(True, False)]
        switch.value = True  # as the user's tick arrives
        assert explorer.wait_idle(30)
        assert provider.calls[-1] == (True, True)
        assert explorer.state.snapshot().silhouette
        assert explorer._result_key.silhouette  # its own baseline for the change colouring
        explorer.panels.photo.evidence.value = False
        assert explorer.wait_idle(30)
        assert provider.calls[-1] == (False, False)  # the mask only ever joins the keypoints
        assert switch.disabled
        assert not explorer._result_key.silhouette
        explorer.panels.photo.evidence.value = True
        assert explorer.wait_idle(30)
        assert provider.calls[-1] == (True, True) and not switch.disabled
        count = len(provider.calls)
        explorer.set_silhouette(True)  # unchanged: nothing to predict
        assert explorer.wait_idle(30) and len(provider.calls) == count
        explorer.set_silhouette(False)
        assert explorer.wait_idle(30) and provider.calls[-1] == (True, False)
    finally:
        explorer.stop()


def test_a_provider_without_masks_hides_the_switch_and_is_called_as_before() -> None:
    provider = KeypointsOnlyDouble()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0, num_displayed=2)
    try:
        assert explorer.wait_idle(60)
        assert not explorer.panels.photo.silhouette.visible
        calls = provider.calls
        explorer.set_silhouette(True)  # e.g. a stale client: ignored, nothing predicted
        assert explorer.wait_idle(30)
        assert provider.calls == calls and not explorer.state.snapshot().silhouette
        assert not explorer.errors
    finally:
        explorer.stop()


def test_the_status_and_the_teaching_text_say_the_mask_was_fitted() -> None:
    from types import SimpleNamespace

    from hkpd.explorer.panels.status import source_text
    from hkpd.explorer.panels.teaching import shape_basis_text

    fit = SimpleNamespace(evidence_count=15, seconds=0.2, terms=("keypoints", "silhouette"))
    posterior = SimpleNamespace(
        fallback_reason=None, conditioned=True, evidence_fit=fit, upright_tilt_degrees=None
    )
    assert (
        source_text(posterior) == "*Conditioned on 15 keypoints and the person mask (fit 200 ms).*"
    )
    fitted = shape_basis_text(True, False, ("keypoints", "silhouette"))
    assert "the person mask in the fit" in fitted and "Tick" not in fitted
    plain = shape_basis_text(True, False, ("keypoints",))
    assert "Tick *Fit the person mask*" in plain


def test_the_app_and_a_saved_page_can_start_with_the_mask_fitted() -> None:
    from hkpd.explorer.saved_scene import render_scene_page

    provider = MaskFittingDouble()
    explorer = ExplorerApp(
        provider, provider.double.scene.image, port=0, num_displayed=2, silhouette=True
    )
    try:
        assert explorer.wait_idle(60)
        assert provider.calls == [(True, True)]  # the first prediction already fits the mask
        assert explorer.panels.photo.silhouette.value
    finally:
        explorer.stop()
    provider.calls.clear()
    page = render_scene_page(
        provider, provider.double.scene.image, silhouette=True, num_displayed=1
    )
    assert provider.calls and all(call == (True, True) for call in provider.calls)
    assert "<html" in page.html.lower()


def test_the_predictor_provider_fits_the_mask_for_that_call_only() -> None:
    from hkpd.explorer.demo_photo import shipped_photo
    from hkpd.explorer.provider import PredictorProvider

    provider = PredictorProvider(device="cpu")
    photo = shipped_photo()
    try:
        assert provider.fits_person_mask
        fitted = provider.predict(photo, [], silhouette=True).posterior
        assert fitted.evidence_fit.terms == ("keypoints", "silhouette", "landmarks")
        plain = provider.predict(photo, []).posterior
        assert plain.evidence_fit.terms == ("keypoints", "landmarks")
        assert not provider.predictor.silhouette_evidence
    finally:
        provider.predictor.close()
