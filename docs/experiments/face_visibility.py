"""Does BlazePose tell a person seen from behind by the face? (issue 42, a measurement).

For every ``coco_mini`` person, BlazePose runs as the predictor runs it (the photo loaded at the
working resolution, searched in the box of ``hkpd-eval --coco``: the annotated box grown by
15 %), and one line is printed per detected person:

- ``shown``: the annotated facing where the annotation shows it (``front``/``back``, the rule
  of ``facing_direction.py``), else ``-``; ``face-annotated`` when the annotators marked the
  nose and both eyes visible (COCO ``v = 2``): that person's face is seen;
- ``labels``: the facing BlazePose's labels say (its left shoulder right of its right shoulder
  in the photo: ``front``);
- the landmark model's own *visibility logits* (the number whose sigmoid is the ``visibility``
  that :class:`~hkpd.prediction.detection.keypoint_detector.KeypointDetection` reports as
  confidence; near 1 the probabilities differ little, the logits still do), mean over
  the nose (33-landmark index 0), the six eye landmarks (1-6), the mouth corners (9-10), the
  ears (7-8) and the shoulders (11-12); ``face-sh``: nose minus shoulders;
- ``pres``: the mean *presence* logit of the nose, eyes and mouth (the model's second
  per-landmark score);
- ``nose-z``: the landmark model's depth of the nose minus the shoulders' midpoint, in
  shoulder widths (negative: the nose nearer the camera than the shoulders).

The last lines summarise each quantity by split and shown facing, and list, per score, the
lowest-scoring people a "swap when low" rule would swap first (``docs/evidence.md``, "Facing").
The landmark model's raw output is read by wrapping ``BlazePose``'s private landmark
interpreter (an experiment, not the product path).

    python docs/experiments/face_visibility.py --coco ../shared/data/coco_mini
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hkpd.evaluation.real_photos import AnnotatedPerson, load_coco_people
from hkpd.prediction.detection.blazepose import BlazePose, PersonCandidate, PoseLandmarks
from hkpd.prediction.detection.decoding import LANDMARKS, VALUES_PER_LANDMARK
from hkpd.prediction.detection.keypoint_detector import KeypointDetector, NoPersonFoundError
from hkpd.prediction.detection.warp import Region
from hkpd.prediction.image_input import MAX_IMAGE_SIDE, ImageInputError, load_image

NOSE, EYES, EARS, MOUTH, SHOULDERS = [0], [1, 2, 3, 4, 5, 6], [7, 8], [9, 10], [11, 12]
"""BlazePose's 33-landmark indices."""
FACE = NOSE + EYES + MOUTH
"""The landmarks only a face seen from the front shows."""


def _facing_rule() -> Callable[[AnnotatedPerson], bool | None]:
    """``annotated_facing`` of the sibling experiment ``facing_direction.py``."""
    path = Path(__file__).with_name("facing_direction.py")
    spec = importlib.util.spec_from_file_location("facing_direction", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["facing_direction"] = module  # its dataclasses look themselves up there
    spec.loader.exec_module(module)
    return module.annotated_facing


class _Recorded:
    """The landmark model, passing each call's raw landmark output to ``runner.raw``."""

    def __init__(self, model: object, runner: RecordingRunner) -> None:
        self.model, self.runner = model, runner

    def __getattr__(self, name: str) -> object:
        return getattr(self.model, name)

    def __call__(self, image: np.ndarray) -> dict[str, np.ndarray]:
        outputs = self.model(image)
        values = np.asarray(outputs["Identity"], np.float64)
        self.runner.raw = values.reshape(LANDMARKS, VALUES_PER_LANDMARK)
        return outputs


class RecordingRunner:
    """BlazePose that also keeps the landmark model's raw output of its last call: ``(39, 5)``
    ``x, y, z`` (crop pixels of the 256 crop), visibility logit, presence logit."""

    def __init__(self) -> None:
        self.pose = BlazePose(0.5, segmentation=False)
        self.raw: np.ndarray | None = None
        self.pose._landmarker = _Recorded(self.pose._landmarker, self)

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]:
        return self.pose.find_people(pixels)

    def landmarks(
        self, pixels: np.ndarray, region: Region, segmentation: bool = False
    ) -> PoseLandmarks:
        return self.pose.landmarks(pixels, region, False)


@dataclass
class Row:
    """One detected person's measurement (logits as the model gives them)."""

    name: str
    split: str
    shown: str
    labels: str
    face_annotated: bool
    nose: float
    eyes: float
    mouth: float
    ears: float
    shoulders: float
    presence: float
    nose_depth: float

    @property
    def face_minus_shoulders(self) -> float:
        return self.nose - self.shoulders

    def line(self) -> str:
        return (
            f"{self.name} {self.shown:5} labels={self.labels:5} nose={self.nose:5.1f} "
            f"eyes={self.eyes:5.1f} mouth={self.mouth:5.1f} ears={self.ears:5.1f} "
            f"shoulders={self.shoulders:5.1f} face-sh={self.face_minus_shoulders:5.1f} "
            f"pres={self.presence:5.1f} nose-z={self.nose_depth:5.2f}"
            + (" face-annotated" if self.face_annotated else "")
        )


def measure(person: AnnotatedPerson, raw: np.ndarray, shoulder_offset: float, shown: str) -> Row:
    """The row of ``person`` from the landmark model's ``(39, 5)`` raw output."""
    logits, presence, depth = raw[:, 3], raw[:, 4], raw[:, 2]
    width = float(np.linalg.norm(raw[SHOULDERS[0], :2] - raw[SHOULDERS[1], :2]))
    return Row(
        name=f"{person.image_path.parent.name}/{person.image_path.name}",
        split=person.image_path.parent.name,
        shown=shown,
        labels="front" if shoulder_offset > 0 else "back",
        face_annotated=bool(person.visible[[0, 1, 2]].all()),
        nose=float(logits[NOSE].mean()),
        eyes=float(logits[EYES].mean()),
        mouth=float(logits[MOUTH].mean()),
        ears=float(logits[EARS].mean()),
        shoulders=float(logits[SHOULDERS].mean()),
        presence=float(presence[FACE].mean()),
        nose_depth=float((depth[0] - depth[SHOULDERS].mean()) / max(width, 1e-6)),
    )


SCORES = ("nose", "face_minus_shoulders", "presence")
"""The scores a "swap when low" rule was tried on."""

LOWEST = 12
"""How many of the lowest-scoring candidates :func:`summary` lists per score."""


def summary(rows: list[Row]) -> None:
    """Each quantity's sorted values by split and shown facing; then, per score of
    :data:`SCORES`, the :data:`LOWEST` lowest people a rule could swap (labelled facing the
    camera) among those whose facing is shown or whose face is annotated visible: a rule
    "swap when the score < t" swaps them in this order as ``t`` grows."""
    keys = ("nose", "eyes", "mouth", "face_minus_shoulders", "presence", "nose_depth")
    for split in ("train2017", "val2017"):
        for shown in ("front", "back", "-"):
            chosen = [row for row in rows if row.split == split and row.shown == shown]
            for key in keys:
                values = sorted(round(getattr(row, key), 1) for row in chosen)
                print(f"{split} {shown:5} {key}: {values}")
    seen = sorted(
        round(row.nose, 1) for row in rows if row.face_annotated and row.labels == "front"
    )
    print(f"face annotated visible, labels front ({len(seen)}), nose logit: {seen}")
    candidates = [
        row for row in rows if row.labels == "front" and (row.shown != "-" or row.face_annotated)
    ]
    for key in SCORES:
        print(f"\nlabels front, lowest {key}:")
        for row in sorted(candidates, key=lambda row: getattr(row, key))[:LOWEST]:
            face = " face-annotated" if row.face_annotated else ""
            print(f"  {getattr(row, key):7.3f} {row.name} shown {row.shown}{face}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--coco", type=Path, required=True)
    args = parser.parse_args(argv)
    annotated_facing = _facing_rule()
    runner = RecordingRunner()
    detector = KeypointDetector(segmentation=False, runner=runner)
    rows, missed = [], 0
    for person in load_coco_people(args.coco, min_visible=0):
        shown = {True: "front", False: "back", None: "-"}[annotated_facing(person)]
        try:
            loaded = load_image(person.image_path, max_side=MAX_IMAGE_SIDE)
            detection = detector.detect(loaded, bbox=person.search_box())
        except (NoPersonFoundError, ImageInputError, ValueError):
            missed += 1
            continue
        offset = float(detection.keypoints[5, 0] - detection.keypoints[6, 0])
        rows.append(measure(person, runner.raw, offset, shown))
        print(rows[-1].line())
    print(f"\n{len(rows)} people detected, {missed} not\n")
    summary(rows)


if __name__ == "__main__":
    main()
