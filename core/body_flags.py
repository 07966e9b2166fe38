"""The command-line flags that state what the user knows of the person's body.

``--sex {female,male}`` and one flag per measurement, each ``VALUE [STD]`` (metres, or
kilograms for ``--mass``; without a std the default of
:data:`hkpd.stated_body.DEFAULT_STATED_STD`, e.g. 1 cm and 1 kg). A length may carry its unit,
and a bare length too large for metres is read as centimetres, with a note on stderr
(:func:`hkpd.stated_body.read_stated_text`: the explorer's Body fields read the same text)::

    --height 1.82            # 1.82 m, std 0.01 m
    --height 182             # 182 cm (note: 182 read as centimetres: 1.82 m)
    --height 182cm 2cm       # 1.82 m, std 0.02 m
    --mass 80 2              # 80 kg, std 2 kg
    --chest M [STD] --waist M [STD] --hip M [STD] --shoulder-width M [STD]

:func:`add_body_arguments` adds them to a parser; :func:`stated_body` turns the parsed values
into a checked :class:`~hkpd.conditioning.StatedBody` before any model is loaded, and raises a
ValueError whose message names the flag. ``hkpd-predict`` uses them; the values go to
:meth:`hkpd.prediction.predictor.Predictor.predict` as ``sex=`` and ``measurements=``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from hkpd.stated_body import (
    DEFAULT_STATED_STD,
    SEX_NAMES,
    StatedBody,
    StatedValue,
    read_stated_text,
)

MEASUREMENT_FLAGS: dict[str, str] = {
    "height_m": "--height",
    "mass_kg": "--mass",
    "chest_m": "--chest",
    "waist_m": "--waist",
    "hip_m": "--hip",
    "shoulder_width_m": "--shoulder-width",
}
"""The flag of each measurement (names: :data:`hkpd.body.measurements.MEASUREMENT_NAMES`)."""

_WHAT = {
    "height_m": "height, metres (head top to soles)",
    "mass_kg": "mass, kilograms",
    "chest_m": "chest circumference, metres",
    "waist_m": "waist circumference, metres",
    "hip_m": "hip circumference, metres",
    "shoulder_width_m": "shoulder width, metres (between the shoulder joints)",
}

BODY_FLAGS = ("--sex", *MEASUREMENT_FLAGS.values())
"""Every flag that states something about the body."""


def _dest(name: str) -> str:
    return f"stated_{name}"


def add_body_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--sex`` and the measurement flags (parsed as strings; see :func:`stated_body`)."""
    group = parser.add_argument_group(
        "what you know of the person (conditions the body shape; docs/prediction.md); lengths "
        "in metres, or with their unit (182cm); a bare length too large for metres (182) is "
        "read as centimetres"
    )
    group.add_argument(
        "--sex",
        choices=SEX_NAMES,
        default=None,
        help="the person's sex; without it the photo decides and the outputs say how probable "
        "each sex is",
    )
    for name, flag in MEASUREMENT_FLAGS.items():
        unit = "KG" if name == "mass_kg" else "M|CM"
        group.add_argument(
            flag,
            dest=_dest(name),
            nargs="+",
            metavar=(unit, "STD"),
            default=None,
            help=f"{_WHAT[name]}, optionally followed by its std (default "
            f"{DEFAULT_STATED_STD[name]:g})",
        )


def stated_body(args: argparse.Namespace) -> StatedBody:
    """The sex and measurements the flags state, checked (an empty StatedBody when none).

    Raises:
        ValueError: a flag with no or more than two values, a value that is not a number, or
            one :meth:`StatedBody.of` refuses (outside a plausible range, a std that is not
            > 0); the message starts with the flag and what was given.
    """
    measurements: dict[str, StatedValue] = {}
    for name, flag in MEASUREMENT_FLAGS.items():
        values = getattr(args, _dest(name), None)
        if values is not None:
            measurements[name] = _stated_value(name, flag, values)
    return StatedBody.of(getattr(args, "sex", None), measurements)


def _stated_value(name: str, flag: str, values: Sequence[str]) -> StatedValue:
    """One flag's ``VALUE [STD]`` as a float or a ``(value, std)`` pair, checked (a length
    read as centimetres prints a note on stderr)."""
    given = f"{flag} {' '.join(values)}"
    unit = "kilograms" if name == "mass_kg" else "metres (or cm)"
    if not 1 <= len(values) <= 2:
        raise ValueError(
            f"{given}: give a value in {unit} and optionally its std, e.g. {flag} "
            f"{_example(name)} (put the photos before the flags)"
        )
    try:
        stated, note = read_stated_text(name, " ".join(values), "kg" if name == "mass_kg" else "m")
    except ValueError as error:
        raise ValueError(
            f"{given}: {error}; give a value in {unit} and optionally its std, e.g. {flag} "
            f"{_example(name)} (put the photos before the flags)"
        ) from None
    if note:
        print(f"note: {flag} {note}", file=sys.stderr)
    return stated


def _example(name: str) -> str:
    return {"height_m": "1.75 0.02", "mass_kg": "70 2"}.get(name, "0.9 0.02")
