"""Would a person detector that ships with our dependencies raise the Person menu's recall?

OpenCV (``opencv-python``, Apache 2.0) carries the only person detectors with weights among our
dependencies: the HOG pedestrian detector (Dalal-Triggs, its SVM built in) and the Haar full-body
and upper-body cascades (``cv2.data.haarcascades``). On coco_mini's multi-person photos (the
people of ``benchmarks/bench_person_search.py``: >= 2 annotated people with >= 8 keypoints), count
the annotated people a box matches (IoU >= 0.3, one to one) and the boxes given.

    python docs/experiments/extra_person_detectors.py path/to/coco_mini
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from bench_person_search import MIN_ANNOTATED_KEYPOINTS, annotated_people

from hkpd.prediction.detection.boxes import box_iou

MATCH_IOU = 0.3
"""A box matches an annotated person at this overlap (looser than the menu's 0.5)."""


def hog_boxes(photo: np.ndarray) -> list[np.ndarray]:
    """HOG pedestrian boxes ``(x0, y0, x1, y1)`` in photo pixels (photo upscaled to 800 px)."""
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    scale = max(1.0, 800 / max(photo.shape[:2]))
    resized = cv2.resize(photo, None, fx=scale, fy=scale)
    rects, weights = hog.detectMultiScale(resized, winStride=(4, 4), padding=(8, 8), scale=1.05)
    scores = np.ravel(weights) if len(rects) else np.zeros(0)
    return [np.array([x, y, x + w, y + h], float) / scale
            for (x, y, w, h), score in zip(rects, scores, strict=True) if score > 0.5]  # fmt: skip


def cascade_boxes(name: str) -> Callable[[np.ndarray], list[np.ndarray]]:
    """A Haar cascade of ``cv2.data.haarcascades`` as a box function."""
    cascade = cv2.CascadeClassifier(cv2.data.haarcascades + name)

    def boxes(photo: np.ndarray) -> list[np.ndarray]:
        gray = cv2.cvtColor(photo, cv2.COLOR_BGR2GRAY)
        return [np.array([x, y, x + w, y + h], float)
                for (x, y, w, h) in cascade.detectMultiScale(gray, 1.05, 3)]  # fmt: skip

    return boxes


def matched_people(boxes: list[np.ndarray], people: list) -> int:
    """Annotated people that a box matches at IoU >= :data:`MATCH_IOU`, one to one."""
    used: set[int] = set()
    for person in people:
        overlaps = [(box_iou(box, person.box), index)
                    for index, box in enumerate(boxes) if index not in used]  # fmt: skip
        best = max(overlaps, default=(0.0, -1))
        if best[0] >= MATCH_IOU:
            used.add(best[1])
    return len(used)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coco_dir", type=Path)
    coco_dir = parser.parse_args().coco_dir
    detectors = {"HOG pedestrian": hog_boxes,
                 "Haar full body": cascade_boxes("haarcascade_fullbody.xml"),
                 "Haar upper body": cascade_boxes("haarcascade_upperbody.xml")}  # fmt: skip
    print("| detector | people | matched | boxes |\n|---|---|---|---|")
    for name, detector in detectors.items():
        counts = np.zeros(3, int)
        for split in ("train2017", "val2017"):
            for photo, annotated in annotated_people(coco_dir, split).items():
                targets = [a for a in annotated if a.count >= MIN_ANNOTATED_KEYPOINTS]
                if len(targets) >= 2:
                    boxes = detector(cv2.imread(str(photo)))
                    counts += (len(targets), matched_people(boxes, targets), len(boxes))
        print(f"| {name} | {counts[0]} | {counts[1]} | {counts[2]} |")


if __name__ == "__main__":
    main()
