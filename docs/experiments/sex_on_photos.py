"""How often does the automatic sex match a person's apparent sex on real photos? (docs/shape.md)

The coco_mini people that ``load_coco_people`` keeps were labelled by apparent sex by looking
at each crop (``coco_mini_apparent_sex.json`` beside this script: female, male or unclear, and
whether the person is a child). Each labelled person is read by the shipped predictor with their
annotated box as ``bbox`` (keypoints only, and with the person mask), and the more probable sex
is compared with the label. Printed per split (train2017 for choices, val2017 reported): the
accuracy on labelled adults, the mean probability given to the labelled sex, and per person the
probabilities and the measurements' height and mass.

    python docs/experiments/sex_on_photos.py path/to/coco_mini
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch

from hkpd.prediction import Predictor

LABELS = Path(__file__).with_name("coco_mini_apparent_sex.json")


def labelled_people(coco: Path) -> list[dict]:
    """The labelled people whose photo exists in ``coco``, adults with a clear apparent sex."""
    rows = json.loads(LABELS.read_text())["people"]
    return [
        row
        for row in rows
        if row["apparent_sex"] != "unclear" and not row["child"] and (coco / row["photo"]).is_file()
    ]


def read(predictor: Predictor, coco: Path, row: dict) -> dict:
    """The person's sex probabilities, height and mass (mean ± std)."""
    posterior = predictor.predict(coco / row["photo"], bbox=np.asarray(row["bbox"], float))
    measured = posterior.measurements()
    probabilities = posterior.sex_probabilities or {"female": 0.5, "male": 0.5}
    return {
        "p_labelled": probabilities[row["apparent_sex"]],
        "correct": probabilities[row["apparent_sex"]] > 0.5,
        "height": measured["height_m"],
        "mass": measured["mass_kg"],
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coco", type=Path)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    people = labelled_people(args.coco)
    for silhouette in (False, True):
        predictor.silhouette_evidence = silhouette
        print(f"\n## {'keypoints + person mask' if silhouette else 'keypoints only'}\n")
        print("| split | labelled adults | accuracy | mean p(labelled sex) |\n|---|---|---|---|")
        for split in ("train2017", "val2017"):
            chosen = [row for row in people if row["photo"].startswith(split)]
            results = [read(predictor, args.coco, row) for row in chosen]
            for row, result in zip(chosen, results, strict=True):
                height, mass = result["height"], result["mass"]
                print(
                    f"<!-- {row['photo']} {row['apparent_sex']}: p={result['p_labelled']:.2f} "
                    f"height {height[0]:.2f}±{height[1]:.2f} m "
                    f"mass {mass[0]:.0f}±{mass[1]:.0f} kg -->"
                )
            accuracy = np.mean([r["correct"] for r in results]) if results else float("nan")
            mean_p = np.mean([r["p_labelled"] for r in results]) if results else float("nan")
            print(f"| {split} | {len(results)} | {accuracy:.2f} | {mean_p:.2f} |")
    predictor.close()


if __name__ == "__main__":
    main()
