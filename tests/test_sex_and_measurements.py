"""Sex as a latent, body measurements and stated values (issue 49)."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from hkpd.body import BodyModel, load_body_asset, save_body_asset
from hkpd.body.body_model import load_shipped_asset
from hkpd.body.measurements import MEASUREMENT_NAMES, BodyMeasurer, body_measurer
from hkpd.conditioning import StatedBody, conditioned_on_measurements, rebased_on_population
from hkpd.conditioning.shape_prior import TRAINING_SHAPE_STD
from hkpd.prediction.sex_latent import SexShapes, sex_probabilities


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


@pytest.fixture(scope="module")
def measurer(body: BodyModel) -> BodyMeasurer:
    return body_measurer(body)


def _index(name: str) -> int:
    return MEASUREMENT_NAMES.index(name)


def test_mean_body_measurements_are_those_of_an_adult(measurer: BodyMeasurer) -> None:
    values = measurer(torch.zeros(1, 10))[0]
    assert 1.55 < values[_index("height_m")] < 1.80
    assert 50 < values[_index("mass_kg")] < 85
    assert values[_index("waist_m")] < values[_index("hip_m")]
    assert 0.25 < values[_index("shoulder_width_m")] < 0.45


def test_measurement_jacobian_matches_finite_differences(measurer: BodyMeasurer) -> None:
    point = torch.linspace(-0.5, 0.5, 10, dtype=torch.float64)
    jacobian = measurer.jacobian(point)
    step = 1e-5
    for k in (0, 3, 7):
        shifted = point.clone()
        shifted[k] += step
        numeric = (measurer(shifted[None])[0] - measurer(point[None])[0]) / step
        assert torch.allclose(jacobian[:, k], numeric, rtol=1e-3, atol=1e-4)


def test_male_prior_is_broader_at_the_shoulders_and_flatter_at_the_chest(
    body: BodyModel, measurer: BodyMeasurer
) -> None:
    female, _ = body.sex_shape_prior("female")
    male, _ = body.sex_shape_prior("male")
    values = measurer(torch.stack((female, male)))
    shoulders = values[:, _index("shoulder_width_m")]
    assert shoulders[1] > shoulders[0] + 0.03
    # Bust prominence: how far the chest's front stands out from the front just under it.
    vertices = measurer.rest_vertices(torch.stack((female, male)))
    chest_height = measurer.loops["chest_m"].height
    torso = (vertices[0, :, 0].abs() < 0.12)[None]

    def front(low: float, high: float) -> torch.Tensor:
        band = torso & (vertices[..., 1] > low) & (vertices[..., 1] < high)
        return torch.where(band, vertices[..., 2], torch.full_like(vertices[..., 2], -9)).amax(1)

    prominence = front(chest_height - 0.12, chest_height + 0.02) - front(
        chest_height - 0.22, chest_height - 0.14
    )
    assert prominence[0] > prominence[1] + 0.01


def test_uninformative_reading_gives_the_population_back(body: BodyModel) -> None:
    mean, covariance = body.sex_shape_prior("male")
    rebased = rebased_on_population(
        torch.zeros(2, 10), torch.full((2, 10), TRAINING_SHAPE_STD), mean, covariance, 0.5
    )
    assert torch.allclose(rebased.mean, mean.double().expand(2, -1), atol=1e-5)
    assert torch.allclose(rebased.covariance, covariance.double().expand(2, -1, -1), atol=1e-5)


def test_a_confident_reading_pulls_the_shape_towards_it(body: BodyModel) -> None:
    mean, covariance = body.sex_shape_prior("female")
    reading = torch.full((1, 10), 1.5)
    rebased = rebased_on_population(reading, torch.full((1, 10), 0.3), mean, covariance, 1.0)
    to_reading = (rebased.mean[0] - reading[0].double()).norm()
    assert to_reading < 0.5 * (reading[0] - mean).norm()
    assert rebased.covariance[0].diagonal().max() < 0.3**2 * 1.2


def test_stated_measurements_move_the_shape_as_stated(
    body: BodyModel, measurer: BodyMeasurer
) -> None:
    mean, covariance = body.sex_shape_prior("male")
    prior = rebased_on_population(torch.zeros(1, 10), torch.ones(1, 10), mean, covariance, 0.5)
    stated = {"height_m": (1.93, 0.005), "mass_kg": (105.0, 0.5)}
    updated = conditioned_on_measurements(prior, measurer, stated)
    values = measurer(updated.mean)[0]
    assert abs(float(values[_index("height_m")]) - 1.93) < 0.01
    assert abs(float(values[_index("mass_kg")]) - 105.0) < 1.5
    _, stds = measurer.gaussian(updated.mean[0], updated.covariance[0])
    assert stds[_index("height_m")] < 0.006
    # A tall heavy man is far likelier under the male prior than under the female one.
    female_mean, female_cov = body.sex_shape_prior("female")
    female = conditioned_on_measurements(
        rebased_on_population(torch.zeros(1, 10), torch.ones(1, 10), female_mean, female_cov, 0.5),
        measurer,
        stated,
    )
    assert updated.log_weight[0] > female.log_weight[0] + 3


def test_sex_probabilities_follow_the_evidence() -> None:
    assert sex_probabilities({"female": -10.0, "male": -10.0}) == {"female": 0.5, "male": 0.5}
    tilted = sex_probabilities({"female": -10.0, "male": -10.0 + 2.0})
    assert tilted["male"] == pytest.approx(1 / (1 + torch.e**-2.0))
    assert sex_probabilities({"female": float("nan"), "male": -3.0})["male"] == 1.0


def test_mixture_samples_each_sex_in_proportion(body: BodyModel) -> None:
    means = {sex: body.sex_shape_prior(sex)[0] for sex in ("female", "male")}
    covariances = {sex: body.sex_shape_prior(sex)[1] * 1e-6 for sex in ("female", "male")}
    shapes = SexShapes({"female": 0.3, "male": 0.7}, means, covariances)
    generator = torch.Generator().manual_seed(0)
    betas = shapes.sample_betas(
        torch.randn(2000, 10, generator=generator), torch.rand(2000, generator=generator)
    )
    male = (betas - means["male"]).norm(dim=-1) < 0.01
    assert 0.65 < float(male.float().mean()) < 0.75


@pytest.mark.parametrize(
    ("sex", "measurements", "message"),
    [
        ("man", None, "sex must be one of"),
        (None, {"height": 1.8}, "unknown measurement"),
        (None, {"height_m": 180}, "give it in metres"),
        (None, {"mass_kg": (80, -1)}, "std must be > 0"),
        (None, {"mass_kg": float("nan")}, "must be finite"),
        (None, {"waist_m": "thin"}, "must be a number"),
    ],
)
def test_stated_values_are_checked(sex, measurements, message) -> None:
    with pytest.raises(ValueError, match=message):
        StatedBody.of(sex, measurements)


def test_stated_values_get_default_stds() -> None:
    stated = StatedBody.of("male", {"height_m": 1.8, "mass_kg": (80, 2)})
    assert stated.measurements == {"height_m": (1.8, 0.01), "mass_kg": (80.0, 2.0)}
    assert "height 1.8 ± 0.01 m" in stated.summary()


def test_an_asset_without_sex_priors_still_loads(tmp_path) -> None:
    asset = dataclasses.replace(
        load_shipped_asset(), sex_shape_means=None, sex_shape_covariances=None
    )
    path = tmp_path / "old_body.npz"
    save_body_asset(asset, path)
    old = BodyModel(load_body_asset(path))
    assert not old.has_sex_priors
    with pytest.raises(ValueError, match="no sex-specific shape priors"):
        old.sex_shape_prior("female")
    assert BodyModel(load_body_asset(path, num_betas=4)).num_betas == 4


def test_sex_priors_truncate_with_the_betas(tmp_path) -> None:
    path = tmp_path / "body.npz"
    save_body_asset(load_shipped_asset(), path)
    small = BodyModel(load_body_asset(path, num_betas=4))
    mean, covariance = small.sex_shape_prior("male")
    assert mean.shape == (4,) and covariance.shape == (4, 4)


def test_the_closed_form_jacobian_is_reverse_modes(measurer: BodyMeasurer) -> None:
    """The closed-form derivatives (issue 58: ~7x faster) are what autodiff gives."""
    for seed in range(3):
        betas = 0.7 * torch.randn(10, generator=torch.Generator().manual_seed(seed)).double()
        reverse = torch.autograd.functional.jacobian(lambda b: measurer(b[None])[0], betas)
        torch.testing.assert_close(measurer.jacobian(betas), reverse, rtol=1e-9, atol=1e-12)
