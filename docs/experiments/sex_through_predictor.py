"""The sex as the whole predictor reads it on labelled real photos, with and without the face
(issue 57's targets; docs/shape.md section 7).

Every adult of coco_mini labelled female or male in ``people_labels.json`` (beside this script)
is predicted by the shipped predictor in their annotated box, once with the face read (the
default) and once without (``read_face=False``). Printed per split (train2017 for choices,
val2017 reported): balanced accuracy (the mean of the women's and the men's accuracy), ECE of
the more probable sex, how often the body drawn claims a sex ("sure"), and the same on the
people whose face was read; for the face-read people, also those whose face square is >= 60 px
(3.2 times the eye distance as the face reader measures it).

    python docs/experiments/sex_through_predictor.py path/to/coco_mini [--split val2017]
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np
import torch

from hkpd.prediction import Predictor
from hkpd.prediction.detection.face_sex import FaceSexReader

LABELS = Path(__file__).with_name("people_labels.json")
LARGE_FACE_PX = 60.0


def labelled_adults(coco: Path, split: str) -> list[tuple[str, dict]]:
    """``(key, row)`` of the split's adults labelled female or male whose photo exists."""
    people = json.loads(LABELS.read_text())["people"]
    chosen = []
    for key, row in people.items():
        if not key.startswith(split + "/") or row["sex"] not in ("female", "male") or row["child"]:
            continue
        image_id = key.split("/")[1]
        if (coco / split / f"{image_id}.jpg").is_file():
            chosen.append((key, row))
    return chosen


def balanced_accuracy(labels: list[str], p_male: np.ndarray) -> float:
    """Mean of each sex's accuracy (NaN for a sex with nobody)."""
    labels_male = np.asarray([label == "male" for label in labels])
    right = (p_male > 0.5) == labels_male
    per_sex = [
        right[labels_male == sex].mean() for sex in (True, False) if (labels_male == sex).any()
    ]
    return float(np.mean(per_sex)) if per_sex else float("nan")


def ece(labels: list[str], p_male: np.ndarray, bins: int = 5) -> float:
    """Expected calibration error of the more probable sex (equal-width confidence bins)."""
    confidence = np.maximum(p_male, 1 - p_male)
    right = (p_male > 0.5) == np.asarray([label == "male" for label in labels])
    edges = np.linspace(0.5, 1.0, bins + 1)
    total = 0.0
    for low, high in itertools.pairwise(edges):
        inside = (confidence >= low) & ((confidence < high) | (high == 1.0))
        if inside.any():
            total += inside.mean() * abs(right[inside].mean() - confidence[inside].mean())
    return float(total)


def read_people(predictor: Predictor, coco: Path, split: str, people, read_face: bool) -> list:
    """Per person ``(label, p_male, drawn_sex, face_px or None)``."""
    reader = FaceSexReader()
    rows = []
    for key, row in people:
        photo = coco / split / f"{key.split('/')[1]}.jpg"
        try:
            posterior = predictor.predict(photo, bbox=np.asarray(row["bbox"]), read_face=read_face)
        except Exception as error:  # a person the detector misses counts as 50/50
            rows.append((row["sex"], 0.5, "none", None, f"{type(error).__name__}"))
            continue
        spoke = posterior.sex_evidence is not None and posterior.sex_evidence["face"] is not None
        face_px = None
        if spoke:
            face_px = reader.read(
                posterior.network_input.image, posterior.network_input.detection
            ).face_px
        rows.append(
            (row["sex"], posterior.sex_probabilities["male"], posterior.drawn_sex, face_px, "")
        )
    return rows


def summary(rows: list, title: str) -> str:
    """One markdown row."""
    if not rows:
        return f"| {title} | 0 | | | |"
    labels = [row[0] for row in rows]
    p_male = np.asarray([row[1] for row in rows])
    sure = np.mean([row[2] in ("female", "male") for row in rows])
    women = sum(label == "female" for label in labels)
    return (
        f"| {title} | {len(rows)} ({women} women) | {balanced_accuracy(labels, p_male):.2f} | "
        f"{ece(labels, p_male):.3f} | {sure:.0%} |"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coco", type=Path)
    parser.add_argument("--split", default="val2017")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    people = labelled_adults(args.coco, args.split)
    print(f"| {args.split} | people | balanced accuracy | ECE | body claims a sex |")
    print("|---|---|---|---|---|")
    for read_face in (True, False):
        rows = read_people(predictor, args.coco, args.split, people, read_face)
        name = "face + keypoints" if read_face else "keypoints only"
        print(summary(rows, f"{name}: all labelled adults"))
        if read_face:
            faced = [row for row in rows if row[3] is not None]
            print(summary(faced, f"{name}: face read"))
            large = [row for row in faced if row[3] >= LARGE_FACE_PX]
            print(summary(large, f"{name}: face read, >= {LARGE_FACE_PX:.0f} px"))
            missed = [row for row in rows if row[4]]
            print(f"\n(detector found nobody in the box: {len(missed)})\n")


if __name__ == "__main__":
    main()
