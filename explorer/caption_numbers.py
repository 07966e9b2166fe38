"""The numbers a saved page's caption states: mean per-vertex uncertainty of the whole body and
of the limb ends, for posterior A and, when comparing, B and B ÷ A.

Two pages of the same scene state the same numbers (the draw is seeded), so the numbers are
also how a reopened scene is checked against the page it was saved from.
"""

from __future__ import annotations

import numpy as np

from hkpd.explorer.posterior_view import PosteriorView, part_uncertainty

LIMB_ENDS: tuple[tuple[str, str], ...] = (
    ("left forearm", "left_elbow"),
    ("right forearm", "right_elbow"),
    ("left wrist", "left_wrist"),
    ("right wrist", "right_wrist"),
    ("left shin", "left_knee"),
    ("right shin", "right_knee"),
)
"""``(name in captions, SMPL part)``: a part is the vertices its joint moves most (the left
elbow's part is the left forearm, the left wrist's the hand)."""


def limb_uncertainty_cm(view: PosteriorView) -> dict[str, float] | None:
    """Mean uncertainty (cm) of the whole body and of each of :data:`LIMB_ENDS` in ``view``;
    None when its posterior has no body model with part labels (a custom provider's)."""
    labels = getattr(getattr(view.posterior, "body", None), "part_labels", None)
    if labels is None:
        return None
    parts = part_uncertainty(view.uncertainty, np.asarray(labels.cpu()))
    numbers = {"whole body": 100.0 * float(np.mean(view.uncertainty))}
    numbers |= {name: 100.0 * parts[part] for name, part in LIMB_ENDS if part in parts}
    return numbers


def numbers_sentence(view: PosteriorView, compare: PosteriorView | None = None) -> str:
    """A caption sentence with :func:`limb_uncertainty_cm` of A (and of B with B ÷ A)."""
    numbers_a = limb_uncertainty_cm(view)
    if numbers_a is None:
        return ""
    numbers_b = None if compare is None else limb_uncertainty_cm(compare)
    if numbers_b is None:
        listed = "; ".join(f"{name} {cm:.1f} cm" for name, cm in numbers_a.items())
        return f"Mean vertex uncertainty: {listed}."
    listed = "; ".join(
        f"{name} A {cm:.1f} cm, B {numbers_b[name]:.1f} cm (B ÷ A {numbers_b[name] / cm:.2f}×)"
        for name, cm in numbers_a.items()
    )
    return f"Mean vertex uncertainty: {listed}."
