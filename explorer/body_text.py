"""The body a posterior draws, in words: its sex with the probability, and its measurements.

Shared by the Body section (:mod:`hkpd.explorer.panels.body`), the status line and the saved
page's caption (:func:`hkpd.explorer.panels.status.source_text`). On the shipped model the sex
read from keypoints is close to a coin flip (docs/shape.md), so every text says plainly when
the sex is uncertain and how to state it. A posterior's measurements cost a linearisation per
sex (~0.1 s each), so they are computed once per posterior (:func:`measurements_of`).
"""

from __future__ import annotations

import threading
from collections import OrderedDict

from hkpd.explorer.body_settings import FIELD_UNITS, LABELS, BodyStatement, in_field_units
from hkpd.prediction.exports.body_summary import sex_statement
from hkpd.prediction.sex_latent import SURE_SEX_PROBABILITY, SexShapes

_KEPT = 8
_cache: OrderedDict[int, tuple[object, dict[str, tuple[float, float]]]] = OrderedDict()
_cache_lock = threading.Lock()


def measurements_of(posterior: object) -> dict[str, tuple[float, float]] | None:
    """``posterior.measurements()`` (``{name: (mean, std)}``, metres and kilograms), computed
    once per posterior (the last few are kept); None for a posterior without them (a custom
    provider's, or one whose body model cannot be measured)."""
    measure = getattr(posterior, "measurements", None)
    if not callable(measure):
        return None
    with _cache_lock:
        found = _cache.get(id(posterior))
        if found is not None and found[0] is posterior:
            _cache.move_to_end(id(posterior))
            return found[1]
    try:
        values = dict(measure())
    except (AttributeError, RuntimeError, TypeError, ValueError):
        return None
    with _cache_lock:
        _cache[id(posterior)] = (posterior, values)
        while len(_cache) > _KEPT:
            _cache.popitem(last=False)
    return values


def sex_words(posterior: object) -> str | None:
    """The drawn body's sex in a few words, with where it came from
    (:func:`hkpd.prediction.exports.body_summary.sex_statement`): ``"male (stated)"``,
    ``"male 96 % from the face"``, ``"not sure (female 58 % from the body's proportions)"``;
    None without sexes (the network alone, or a body model without sex priors)."""
    probabilities = getattr(posterior, "sex_probabilities", None)
    if not probabilities:
        return None
    sexes = getattr(posterior, "sexes", None)
    if isinstance(sexes, SexShapes):
        return sex_statement(sexes)
    sex = max(probabilities, key=lambda name: (probabilities[name], name == "female"))
    if getattr(sexes, "stated", False):
        return f"{sex} (stated)"
    words = f"{sex} {probabilities[sex] * 100:.0f} %"
    return words if probabilities[sex] >= SURE_SEX_PROBABILITY else f"not sure ({words})"


def sex_markdown(posterior: object | None, evidence: bool, can_state: bool) -> str:
    """The Body section's sex line (markdown): the sex with its probability and where it came
    from and, when it is uncertain, plainly so with what to do; or why there is none."""
    if posterior is None:
        return "**Sex:** no person yet."
    words = sex_words(posterior)
    if words is None:
        if not can_state:
            return "**Sex:** this model's body has no sex priors; it draws one average body."
        if not evidence:
            return (
                "**Sex:** not estimated for the network alone: switch on *Condition on 2D "
                "keypoints* (Photo and occluders) to weigh the sexes and state what you know."
            )
        return "**Sex:** not estimated for this prediction."
    if words.startswith("not sure"):
        return (
            f"**Sex: {words} — pick the sex below.** *The body drawn is neither sex's (no "
            "chest or hips of either) until the photo or you say which: the body's proportions "
            f"barely tell the sexes apart, and {face_clause(posterior)}.*"
        )
    if words.endswith("(stated)"):
        return f"**Sex: {words}.**"
    return f"**Sex: {words}** *(state it below if it is wrong).*"


def face_clause(posterior: object) -> str:
    """Why the face did not settle the sex, in words: "the face was not read (switched off)",
    "the face said nothing: the head is turned away from the camera", "the face's word (male
    75 %) is not clear enough", or "this reading is in doubt"."""
    sexes = getattr(posterior, "sexes", None)
    evidence = getattr(sexes, "evidence", None)
    if getattr(sexes, "doubted", False):
        return "this reading is in doubt (see the quality line)"
    if evidence is None:
        return "no face was read"
    if evidence.face is None:
        if evidence.face_reason is None:
            return "the face was not read (switched off)"
        return f"the face said nothing: {evidence.face_reason}"
    sex = "male" if evidence.face >= 0.5 else "female"
    percent = 100 * max(evidence.face, 1 - evidence.face)
    return f"the face's word ({sex} {percent:.0f} %) is not clear enough"


def measurement_markdown(
    measurements: dict[str, tuple[float, float]] | None, stated: BodyStatement
) -> str:
    """The measurements of the drawn body as a table: mean ± std (cm, kg), beside what was
    stated."""
    if measurements is None:
        return "*No measurements for this prediction.*"
    given = stated.values()
    rows = ["| | body (mean ± std) | stated |", "|---|---|---|"]
    for name, label in LABELS.items():
        if name not in measurements:
            continue
        mean, std = measurements[name]
        unit = FIELD_UNITS[name][0]
        body = f"{in_field_units(name, mean):.0f} ± {in_field_units(name, std):.0f} {unit}"
        said = ""
        if name in given:
            value, spread = (in_field_units(name, number) for number in given[name])
            said = f"{value:g} ± {spread:.2g} {unit}"
        rows.append(f"| {label} | {body} | {said} |")
    return "\n".join(rows)


def body_sentence(posterior: object) -> str:
    """One plain sentence for the status line and saved pages' captions, e.g. "Body drawn: not
    sure (female 62 % from the body's proportions), neither sex drawn (state the sex in Photo ›
    Body); height 169 ± 10 cm, mass 65 ± 15 kg. Stated: male, height 185 ± 1 cm."; "" for a
    posterior without sexes."""
    words = sex_words(posterior)
    if words is None:
        return ""
    if words.startswith("not sure"):
        words += ", neither sex drawn (state the sex in Photo › Body)"
    parts = [f"Body drawn: {words}"]
    measurements = measurements_of(posterior)
    if measurements:
        sizes = [
            f"{LABELS[name].lower()} {in_field_units(name, mean):.0f} ± "
            f"{in_field_units(name, std):.0f} {FIELD_UNITS[name][0]}"
            for name, (mean, std) in measurements.items()
            if name in ("height_m", "mass_kg")
        ]
        parts.append("; " + ", ".join(sizes))
    text = "".join(parts) + "."
    stated = BodyStatement.from_stated(getattr(posterior, "stated", None))
    if not stated.empty:
        text += f" Stated: {stated.summary()}."
    return text
