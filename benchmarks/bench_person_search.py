"""Do the whole-photo path and the Person menu give one detector answer? (issues 42 and 44)

For every photo of a COCO keypoint folder (e.g. ``coco_mini``), with the shipped BlazePose
models and hkpd's front end (:func:`hkpd.prediction.network_input.prepare_network_input`, what
``Predictor.predict`` runs before the network):

- the *whole-photo path*: ``prepare_network_input(photo)`` (``predict``, ``hkpd-predict``, the
  explorer's upload), person found or not;
- the *Person menu*: ``KeypointDetector.detect_all(photo)`` (the explorer's list of people);
- each listed person *predicted in their box* (:func:`reading_box`: the person box they were
  found in, or their landmark box): ``prepare_network_input(photo, bbox=box)`` must succeed
  and take the same person (its landmark box overlapping the listed one by
  IoU >= :data:`SAME_PERSON_IOU`).

Menu precision and recall are counted on the *multi-person photos*: photos with two or more
non-crowd annotated people with >= :data:`MIN_ANNOTATED_KEYPOINTS` annotated keypoints
(``v > 0``; coco_mini: 17 photos, 67 people). A listed person is *real* when it matches an
annotated person (any non-crowd person of the photo, annotated keypoints or not) with
``max(OKS, IoU) >= REAL_PERSON_MATCH``: OKS is COCO's object keypoint similarity of the listed
keypoints to the annotated ones (COCO's per-keypoint constants, the annotated area; 0.5 is
COCO's AP50 criterion), IoU the overlap of the landmark box with the annotated box (the only
test for people annotated without keypoints). Matching is one to one, best first: a person
listed twice counts once, the second entry is not real. As in COCO's own evaluation, a listed
person matching nobody whose landmark box lies mostly (:data:`CROWD_INSIDE`) inside a region
annotated as a crowd (``iscrowd``: people not annotated one by one) is ignored, neither real nor
false; the precision is printed without and with that rule. Recall: the annotated people with
enough keypoints that a listed person matched. The false entries are listed by photo.

The menu is ``detect_all`` as shipped: BlazePose's detector plus NanoDet's person boxes
(:mod:`hkpd.prediction.detection.person_detector`); ``--person-threshold`` sets NanoDet's
score threshold, ``--no-person-boxes`` measures BlazePose's detector alone (the menu before
issue 57).

Usage: python benchmarks/bench_person_search.py COCO_DIR [--split train2017|val2017]
    [--person-threshold T | --no-person-boxes]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from PIL import Image

from hkpd.prediction.detection.boxes import box_iou
from hkpd.prediction.detection.keypoint_detector import (
    SAME_PERSON_IOU,
    KeypointDetection,
    KeypointDetector,
    NoPersonFoundError,
    reading_box,
)
from hkpd.prediction.detection.person_detector import PERSON_SCORE_THRESHOLD, PersonDetector
from hkpd.prediction.network_input import prepare_network_input

MIN_ANNOTATED_KEYPOINTS = 8
"""Annotated people with at least this many keypoints (``v > 0``) are the people to find."""

REAL_PERSON_MATCH = 0.5
"""A listed person whose OKS or box IoU with an annotated person reaches this is real."""

CROWD_INSIDE = 0.5
"""A listed person matching nobody with at least this fraction of its landmark box inside a
crowd region is ignored (COCO's evaluation matches detections to crowd regions by the
intersection over the detection's own area)."""

COCO_SIGMAS = (
    np.array([26, 25, 25, 35, 35, 79, 79, 72, 72, 62, 62, 107, 107, 87, 87, 89, 89], np.float64)
    / 1000
)
"""COCO's per-keypoint OKS constants (nose ... ankles)."""


class Annotated(NamedTuple):
    """One non-crowd annotated person: box ``(x0, y0, x1, y1)``, ``(17, 3)`` keypoints
    ``(u, v, flag)``, segmented area (pixels²)."""

    box: np.ndarray
    keypoints: np.ndarray
    area: float

    @property
    def count(self) -> int:
        """Annotated keypoints (flag > 0)."""
        return int((self.keypoints[:, 2] > 0).sum())


def similarity(listed: KeypointDetection, person: Annotated) -> float:
    """``max(OKS, IoU)`` of a listed person and an annotated one."""
    iou = box_iou(listed.person_box, person.box)
    labelled = person.keypoints[:, 2] > 0
    if not labelled.any():
        return iou
    squared = ((listed.keypoints - person.keypoints[:, :2]) ** 2).sum(-1)
    scale = 2 * max(person.area, 1.0) * (2 * COCO_SIGMAS) ** 2
    return max(iou, float(np.exp(-squared / scale)[labelled].mean()))


def annotated_people(coco_dir: Path, split: str) -> dict[Path, list[Annotated]]:
    """Per photo of ``split`` that exists: its non-crowd annotated people."""
    return _annotations(coco_dir, split)[0]


def _annotations(
    coco_dir: Path, split: str
) -> tuple[dict[Path, list[Annotated]], dict[Path, list[np.ndarray]]]:
    """Per photo of ``split`` that exists: its non-crowd annotated people, and the
    ``(x0, y0, x1, y1)`` boxes of its crowd regions."""
    data = json.loads((coco_dir / "annotations" / f"person_keypoints_{split}.json").read_text())
    names = {image["id"]: coco_dir / split / image["file_name"] for image in data["images"]}
    people: dict[Path, list[Annotated]] = {}
    crowds: dict[Path, list[np.ndarray]] = {}
    for path in names.values():
        if path.is_file():
            people[path], crowds[path] = [], []
    for annotation in data["annotations"]:
        path = names[annotation["image_id"]]
        if path not in people:
            continue
        x, y, w, h = annotation["bbox"]
        box = np.array([x, y, x + w, y + h])
        if annotation.get("iscrowd"):
            crowds[path].append(box)
            continue
        keypoints = np.asarray(annotation["keypoints"], np.float64).reshape(17, 3)
        people[path].append(Annotated(box, keypoints, float(annotation["area"])))
    return people, crowds


def in_a_crowd(listed: KeypointDetection, crowds: list[np.ndarray]) -> bool:
    """Whether :data:`CROWD_INSIDE` of the listed landmark box lies inside one crowd region."""
    box = listed.person_box
    area = max(float(np.prod(box[2:] - box[:2])), 1e-9)
    for crowd in crowds:
        overlap = np.clip(np.minimum(box[2:], crowd[2:]) - np.maximum(box[:2], crowd[:2]), 0, None)
        if float(np.prod(overlap)) / area >= CROWD_INSIDE:
            return True
    return False


def matched(listed: list[KeypointDetection], annotated: list[Annotated]) -> list[int | None]:
    """For each listed person, the index of the annotated person it is matched to (one to one,
    best :func:`similarity` first, at least :data:`REAL_PERSON_MATCH`), or None."""
    pairs = sorted(
        ((similarity(person, truth), i, j) for i, person in enumerate(listed)
         for j, truth in enumerate(annotated)),
        reverse=True,
    )  # fmt: skip
    result: list[int | None] = [None] * len(listed)
    taken: set[int] = set()
    for iou, i, j in pairs:
        if iou >= REAL_PERSON_MATCH and result[i] is None and j not in taken:
            result[i] = j
            taken.add(j)
    return result


def in_box_failure(
    detector: KeypointDetector, photo: Path, listed: KeypointDetection
) -> str | None:
    """None when the front end, asked for the person in the listed person's
    :func:`reading_box` (as it is, and in whole pixels as the explorer passes it on), takes that
    person (landmark boxes overlapping by :data:`SAME_PERSON_IOU`); else ``"nobody"`` (no person
    found, or the box refused) or ``"another person"``."""
    width, height = Image.open(photo).size
    box, handed_on = listed.person_box, reading_box(listed)
    for search in (handed_on, np.round(np.clip(handed_on, 0, [width, height, width, height]))):
        try:
            prepared = prepare_network_input(str(photo), detector, bbox=search)
        except (NoPersonFoundError, ValueError):
            return "nobody"
        if box_iou(prepared.detection.person_box, box) < SAME_PERSON_IOU:
            return "another person"
    return None


def whole_photo_finds(detector: KeypointDetector, photo: Path) -> bool:
    """Whether the whole-photo path finds a person."""
    try:
        prepare_network_input(str(photo), detector)
    except NoPersonFoundError:
        return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("coco_dir", type=Path)
    parser.add_argument("--split", choices=("train2017", "val2017"), action="append")
    parser.add_argument("--person-threshold", type=float, default=PERSON_SCORE_THRESHOLD)
    parser.add_argument("--no-person-boxes", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(1)
    detector = KeypointDetector()
    detector.person_finder = (
        None if args.no_person_boxes else PersonDetector(threshold=args.person_threshold)
    )
    print(
        "BlazePose's detector alone"
        if args.no_person_boxes
        else f"with NanoDet's person boxes, threshold {args.person_threshold}"
    )
    for split in args.split or ["train2017", "val2017"]:
        report_split(detector, args.coco_dir, split)


def report_split(detector: KeypointDetector, coco_dir: Path, split: str) -> None:
    """Print one split's rows (see the module docstring)."""
    people, crowds = _annotations(coco_dir, split)
    dead_ends, listed_count, failing, real, found, wanted, multi = [], 0, [], 0, 0, 0, 0
    multi_listed, ignored, false_entries, seconds = 0, 0, [], []
    for photo, truths in sorted(people.items()):
        start = time.perf_counter()
        listed = detector.detect_all(str(photo))
        seconds.append(time.perf_counter() - start)
        listed_count += len(listed)
        if listed and not whole_photo_finds(detector, photo):
            dead_ends.append(f"{photo.name} ({len(listed)} listed)")
        for i, person in enumerate(listed):
            failure = in_box_failure(detector, photo, person)
            if failure is not None:
                failing.append(f"{photo.name} #{i + 1} ({failure})")
        targets = [person.count >= MIN_ANNOTATED_KEYPOINTS for person in truths]
        if sum(targets) < 2:
            continue
        multi += 1
        matches = matched(listed, truths)
        multi_listed += len(listed)
        real += sum(match is not None for match in matches)
        found += sum(match is not None and targets[match] for match in matches)
        wanted += sum(targets)
        for i, (person, match) in enumerate(zip(listed, matches, strict=True)):
            if match is None and in_a_crowd(person, crowds[photo]):
                ignored += 1
            elif match is None:
                false_entries.append(f"{photo.name} #{i + 1} {np.round(person.person_box)}")
    print(
        f"## {split}: {len(people)} photos, {listed_count} people listed "
        f"(detect_all {1e3 * float(np.median(seconds)):.0f} ms median a photo, "
        f"load {os.getloadavg()[0]:.1f})"
    )
    print(f"- menu lists someone, whole-photo path finds nobody: {len(dead_ends)} {dead_ends}")
    print(f"- listed people failing in their box: {len(failing)} of {listed_count} {failing}")
    precision = real / multi_listed if multi_listed else float("nan")
    counted = multi_listed - ignored
    coco_precision = real / counted if counted else float("nan")
    print(f"- multi-person photos ({multi}): {multi_listed} listed, {real} real, precision "
          f"{precision:.2f}; {ignored} in crowd regions ignored as COCO does: precision "
          f"{coco_precision:.2f}; recall {found} of {wanted} annotated people")  # fmt: skip
    print(f"- false entries: {false_entries}")


if __name__ == "__main__":
    main()
