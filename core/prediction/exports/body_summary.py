"""What ``hkpd-predict``'s files say about the body: the sex with its probability, the
measurements with their stds, and what the user stated.

- :func:`body_summary`: the ``summary.json`` keys ``"drawn_sex"``, ``"sex_probabilities"``,
  ``"sex_evidence"``, ``"measurements"`` and ``"stated"``;
- :func:`sex_statement`: the sex in words with where it came from (the face, the body's
  proportions, stated) or that it is not sure, shared with the explorer;
- :func:`body_caption`: the overview's line, e.g. ``"body: male 87 %, height 1.78 ± 0.05 m,
  mass 73 ± 6 kg"`` (``"male (stated)"`` for a stated sex);
- :func:`body_arrays`: the ``prediction.npz`` arrays of the sexes and measurements
  (:func:`sex_arrays`, :func:`measurement_arrays`; ``--same-person``'s ``shape.npz`` too).

Measurements are those of :meth:`hkpd.prediction.posterior.BodyPosterior.measurements`
(metres, kilograms; :mod:`hkpd.body.measurements` says where each is taken).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from hkpd.body.asset import SEX_NAMES
from hkpd.body.measurements import MEASUREMENT_NAMES

if TYPE_CHECKING:
    from hkpd.conditioning import StatedBody
    from hkpd.prediction.posterior import BodyPosterior
    from hkpd.prediction.sex_latent import SexShapes

Measurements = Mapping[str, tuple[float, float]]
"""``{name: (mean, std)}`` as :meth:`BodyPosterior.measurements` returns it."""


def stated_summary(stated: StatedBody | None) -> dict[str, Any] | None:
    """``{"sex": s | None, "measurements": {name: {"value": v, "std": s}}}``, or None when
    nothing was stated."""
    if stated is None or stated.empty:
        return None
    return {
        "sex": stated.sex,
        "measurements": {
            name: {"value": value, "std": std} for name, (value, std) in stated.measurements.items()
        },
    }


def measurement_summary(measurements: Measurements) -> dict[str, dict[str, float]]:
    """``{name: {"mean": m, "std": s}}`` in :data:`MEASUREMENT_NAMES` order."""
    return {
        name: {"mean": float(measurements[name][0]), "std": float(measurements[name][1])}
        for name in MEASUREMENT_NAMES
        if name in measurements
    }


def body_summary(posterior: BodyPosterior, measurements: Measurements) -> dict[str, Any]:
    """The ``summary.json`` keys about the body.

    Args:
        posterior: the photo's posterior.
        measurements: ``posterior.measurements()`` (passed in: it is computed once per photo).

    Returns:
        ``"drawn_sex"``: whose body the mode and the overview draw: a sex, or ``"neutral"``
        when no sex is sure (None without sexes); ``"sex_probabilities"``:
        ``{"female": p, "male": 1 - p}`` or None (the network's own posterior, or a body model
        without sex priors); ``"sex_evidence"``: ``{"face": p_male or None, "keypoints":
        p_male}``, what each source says alone (None when stated); ``"measurements"``:
        :func:`measurement_summary`; ``"stated"``: :func:`stated_summary`.
    """
    probabilities = posterior.sex_probabilities
    return {
        "drawn_sex": posterior.drawn_sex,
        "sex_probabilities": None if probabilities is None else dict(probabilities),
        "sex_evidence": posterior.sex_evidence,
        "measurements": measurement_summary(measurements),
        "stated": stated_summary(posterior.stated),
    }


SEX_SOURCE_WORDS = {"face": "from the face", "keypoints": "from the body's proportions"}
"""Where an automatic sex came from, in words (:attr:`SexEvidence.source`)."""


def _percent(sex: str, probability: float) -> str:
    """``"male 87 %"``, ``"female > 99 %"``."""
    percent = 100.0 * probability
    return f"{sex} > 99 %" if percent > 99.5 else f"{sex} {percent:.0f} %"


def _sex_text(probabilities: Mapping[str, float] | None, stated: bool) -> str | None:
    """``"male 87 %"``, ``"female > 99 %"``, ``"male (stated)"``, or None without sexes."""
    if not probabilities:
        return None
    sex = max(SEX_NAMES, key=lambda name: (probabilities[name], name == "female"))
    return f"{sex} (stated)" if stated else _percent(sex, probabilities[sex])


def sex_statement(sexes: SexShapes | None) -> str | None:
    """What the drawn body says of the sex, and why: ``"male (stated)"``, ``"male 96 % from the
    face"``, ``"not sure (female 58 % from the body's proportions)"``, ``"not sure (male 93 %
    from the face, but this reading is in doubt)"``; None without sexes."""
    if sexes is None:
        return None
    sex = sexes.most_probable
    if sexes.stated:
        return f"{sex} (stated)"
    said = _percent(sex, sexes.probabilities[sex])
    if sexes.evidence is not None:
        said += " " + SEX_SOURCE_WORDS[sexes.evidence.source]
    if sexes.sure:
        return said
    doubt = ", but this reading is in doubt" if sexes.doubted else ""
    return f"not sure ({said}{doubt})"


def _plus_minus(mean: float, std: float, decimals: int, unit: str) -> str:
    """``"1.78 ± 0.05 m"``, one more decimal when the std would round to 0."""
    if round(std, decimals) == 0:
        decimals += 1
    return f"{mean:.{decimals}f} ± {std:.{decimals}f} {unit}"


def body_caption(
    probabilities: Mapping[str, float] | None,
    sex_stated: bool,
    measurements: Measurements,
    sex_words: str | None = None,
) -> str:
    """The overview's line about the body: the more probable sex with its probability (or
    ``sex_words``, :func:`sex_statement`'s), then height and mass with ± one std.

    Args:
        probabilities: ``{"female": p, "male": 1 - p}`` or None (no sex latent: not shown).
        sex_stated: the sex was stated by the user (shown as ``"(stated)"``).
        measurements: ``{name: (mean, std)}``; height and mass are shown when present.
        sex_words: the sex in words, with where it came from; None: from ``probabilities``.
    """
    parts = [sex_words if sex_words is not None else _sex_text(probabilities, sex_stated)]
    if "height_m" in measurements:
        parts.append("height " + _plus_minus(*measurements["height_m"], 2, "m"))
    if "mass_kg" in measurements:
        parts.append("mass " + _plus_minus(*measurements["mass_kg"], 0, "kg"))
    shown = [part for part in parts if part]
    return "body: " + ", ".join(shown) if shown else ""


def posterior_caption(posterior: BodyPosterior, measurements: Measurements) -> str:
    """:func:`body_caption` of a posterior."""
    stated = posterior.sexes is not None and posterior.sexes.stated
    words = sex_statement(posterior.sexes)
    return body_caption(posterior.sex_probabilities, stated, measurements, words)


def measurement_arrays(measurements: Measurements) -> dict[str, np.ndarray]:
    """``measurement_names (6,)`` str, ``measurement_mean (6,)`` and ``measurement_std (6,)``
    (metres, kilograms)."""
    return {
        "measurement_names": np.asarray(MEASUREMENT_NAMES),
        "measurement_mean": np.asarray([measurements[n][0] for n in MEASUREMENT_NAMES]),
        "measurement_std": np.asarray([measurements[n][1] for n in MEASUREMENT_NAMES]),
    }


def sex_arrays(sexes: SexShapes | None, size: int) -> dict[str, np.ndarray]:
    """The arrays of sex as a latent (none when ``sexes`` is None): ``sex_names (2,)`` str
    (``female``, ``male``), ``sex_probabilities (2,)``, ``sex_stated ()`` bool,
    ``sex_shape_means (2, size)`` and ``sex_shape_covariances (2, size, size)`` (each sex's
    shape Gaussian; NaN for a sex that was not fitted, i.e. the other one when the sex was
    stated)."""
    if sexes is None:
        return {}
    means = np.full((len(SEX_NAMES), size), np.nan)
    covariances = np.full((len(SEX_NAMES), size, size), np.nan)
    for index, sex in enumerate(SEX_NAMES):
        if sex in sexes.means:
            means[index] = sexes.means[sex].detach().cpu().double().numpy()
            covariances[index] = sexes.covariances[sex].detach().cpu().double().numpy()
    return {
        "sex_names": np.asarray(SEX_NAMES),
        "sex_probabilities": np.asarray([sexes.probabilities[sex] for sex in SEX_NAMES]),
        "sex_stated": np.bool_(sexes.stated),
        "sex_shape_means": means,
        "sex_shape_covariances": covariances,
    }


def body_arrays(posterior: BodyPosterior, measurements: Measurements) -> dict[str, np.ndarray]:
    """The ``prediction.npz`` arrays of the body: :func:`measurement_arrays` and, with sexes,
    :func:`sex_arrays` (``K`` = the posterior's shape coefficients)."""
    size = int(posterior.shape_mean.shape[-1])
    return measurement_arrays(measurements) | sex_arrays(posterior.sexes, size)
