"""The shipped predictor with sex as a latent and stated measurements (issue 49)."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from hkpd.assets import shipped_file
from hkpd.body import BodyModel
from hkpd.body.body_model import load_shipped_asset
from hkpd.prediction import Predictor

PHOTO = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "")


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    torch.set_num_threads(1)
    return Predictor.from_pretrained(device="cpu")


@pytest.fixture(scope="module")
def automatic(predictor: Predictor):
    return predictor.predict(PHOTO)


def test_automatic_posterior_weighs_both_sexes(automatic) -> None:
    probabilities = automatic.sex_probabilities
    assert set(probabilities) == {"female", "male"}
    assert probabilities["female"] + probabilities["male"] == pytest.approx(1.0)
    assert automatic.sex in ("female", "male")
    assert set(automatic.evidence_fit.terms) == {"keypoints", "landmarks"}
    assert len(repr(automatic)) <= 200


def test_a_stated_sex_has_probability_one(predictor: Predictor) -> None:
    posterior = predictor.predict(PHOTO, sex="male")
    assert posterior.sex_probabilities == {"female": 0.0, "male": 1.0}
    assert posterior.sexes.stated and posterior.sex == "male"
    male_mean, _ = predictor.body.sex_shape_prior("male")
    female_mean, _ = predictor.body.sex_shape_prior("female")
    mode = posterior.shape_mean
    assert (mode - male_mean).norm() < (mode - female_mean).norm()


def test_stated_height_and_mass_are_honoured(predictor: Predictor) -> None:
    posterior = predictor.predict(PHOTO, measurements={"height_m": 1.88, "mass_kg": 95.0})
    measured = posterior.measurements()
    assert set(measured) == {
        "height_m", "mass_kg", "chest_m", "waist_m", "hip_m", "shoulder_width_m"
    }  # fmt: skip
    from hkpd.body.measurements import body_measurer

    mode = body_measurer(predictor.body)(posterior.shape_mean[None])[0]
    assert abs(float(mode[0]) - 1.88) < 0.015
    assert abs(float(mode[1]) - 95.0) < 3.0
    assert measured["height_m"][1] < 0.02
    assert posterior.sex_probabilities["male"] > 0.9  # a 1.88 m, 95 kg person


def test_samples_come_from_the_mixture_with_full_covariance(automatic) -> None:
    samples = automatic.sample(50, seed=1)
    again = automatic.sample(50, seed=1)
    assert torch.equal(samples.betas, again.betas)
    assert samples.betas.std(0).min() > 0


def test_stated_values_are_refused_without_evidence_or_priors(predictor: Predictor) -> None:
    with pytest.raises(ValueError, match="needs the evidence posterior"):
        predictor.predict(PHOTO, sex="female", evidence=False)
    with pytest.raises(ValueError, match="unknown measurement"):
        predictor.predict(PHOTO, measurements={"weight": 70})
    old_body = BodyModel(
        dataclasses.replace(load_shipped_asset(), sex_shape_means=None, sex_shape_covariances=None)
    )
    old = Predictor(predictor.network, body=old_body, detector=predictor.detector)
    posterior = old.predict(PHOTO)
    assert posterior.sex_probabilities is None and posterior.conditioned
    with pytest.raises(ValueError, match="no sex-specific shape priors"):
        old.predict(PHOTO, sex="male")


def test_two_photos_combine_sexes_and_count_stated_values_once(predictor: Predictor) -> None:
    from hkpd.prediction import combine_shapes

    stated = predictor.predict(PHOTO, measurements={"height_m": 1.80})
    one = stated.measurements()["height_m"]
    combined = combine_shapes([stated, stated], predictor.body)
    assert combined.sexes is not None and combined.count == 2
    from hkpd.body.measurements import body_measurer

    measurer = body_measurer(predictor.body)
    sex = combined.sexes.most_probable
    mean, std = measurer.gaussian(combined.sexes.means[sex], combined.sexes.covariances[sex])
    assert abs(float(mean[0]) - 1.80) < 0.015
    # Counted once: about the single photo's height std, not 1/sqrt(2) of it.
    assert float(std[0]) > 0.85 * one[1]
    # The sexes' log-odds add (equal prior odds); the stated height's share counted once.
    automatic = predictor.predict(PHOTO)
    pair = combine_shapes([automatic, automatic], predictor.body).sexes
    p = automatic.sex_probabilities["female"]
    assert pair.probabilities["female"] == pytest.approx(p * p / (p * p + (1 - p) ** 2))
    with pytest.raises(ValueError, match="different stated values"):
        combine_shapes([automatic, stated], predictor.body)


def test_log_prob_is_the_pose_density_plus_the_sex_mixture(automatic) -> None:
    samples = automatic.sample(5, seed=3)
    total = automatic.log_prob(samples.body_pose, samples.betas)
    exact = automatic.distribution.to(torch.float64)
    pose = exact.pose_distribution().log_prob(samples.body_pose.double())
    sexes = automatic.sexes
    mixture = torch.logsumexp(
        torch.stack([
            torch.log(torch.tensor(sexes.probabilities[s], dtype=torch.float64))
            + torch.distributions.MultivariateNormal(
                sexes.means[s].double(), sexes.covariances[s].double()
            ).log_prob(samples.betas.double())
            for s in ("female", "male")
        ]),
        dim=0,
    )  # fmt: skip
    assert total.shape == (5,)
    assert torch.allclose(total, pose + mixture, atol=1e-6)


def test_part_uncertainty_names_every_part_and_a_hidden_limb_spreads(predictor: Predictor) -> None:
    posterior = predictor.predict(PHOTO)
    parts = posterior.part_uncertainty(50)
    assert set(parts) == set(predictor.body.part_names)
    assert all(value > 0 for value in parts.values())
    assert parts["left_wrist"] > parts["pelvis"]


def test_meshes_have_a_short_repr(automatic) -> None:
    text = repr(automatic.sample(3, seed=0))
    assert len(text) <= 200 and "3 bodies" in text


def test_the_explorers_added_photos_combine_per_sex(automatic) -> None:
    from hkpd.explorer.same_person_shapes import combined_photos
    from hkpd.explorer.state import SamePersonShape

    mean = tuple(automatic.shape_mean.double().tolist())
    std = tuple(automatic.shape_std.double().tolist())
    added = SamePersonShape("again.jpg", mean, std, automatic.sexes, automatic.stated)
    combined = combined_photos(automatic, [added])
    assert combined.count == 2 and combined.sexes is not None
    p = automatic.sex_probabilities["female"]
    assert combined.sexes.probabilities["female"] == pytest.approx(p * p / (p * p + (1 - p) ** 2))
    plain = combined_photos(automatic, [SamePersonShape("old.jpg", mean, std)])
    assert plain.count == 2 and plain.sexes is None  # a photo without sexes: the product
