"""``StatedBody``: what the user knows about the person (sex, measurements), checked once.

Torch-free on purpose: the command lines check ``--sex``/``--height``… before loading anything
heavy (``hkpd.body_flags``).

A stated sex skips the comparison of the sexes; a stated measurement is evidence on the shape
(:func:`hkpd.conditioning.shape_prior.conditioned_on_measurements`). Values are metres and
kilograms; each comes with a standard deviation, by default :data:`DEFAULT_STATED_STD`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from numbers import Real

SEX_NAMES: tuple[str, ...] = ("female", "male")
"""The two sexes of the sex-specific shape priors, in the order of their rows."""

MEASUREMENT_NAMES: tuple[str, ...] = (
    "height_m",
    "mass_kg",
    "chest_m",
    "waist_m",
    "hip_m",
    "shoulder_width_m",
)
"""The body measurements (:mod:`hkpd.body.measurements` says where each is taken), in the order
of :class:`hkpd.body.measurements.BodyMeasurer`'s output columns."""

DEFAULT_STATED_STD: dict[str, float] = {
    "height_m": 0.01,
    "mass_kg": 1.0,
    "chest_m": 0.02,
    "waist_m": 0.02,
    "hip_m": 0.02,
    "shoulder_width_m": 0.01,
}
"""How sure a stated value is when no std is given: a tape or a scale read by a person."""

PLAUSIBLE_RANGE: dict[str, tuple[float, float]] = {
    "height_m": (0.5, 2.6),
    "mass_kg": (10.0, 400.0),
    "chest_m": (0.3, 2.5),
    "waist_m": (0.3, 2.5),
    "hip_m": (0.3, 2.5),
    "shoulder_width_m": (0.1, 0.8),
}
"""Values outside these are refused as typing mistakes (e.g. centimetres given as metres)."""

StatedValue = float | tuple[float, float]


@dataclass(frozen=True)
class StatedBody:
    """The sex and measurements a user states, validated.

    Attributes:
        sex: "female", "male" or None (let the photo decide).
        measurements: ``{name: (value, std)}`` with names from
            :data:`hkpd.body.measurements.MEASUREMENT_NAMES`.
    """

    sex: str | None = None
    measurements: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    @classmethod
    def of(
        cls, sex: str | None = None, measurements: Mapping[str, StatedValue] | None = None
    ) -> StatedBody:
        """Check and normalise user input.

        Args:
            sex: "female", "male" or None.
            measurements: ``{name: value}`` or ``{name: (value, std)}``.

        Raises:
            ValueError: an unknown sex or measurement name, or a value or std that is not a
                finite positive number in a plausible range (the message says which).
        """
        if sex is not None and sex not in SEX_NAMES:
            raise ValueError(f"sex must be one of {', '.join(SEX_NAMES)} or None, got {sex!r}")
        checked = {}
        for name, stated in (measurements or {}).items():
            checked[name] = _checked_measurement(name, stated)
        return cls(sex, checked)

    @property
    def empty(self) -> bool:
        """Nothing is stated."""
        return self.sex is None and not self.measurements

    def summary(self) -> str:
        """One line, e.g. ``"male, height 1.85 ± 0.01 m"`` (``"nothing"`` when empty)."""
        parts = [] if self.sex is None else [self.sex]
        for name, (value, std) in self.measurements.items():
            label, unit = name.rsplit("_", 1)
            parts.append(f"{label.replace('_', ' ')} {value:g} ± {std:g} {unit}")
        return ", ".join(parts) or "nothing"


def _checked_measurement(name: object, stated: object) -> tuple[float, float]:
    if name not in MEASUREMENT_NAMES:
        raise ValueError(
            f"unknown measurement {name!r}; the measurements are {', '.join(MEASUREMENT_NAMES)}"
        )
    if isinstance(stated, tuple | list):
        if len(stated) != 2:
            raise ValueError(f"{name}: give a value or a (value, std) pair, got {stated!r}")
        value, std = stated
    else:
        value, std = stated, DEFAULT_STATED_STD[str(name)]
    value, std = _number(f"{name}", value), _number(f"{name}'s std", std)
    low, high = PLAUSIBLE_RANGE[str(name)]
    unit = "kg" if name == "mass_kg" else "m"
    if not low <= value <= high:
        raise ValueError(
            f"{name} = {value:g} {unit} is outside {low:g}-{high:g} {unit}; "
            f"give it in {'kilograms' if unit == 'kg' else 'metres'}"
        )
    if not 0 < std <= high:
        raise ValueError(f"{name}'s std must be > 0 and at most {high:g} {unit}, got {std:g}")
    return value, std


def _number(what: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ValueError(f"{what} must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{what} must be finite, got {value!r}")
    return number


UNIT_SIZES: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "kg": 1.0}
"""Units a stated measurement may be typed in, and their size in metres (kilograms for kg)."""

_NUMBER = r"[-+]?(?:\d+(?:[.,]\d*)?|[.,]\d+)"
_UNIT = r"(?:\s*(mm|cm|m|kg)\b)?"
_STATED_TEXT = re.compile(
    rf"^\s*({_NUMBER}){_UNIT}\s*(?:(?:±|\+/-|\+-|\s)\s*({_NUMBER}){_UNIT})?\s*$", re.IGNORECASE
)


def read_stated_text(name: str, text: str, default_unit: str) -> tuple[StatedValue, str]:
    """A measurement typed as text: ``"VALUE [± STD]"``, each number optionally with its unit
    (``"185 cm"``, ``"1.85m ± 2cm"``, ``"80 kg"``), in metres or kilograms.

    A bare number is in ``default_unit`` (``"m"`` on the command line, ``"cm"`` in the
    explorer's Body fields), except a length that is not plausible in it but is in the other
    of metres and centimetres (no length is plausible in both: :data:`PLAUSIBLE_RANGE` in
    metres stays below 2.6, in centimetres above 10): ``--height 185`` is 185 cm and the
    field's ``1.85`` is 1.85 m. The note then says how it was read ("" otherwise).

    Raises:
        ValueError: not ``VALUE [STD]``, a unit that does not fit the measurement, or a value
            :meth:`StatedBody.of` refuses; the message says what to type.
    """
    mass = name == "mass_kg"
    match = _STATED_TEXT.match(text)
    if match is None:
        raise ValueError(f"not a number: {text!r} (a value, an optional ± std, units m, cm, kg)")
    value_text, value_unit, std_text, std_unit = match.groups()
    units = {(u or "").lower() for u in (value_unit, std_unit)} - {""}
    if units and (units != {"kg"} if mass else "kg" in units):
        raise ValueError(f"{text!r}: give {'mass in kg' if mass else 'a length in m or cm'}")
    value = float(value_text.replace(",", "."))
    std = None if std_text is None else float(std_text.replace(",", "."))
    unit, note = (value_unit or default_unit).lower(), ""
    if not mass and value_unit is None:
        unit = _plausible_unit(name, value, unit)
        if unit != default_unit:
            words = "centimetres" if unit == "cm" else "metres"
            note = f"{value:g} read as {words}: {value * UNIT_SIZES[unit]:g} m"
    metres = value * UNIT_SIZES["kg" if mass else unit]
    if std is not None:
        std_metres = std * UNIT_SIZES["kg" if mass else (std_unit or unit).lower()]
        stated: StatedValue = (metres, std_metres)
    else:
        stated = metres
    try:
        StatedBody.of(None, {name: stated})
    except ValueError as error:
        example = "80 kg" if mass else "1.85 m or 185 cm" if name == "height_m" else "90 cm"
        raise ValueError(f"{text!r} is not plausible ({error}); type e.g. {example}") from None
    return stated, note


def _plausible_unit(name: str, value: float, unit: str) -> str:
    """``unit``, or the other of m and cm when only that one makes ``value`` plausible."""
    low, high = PLAUSIBLE_RANGE[name]
    other = "cm" if unit == "m" else "m"
    if (
        not low <= value * UNIT_SIZES.get(unit, 1.0) <= high
        and low <= value * UNIT_SIZES[other] <= high
    ):
        return other
    return unit
