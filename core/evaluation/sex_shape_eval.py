"""Sex, measurements and stated values scored on sex-labelled synthetic bodies (issue 49).

The bodies are drawn half from each sex's population prior (alternating female, male; the
body model's :meth:`~hkpd.body.BodyModel.sex_shape_prior`), rendered with the fixed test
set's poses and cameras, and read as the predictor reads a photo: the network's reading, then
:func:`hkpd.prediction.sex_fits.fit_each_sex` on detector-like keypoints. Three posteriors per
body: *automatic* (both sexes fitted, the sex chosen by the evidence), *sex stated* and *sex,
height and mass stated* (the true values with σ 1 cm and 1 kg). Scored: the automatic sex's
accuracy and expected calibration error, each measurement's absolute error and z² under the
automatic mixture, and the PVE-T-SC of each posterior's most likely shape.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.body.asset import SEX_NAMES
from hkpd.body.measurements import MEASUREMENT_NAMES, body_measurer
from hkpd.conditioning import EvidenceConfig, KeypointEvidence, StatedBody
from hkpd.evaluation.shape_metrics import shape_scores
from hkpd.evaluation.test_set import TEST_BATCH_SIZE, TEST_SET_SEED
from hkpd.prediction.sex_fits import SexFits, fit_each_sex
from hkpd.prediction.sex_latent import NEUTRAL
from hkpd.synthesis.detector_noise import DetectorNoise, detector_like_keypoints
from hkpd.synthesis.generator import RenderedBatch, SyntheticDataGenerator, batch_seed

STATED_STD = {"height_m": 0.01, "mass_kg": 1.0}
"""How sure the stated true values are (the issue's σ 1 cm and 1 kg)."""

CALIBRATION_BINS = 10
"""Confidence bins of the expected calibration error."""

POSTERIORS = ("automatic", "sex", "sex+height+mass")
"""The three posteriors scored, by what was stated."""

DRAWN = "automatic (drawn)"
"""The automatic posterior's drawn body: the more probable sex's, or neither sex's
(:attr:`hkpd.prediction.sex_latent.SexShapes.drawn`) below the sure probability."""


def sex_labelled_shapes(body: BodyModel, count: int, seed: int) -> tuple[list[str], torch.Tensor]:
    """``count`` sexes (alternating female, male) and ``(count, K)`` shapes drawn from each
    sex's population prior."""
    generator = torch.Generator().manual_seed(seed)
    sexes = [SEX_NAMES[i % 2] for i in range(count)]
    noise = torch.randn(count, body.num_betas, generator=generator, dtype=torch.float64)
    betas = torch.empty_like(noise)
    for sex in SEX_NAMES:
        mean, covariance = body.sex_shape_prior(sex)
        lower = torch.linalg.cholesky(covariance.double().cpu())
        chosen = torch.tensor([label == sex for label in sexes])
        betas[chosen] = mean.double().cpu() + noise[chosen] @ lower.T
    return sexes, betas


@dataclass
class _Records:
    """Per example: the true sex's probability, the posteriors' modes and stds, measurements."""

    true_sex_probability: list[float] = field(default_factory=list)
    modes: dict[str, list[torch.Tensor]] = field(default_factory=dict)
    stds: dict[str, list[torch.Tensor]] = field(default_factory=dict)
    measured: list[torch.Tensor] = field(default_factory=list)
    measured_std: list[torch.Tensor] = field(default_factory=list)
    neutral: list[bool] = field(default_factory=list)

    def add(self, name: str, fits: SexFits) -> None:
        shapes = fits.shapes
        sex = shapes.most_probable
        self.modes.setdefault(name, []).append(shapes.means[sex].double())
        std = shapes.covariances[sex].diagonal().clamp_min(0).sqrt().double()
        self.stds.setdefault(name, []).append(std)
        if name == "automatic":  # the body drawn: neither sex's when unsure
            self.modes.setdefault(DRAWN, []).append(shapes.drawn_mean().double())
            self.stds.setdefault(DRAWN, []).append(std)
            self.neutral.append(shapes.drawn == NEUTRAL)


def sex_test_batches(
    generator: SyntheticDataGenerator, betas: torch.Tensor, seed: int = TEST_SET_SEED
) -> Iterator[RenderedBatch]:
    """The test set's poses and cameras rendered with ``betas`` ``(count, K)``."""
    count = betas.shape[0]
    for index, start in enumerate(range(0, count, TEST_BATCH_SIZE)):
        chunk = betas[start : start + TEST_BATCH_SIZE]
        yield generator.generate(len(chunk), batch_seed(seed, index), betas=chunk)


@torch.no_grad()
def evaluate_sex_shape(
    reader: torch.nn.Module,
    generator: SyntheticDataGenerator,
    body64: BodyModel,
    count: int,
    config: EvidenceConfig | None = None,
    noise: DetectorNoise | None = None,
    seed: int = 0,
) -> dict:
    """The ``shape.json`` record of issue 49 (module docstring).

    Args:
        reader: reads a batch of proxies into the network's distribution (a ``ProxyReader``).
        generator: renders the test set (its body has sex priors).
        body64: float64 body model with sex priors.
        count: bodies (half of each sex).
        config: the evidence settings.
        noise: detector-like keypoint noise (default: its dataclass').
        seed: seeds the shapes and the keypoint noise.

    Returns:
        ``{"sex": {"accuracy", "ece", "pve_t_sc_mm", "examples"}, "measurements": {name:
        {"mae", "z2"}}, "stated": {"sex": {"pve_t_sc_mm"}, "sex+height+mass": {"pve_t_sc_mm",
        "height_error_mm", "mass_error_kg"}}}``.
    """
    config = config or EvidenceConfig()
    noise = noise or DetectorNoise()
    stream = torch.Generator().manual_seed(seed)
    measurer = body_measurer(body64)
    sexes, betas = sex_labelled_shapes(body64, count, seed + 7)
    truth_measured = measurer(betas)
    records = _Records()
    example = 0
    for rendered in sex_test_batches(generator, betas.float()):
        batch = rendered.batch
        size = batch.proxy.shape[-1]
        output = reader(batch.proxy).map(lambda tensor: tensor.detach().double().cpu())
        detected, reported = detector_like_keypoints(
            batch.keypoints2d, batch.visible, size, noise, stream
        )
        for item in range(output.batch_size):
            evidence = KeypointEvidence(detected[item].cpu(), reported[item].cpu(), size)
            start = output.rows(slice(item, item + 1))
            sex, truth = sexes[example], truth_measured[example]
            stated = {
                "automatic": StatedBody(),
                "sex": StatedBody.of(sex),
                "sex+height+mass": StatedBody.of(sex, {
                    name: (float(truth[MEASUREMENT_NAMES.index(name)]), std)
                    for name, std in STATED_STD.items()
                }),
            }  # fmt: skip
            for name, what in stated.items():
                fits = fit_each_sex(body64, start, evidence, config, (), what)
                records.add(name, fits)
                if name == "automatic":
                    records.true_sex_probability.append(fits.shapes.probabilities[sex])
                    summary = fits.shapes.measurements(measurer)
                    records.measured.append(
                        torch.tensor([summary[n][0] for n in MEASUREMENT_NAMES])
                    )
                    records.measured_std.append(
                        torch.tensor([summary[n][1] for n in MEASUREMENT_NAMES])
                    )
            example += 1
    return _record(records, betas, truth_measured, body64, measurer)


def _record(
    records: _Records,
    betas: torch.Tensor,
    truth_measured: torch.Tensor,
    body64: BodyModel,
    measurer,
) -> dict:
    """Scores from the collected records."""
    probability = torch.tensor(records.true_sex_probability, dtype=torch.float64)
    scores = {
        name: shape_scores(
            body64, torch.stack(records.modes[name]), torch.stack(records.stds[name]), betas
        )
        for name in (*POSTERIORS, DRAWN)
    }
    measured = torch.stack(records.measured).double()
    measured_std = torch.stack(records.measured_std).double().clamp_min(1e-9)
    error = measured - truth_measured
    fully_stated = measurer(torch.stack(records.modes["sex+height+mass"]))
    return {
        "sex": {
            "accuracy": float((probability > 0.5).double().mean()),
            "ece": expected_calibration_error(probability),
            "pve_t_sc_mm": scores["automatic"].pve_t_sc_mm,
            "drawn_pve_t_sc_mm": scores[DRAWN].pve_t_sc_mm,
            "drawn_neutral_share": float(np.mean(records.neutral)),
            "examples": len(probability),
        },
        "measurements": {
            name: {
                "mae": float(error[:, i].abs().mean()),
                "z2": float(((error[:, i] / measured_std[:, i]) ** 2).mean()),
            }
            for i, name in enumerate(MEASUREMENT_NAMES)
        },
        "stated": {
            "sex": {"pve_t_sc_mm": scores["sex"].pve_t_sc_mm},
            "sex+height+mass": {
                "pve_t_sc_mm": scores["sex+height+mass"].pve_t_sc_mm,
                "height_error_mm": 1000
                * float((fully_stated[:, 0] - truth_measured[:, 0]).abs().mean()),
                "mass_error_kg": float((fully_stated[:, 1] - truth_measured[:, 1]).abs().mean()),
            },
        },
        "mean_body_pve_t_sc_mm": scores["automatic"].mean_body_pve_t_sc_mm,
    }


def expected_calibration_error(true_class_probability: torch.Tensor) -> float:
    """Binary ECE: the predicted class is the one above ½, its confidence ``max(p, 1 - p)``;
    bins of confidence in [½, 1], ``Σ_b (n_b / n) |accuracy_b - confidence_b|``."""
    p = true_class_probability.double()
    confidence = torch.maximum(p, 1 - p)
    correct = (p > 0.5).double()
    edges = torch.linspace(0.5, 1.0, CALIBRATION_BINS + 1, dtype=torch.float64)
    total = 0.0
    for low, high in itertools.pairwise(edges):
        inside = (confidence >= low) & ((confidence < high) | (high == 1.0))
        if inside.any():
            gap = (correct[inside].mean() - confidence[inside].mean()).abs()
            total += float(inside.double().mean() * gap)
    return total
