"""What the user states about the person's body in the explorer, as one hashable value.

:class:`BodyStatement` holds a stated sex and stated measurements (metres, kilograms, each with
a standard deviation). It is part of the state's snapshot and of the keys under which
posteriors are kept (:class:`hkpd.explorer.change_baseline.BaselineKey`), so a posterior
predicted with other stated values is never reused, and it turns into the predictor's
``sex=`` and ``measurements=`` arguments. :func:`parse_field` reads what is typed into the
Body section's fields (centimetres and kilograms, optionally ``± std``) and says clearly what
is wrong with bad input.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from hkpd.stated_body import (
    DEFAULT_STATED_STD,
    MEASUREMENT_NAMES,
    StatedBody,
    StatedValue,
    read_stated_text,
)

FIELD_UNITS: dict[str, tuple[str, float]] = {
    "height_m": ("cm", 0.01),
    "mass_kg": ("kg", 1.0),
    "chest_m": ("cm", 0.01),
    "waist_m": ("cm", 0.01),
    "hip_m": ("cm", 0.01),
    "shoulder_width_m": ("cm", 0.01),
}
"""Each measurement's unit in the panel and its size in the measurement's own unit (m, kg)."""

LABELS: dict[str, str] = {
    "height_m": "Height",
    "mass_kg": "Mass",
    "chest_m": "Chest",
    "waist_m": "Waist",
    "hip_m": "Hip",
    "shoulder_width_m": "Shoulder width",
}
"""What each measurement is called in the panel and the captions."""

EXAMPLES: dict[str, str] = {
    "height_m": "175 or 175 ± 2",
    "mass_kg": "70 or 70 ± 2",
    "shoulder_width_m": "36",
}
"""An example of a good entry per field (others: a girth, "90 or 90 ± 2")."""


@dataclass(frozen=True)
class BodyStatement:
    """A stated sex and stated measurements, checked and hashable.

    Attributes:
        sex: "female", "male" or None (let the photo decide).
        measurements: ``(name, value, std)`` per stated measurement, in the order of
            :data:`hkpd.body.measurements.MEASUREMENT_NAMES` (metres, kilograms).
    """

    sex: str | None = None
    measurements: tuple[tuple[str, float, float], ...] = ()

    @classmethod
    def of(
        cls, sex: str | None = None, measurements: dict[str, StatedValue] | None = None
    ) -> BodyStatement:
        """Check ``sex`` and ``measurements`` (``{name: value | (value, std)}``).

        Raises:
            ValueError: an unknown sex or name, or an implausible value or std (the message
                says which, in metres or kilograms).
        """
        return cls.from_stated(StatedBody.of(sex, measurements))

    @classmethod
    def from_stated(cls, stated: StatedBody | None) -> BodyStatement:
        """The statement of a checked :class:`StatedBody` (None: nothing stated)."""
        if stated is None:
            return cls()
        ordered = tuple(
            (name, float(stated.measurements[name][0]), float(stated.measurements[name][1]))
            for name in MEASUREMENT_NAMES
            if name in stated.measurements
        )
        return cls(stated.sex, ordered)

    @property
    def empty(self) -> bool:
        """Nothing is stated."""
        return self.sex is None and not self.measurements

    def values(self) -> dict[str, tuple[float, float]]:
        """``{name: (value, std)}`` of the stated measurements."""
        return {name: (value, std) for name, value, std in self.measurements}

    def with_sex(self, sex: str | None) -> BodyStatement:
        """The same measurements with ``sex`` stated (None: let the photo decide)."""
        return BodyStatement.of(sex, dict(self.values()))

    def predict_arguments(self) -> dict[str, object]:
        """The predictor's keyword arguments: ``{"sex": ..., "measurements": {...}}``, empty
        when nothing is stated."""
        if self.empty:
            return {}
        return {"sex": self.sex, "measurements": self.values() or None}

    def summary(self) -> str:
        """One line in the panel's units, e.g. ``"male, height 185 ± 1 cm, mass 90 ± 1 kg"``
        (``"nothing"`` when empty)."""
        parts = [] if self.sex is None else [self.sex]
        for name, value, std in self.measurements:
            parts.append(f"{LABELS[name].lower()} {field_text(name, value, std)}")
        return ", ".join(parts) or "nothing"


NOTHING_STATED = BodyStatement()


def in_field_units(name: str, value: float) -> float:
    """``value`` (metres or kilograms) in the panel's unit for measurement ``name``."""
    return value / FIELD_UNITS[name][1]


def field_text(name: str, value: float, std: float) -> str:
    """A stated value as the panel writes it: ``"185 ± 1 cm"``, ``"90 ± 2 kg"``."""
    unit = FIELD_UNITS[name][0]
    return f"{in_field_units(name, value):.3g} ± {in_field_units(name, std):.2g} {unit}"


def entry_text(name: str, value: float, std: float) -> str:
    """What a field holds for a stated value: ``"185"``, or ``"185 ± 3"`` when the std is not
    the default."""
    shown = f"{in_field_units(name, value):g}"
    if math.isclose(std, DEFAULT_STATED_STD[name], rel_tol=1e-6):
        return shown
    return f"{shown} ± {in_field_units(name, std):g}"


def parse_field(name: str, text: str) -> StatedValue | None:
    """What is typed into measurement ``name``'s field, in metres or kilograms.

    Args:
        name: one of :data:`hkpd.body.measurements.MEASUREMENT_NAMES`.
        text: ``""`` (not stated), ``"175"`` or ``"175 ± 2"`` (also ``"175 2"``, ``"175 +- 2"``)
            in the field's unit (:data:`FIELD_UNITS`: centimetres, kilograms for mass), or
            with a unit (``"1.75 m"``); a bare length plausible only in metres (``"1.75"``)
            is read in metres (:func:`hkpd.stated_body.read_stated_text`).

    Returns:
        None for an empty field, the value, or ``(value, std)``.

    Raises:
        ValueError: not a number, or a value or std the predictor would refuse; the message
            names the field and its unit and gives an example.
    """
    text = text.strip()
    if not text:
        return None
    unit = FIELD_UNITS[name][0]
    label = LABELS[name]
    example = EXAMPLES.get(name, "90 or 90 ± 2")
    try:  # the command line's reading, centimetres by default (1.85 is read as metres)
        return read_stated_text(name, text, unit)[0]
    except ValueError as error:
        why = re.sub(r"; type e\.g\. .*$", "", str(error))
        raise ValueError(f"{label}: {why}; type it in {unit}, e.g. {example}") from None


def parse_fields(sex: str | None, texts: dict[str, str]) -> BodyStatement:
    """The statement of the Body section: ``sex`` and each field's text (see
    :func:`parse_field`; empty fields are not stated).

    Raises:
        ValueError: every bad field's message, one per line.
    """
    measurements: dict[str, StatedValue] = {}
    problems = []
    for name, text in texts.items():
        try:
            stated = parse_field(name, text)
        except ValueError as error:
            problems.append(str(error))
            continue
        if stated is not None:
            measurements[name] = stated
    if problems:
        raise ValueError("\n".join(problems))
    return BodyStatement.of(sex, measurements)
