"""Does the second reader as evidence make the mode better (issue 59 part 3)?

Reads coco_mini people of a split through their annotated boxes (grown by 15 %) with the shipped
predictor in three settings and prints the mode's keypoint error (mean over visible keypoints /
the annotated box's longer side) beside BlazePose's own keypoints' error:

- ``blazepose``: ``second_reader=False`` (the predictor before issue 59);
- ``average``: agreed keypoints averaged (:data:`hkpd.prediction.second_evidence.
  SECOND_READER_WEIGHT`), disputed ones kept as BlazePose read them;
- ``average+drop``: and disputed keypoints dropped from the evidence (the shipped rule).

    OMP_NUM_THREADS=1 python docs/experiments/second_evidence_eval.py ../shared/data/coco_mini \
        --split val2017
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

import hkpd.prediction.second_evidence as second_evidence
from hkpd.evaluation.quality_data import MIN_SCORED_KEYPOINTS, reading_error
from hkpd.evaluation.real_photos import load_coco_people
from hkpd.prediction import Predictor
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError

SETTINGS = {"blazepose": (False, True), "average": (True, False), "average+drop": (True, True)}
"""name -> (second_reader, drop disputed)."""


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coco", type=Path)
    parser.add_argument("--split", default="train2017")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    people = [p for p in load_coco_people(args.coco, min_visible=MIN_SCORED_KEYPOINTS)
              if p.image_path.parent.name == args.split]  # fmt: skip
    errors: dict[str, list[float]] = {name: [] for name in (*SETTINGS, "blazepose_keypoints")}
    for person in people:
        size = float((person.bbox[2:] - person.bbox[:2]).max())
        row = {}
        try:
            for name, (second, drop) in SETTINGS.items():
                second_evidence.DROP_DISPUTED = drop
                posterior = predictor.predict(person.image_path, bbox=person.search_box(),
                                              second_reader=second)  # fmt: skip
                mode = posterior.mode().keypoints2d[0].detach().double().numpy()
                row[name] = reading_error(mode, person.keypoints, person.visible, size)
            detected = posterior.network_input.detection.keypoints
            row["blazepose_keypoints"] = reading_error(detected, person.keypoints,
                                                       person.visible, size)  # fmt: skip
        except (NoPersonFoundError, ValueError):
            continue
        for name, value in row.items():
            errors[name].append(value)
    print(f"coco_mini {args.split}: {len(errors['blazepose'])} people (annotated boxes)\n")
    print("| setting | mode error mean | median | off share (> 0.2) | mean / BlazePose kps |")
    print("|---|---|---|---|---|")
    reference = np.mean(errors["blazepose_keypoints"])
    for name, values in errors.items():
        array = np.array(values)
        print(f"| {name} | {array.mean():.4f} | {np.median(array):.4f} | "
              f"{(array > 0.2).mean():.3f} | {array.mean() / reference:.3f} |")  # fmt: skip
    predictor.close()


if __name__ == "__main__":
    main()
