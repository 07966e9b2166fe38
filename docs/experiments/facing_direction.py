"""Does the posterior face the right way? Print evidence.md's facing table (issue 42).

A person's facing is shown by COCO's annotations when the person stands upright: seen from the
front, the person's left shoulder and left hip lie to the *right* of the right ones in the
photo; seen from behind, to the left. Exactly (:func:`annotated_facing`), a person counts when:

- the left and right shoulders and hips are all annotated visible (COCO ``v = 2``);
- the torso is upright: the direction from the hips' midpoint to the shoulders' midpoint is
  within :data:`UPRIGHT_DEGREES` of straight up in the photo;
- both pairs agree: ``x(left shoulder) - x(right shoulder)`` and ``x(left hip) - x(right hip)``
  (photo pixels, x to the right) have the same sign, each at least :data:`MIN_SEPARATION` of
  the torso's length (a person seen from the side shows no facing); positive is *facing the
  camera*, negative *seen from behind*.

The posterior's facing is its most likely body's, read two ways: **projected** (the mode's
projected shoulders and hips by the same rule, without the upright and separation conditions:
both pairs must agree with the annotation, a twisted body whose pairs disagree counts as wrong)
and **forward axis** (the global rotation's body-forward axis points towards the camera or away
from it: :func:`hkpd.conditioning.facing.faces_camera`). Each person goes through the full
predictor (BlazePose inside the annotated box grown by 15 %, as ``hkpd-eval --coco`` does); the
network alone, and the evidence posterior fitted from the network's facing only
(``EvidenceConfig(facings=1)``, the fit before issue 42) and from both facings (``facings=2``,
the default since: a half-turned copy is fitted where it explains the keypoints better before
the fit; each line says how many were). People the detector misses are counted apart.

    python docs/experiments/facing_direction.py assets/models/hkpd_hierarchical.pt \\
        --coco ../shared/data/coco_mini
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch

from hkpd.conditioning.facing import faces_camera
from hkpd.evaluation.real_photos import AnnotatedPerson, load_coco_people
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.image_input import ImageInputError
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.predictor import Predictor

SHOULDERS = (5, 6)
"""COCO left and right shoulder."""
HIPS = (11, 12)
"""COCO left and right hip."""
UPRIGHT_DEGREES = 30.0
"""A torso leaning further from upright in the photo shows no facing by this rule (the
predictor's upright-copy threshold)."""
MIN_SEPARATION = 0.1
"""Each pair's horizontal separation, as a fraction of the torso's length, from which its
order counts."""


def pair_offsets(keypoints: np.ndarray) -> tuple[float, float]:
    """``x(left) - x(right)`` of the shoulders and of the hips, ``(17, 2)`` pixels."""
    return (
        float(keypoints[SHOULDERS[0], 0] - keypoints[SHOULDERS[1], 0]),
        float(keypoints[HIPS[0], 0] - keypoints[HIPS[1], 0]),
    )


def annotated_facing(person: AnnotatedPerson) -> bool | None:
    """True: facing the camera, False: seen from behind, None: the annotation does not show it
    (the module docstring's rule)."""
    if not person.visible[[*SHOULDERS, *HIPS]].all():
        return None
    points = person.keypoints
    torso = points[list(SHOULDERS)].mean(0) - points[list(HIPS)].mean(0)
    length = float(np.hypot(*torso))
    if length < 1e-6 or abs(math.degrees(math.atan2(torso[0], -torso[1]))) > UPRIGHT_DEGREES:
        return None
    offsets = pair_offsets(points)
    if min(abs(offset) for offset in offsets) < MIN_SEPARATION * length:
        return None
    if offsets[0] * offsets[1] < 0:
        return None
    return offsets[0] > 0


def projected_facing(posterior: BodyPosterior) -> bool | None:
    """The mode's facing from its projected shoulders and hips (None: the pairs disagree)."""
    offsets = pair_offsets(posterior.mode().keypoints2d[0].double().cpu().numpy())
    if offsets[0] * offsets[1] <= 0:
        return None
    return offsets[0] > 0


@dataclass
class Tally:
    """Counts of one way of predicting over the labelled people."""

    projected: int = 0
    forward: int = 0
    people: int = 0

    def add(self, posterior: BodyPosterior, truth: bool) -> tuple[bool, bool]:
        """Count ``posterior``; return whether its projected and forward facings are right."""
        by_projection = projected_facing(posterior) == truth
        by_axis = bool(faces_camera(posterior.global_orient.double().cpu())) == truth
        self.projected += by_projection
        self.forward += by_axis
        self.people += 1
        return by_projection, by_axis

    def row(self, name: str) -> str:
        def share(count: int) -> str:
            return f"{count} / {self.people} ({100 * count / max(self.people, 1):.0f} %)"

        return f"| {name} | {share(self.projected)} | {share(self.forward)} |"


WAYS = ("network only", "evidence, facings=1", "evidence, facings=2")


def predictions(predictor: Predictor, person: AnnotatedPerson) -> list[BodyPosterior]:
    """The posteriors of :data:`WAYS` for ``person``."""
    box = person.search_box()
    network = predictor.predict(person.image_path, bbox=box, evidence=False)
    posteriors = [network]
    base = predictor.evidence_config
    for facings in (1, 2):
        predictor.evidence_config = replace(base, facings=facings)
        posteriors.append(predictor.predict(person.image_path, bbox=box))
    predictor.evidence_config = base
    return posteriors


def facing_table(predictor: Predictor, people: list[AnnotatedPerson], split: str) -> None:
    """Print one split's table and each person's line."""
    labelled = [(person, annotated_facing(person)) for person in people]
    labelled = [(person, truth) for person, truth in labelled if truth is not None]
    tallies = {way: Tally() for way in WAYS}
    missed = fitted_copies = 0
    for person, truth in labelled:
        try:
            posteriors = predictions(predictor, person)
        except (NoPersonFoundError, ImageInputError):
            missed += 1
            continue
        marks = []
        for way, posterior in zip(WAYS, posteriors, strict=True):
            right = tallies[way].add(posterior, truth)
            marks.append("".join("+" if r else "-" for r in right))
        fit = posteriors[-1].evidence_fit
        turned = bool(fit is not None and fit.succeeded and fit.turned)
        copies = 0
        if fit is not None and fit.costs is not None and fit.turned_initial_costs is not None:
            copies = fit.costs.shape[0] - fit.turned_initial_costs.shape[0]
        fitted_copies += copies
        print(f"  {person.image_path.name} {'front' if truth else 'back '} "
              f"(projected, axis) {' '.join(marks)} copies fitted={copies} "
              f"turned={turned}")  # fmt: skip
    facing = sum(truth for _, truth in labelled)
    print(f"\n{split}: {len(labelled)} people show their facing ({facing} facing the camera, "
          f"{len(labelled) - facing} seen from behind), {missed} not detected; "
          f"facings=2 fitted {fitted_copies} half-turned copies\n")  # fmt: skip
    print("| | mode projected right | forward axis right |\n|---|---|---|")
    for way in WAYS:
        print(tallies[way].row(way))
    print()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--coco", type=Path, required=True)
    parser.add_argument("--splits", nargs="+", default=["train2017", "val2017"])
    args = parser.parse_args(argv)
    torch.manual_seed(0)
    predictor = Predictor.from_pretrained(args.checkpoint, device="cpu")
    people = load_coco_people(args.coco, min_visible=0)
    try:
        for split in args.splits:
            chosen = [person for person in people if person.image_path.parent.name == split]
            facing_table(predictor, chosen, split)
    finally:
        predictor.close()


if __name__ == "__main__":
    main()
