"""hkpd's own BlazePose runner against the legacy mediapipe solution and human keypoints.

Cases: every photo of ``--demo-photos`` and ``--coco`` (whole photo), and every mostly-visible
annotated person of ``--coco`` (search restricted to the person's box, as ``hkpd-eval`` does).
Prints, over the cases where both found a person, the distance between the two runners' COCO-17
keypoints (original-photo pixels), and per runner the error against the human keypoints
(visible ones, person-box cases).

mediapipe (numpy<2) and hkpd's runner rarely share a venv, so the reference can be saved in one
and read in the other::

    .venv-mediapipe/bin/python benchmarks/bench_keypoint_parity.py --demo-photos DIR \\
        --coco DIR --save-reference mediapipe.npz
    python benchmarks/bench_keypoint_parity.py --demo-photos DIR --coco DIR \\
        --reference mediapipe.npz
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from hkpd.coco_keypoints import COCO17_NAMES
from hkpd.evaluation.real_photos import load_coco_people
from hkpd.prediction.detection.keypoint_detector import COCO_FROM_BLAZEPOSE, KeypointDetector
from hkpd.prediction.image_input import IMAGE_SUFFIXES


def cases(demo: Path | None, coco: Path | None) -> list[tuple[str, Path, np.ndarray | None]]:
    """``(name, photo, bbox or None)`` for every whole photo and annotated person."""
    found = []
    for folder in [demo, *([coco / "train2017", coco / "val2017"] if coco else [])]:
        if folder is not None and folder.is_dir():
            for path in sorted(folder.iterdir()):
                if path.suffix.lower() in IMAGE_SUFFIXES:
                    found.append((f"photo:{folder.name}/{path.name}", path, None))
    if coco is not None:
        for index, person in enumerate(load_coco_people(coco)):
            name = f"person:{person.image_path.parent.name}/{person.image_path.name}:{index}"
            found.append((name, person.image_path, person.bbox))
    return found


def run_mediapipe(todo: list) -> tuple[np.ndarray, list[float]]:
    """``(N, 33, 3)`` landmarks (NaN where no person) and per-case seconds."""
    from hkpd.prediction.detection.mediapipe_reference import MediapipePose

    pose = MediapipePose()
    try:
        return timed_landmarks(pose.landmarks, todo)
    finally:
        pose.close()


def run_hkpd(todo: list) -> tuple[np.ndarray, list[float]]:
    """The same with hkpd's runner (all 33 landmarks, no confidence gate)."""
    detector = KeypointDetector()
    try:
        return timed_landmarks(detector.landmarks33, todo)
    finally:
        detector.close()


def timed_landmarks(landmarks_of, todo: list) -> tuple[np.ndarray, list[float]]:
    """``landmarks_of(path, bbox)`` for every case: ``(N, 33, 3)`` (NaN where it found no
    person) and the seconds of each call."""
    out = np.full((len(todo), 33, 3), np.nan)
    seconds = []
    for i, (_, path, bbox) in enumerate(todo):
        start = time.perf_counter()
        landmarks = landmarks_of(path, bbox)
        seconds.append(time.perf_counter() - start)
        if landmarks is not None:
            out[i] = landmarks
    return out, seconds


def human_errors(
    todo: list, coco: Path | None, landmarks: np.ndarray, scored: np.ndarray
) -> np.ndarray:
    """Pixel errors of visible COCO keypoints of the person-box cases where ``scored``."""
    if coco is None:
        return np.zeros(0)
    people = load_coco_people(coco)
    errors = []
    for (name, _, bbox), found, use in zip(todo, landmarks, scored, strict=True):
        if bbox is None or not use:
            continue
        person = people[int(name.rsplit(":", 1)[1])]
        # COCO puts pixel centres at +0.5, hkpd at integers.
        truth = person.keypoints - 0.5
        distance = np.linalg.norm(found[list(COCO_FROM_BLAZEPOSE), :2] - truth, axis=1)
        errors.extend(distance[person.visible])
    return np.array(errors)


def describe(values: np.ndarray) -> str:
    values = values[np.isfinite(values)]
    if values.size == 0:
        return "n/a"
    return (
        f"median {np.median(values):6.2f}  mean {values.mean():6.2f}  "
        f"p90 {np.percentile(values, 90):6.2f}  (n={values.size})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--demo-photos", type=Path)
    parser.add_argument("--coco", type=Path, help="coco_mini-like folder (annotations/, splits)")
    parser.add_argument("--save-reference", type=Path, help="run mediapipe, save its landmarks")
    parser.add_argument("--reference", type=Path, help="mediapipe landmarks saved before")
    args = parser.parse_args()
    todo = cases(args.demo_photos, args.coco)
    names = np.array([name for name, _, _ in todo])
    print(f"{len(todo)} cases; {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
    if args.save_reference:
        reference, seconds = run_mediapipe(todo)
        np.savez(args.save_reference, names=names, landmarks=reference, seconds=seconds)
        print(f"mediapipe: {np.median(seconds) * 1e3:.1f} ms median per case")
        return
    if args.reference:
        saved = np.load(args.reference)
        if list(saved["names"]) != list(names):
            raise SystemExit(f"{args.reference} was saved for other cases; save it again")
        reference = saved["landmarks"]
    else:
        reference, _ = run_mediapipe(todo)
    ours, seconds = run_hkpd(todo)

    coco = list(COCO_FROM_BLAZEPOSE)
    both = np.isfinite(reference[:, 0, 0]) & np.isfinite(ours[:, 0, 0])
    only_ref = np.isfinite(reference[:, 0, 0]) & ~both
    only_ours = np.isfinite(ours[:, 0, 0]) & ~both
    shift = np.linalg.norm(ours[both][:, coco, :2] - reference[both][:, coco, :2], axis=2)
    print(f"found by both {both.sum()}, only mediapipe {only_ref.sum()}, only hkpd "
          f"{only_ours.sum()}: {list(names[only_ref | only_ours])}")  # fmt: skip
    print(f"hkpd vs mediapipe, COCO-17 px, all keypoints:   {describe(shift.ravel())}")
    print(f"hkpd vs mediapipe, per-case median px:          {describe(np.median(shift, 1))}")
    for group in ("photo:", "person:"):
        rows = np.char.startswith(names[both], group)
        print(f"  {group:8s} cases, all keypoints:          {describe(shift[rows].ravel())}")
    visibility = np.abs(ours[both][:, coco, 2] - reference[both][:, coco, 2])
    print(f"|visibility difference|:                        {describe(visibility.ravel())}")
    for index, name in enumerate(COCO17_NAMES):
        print(f"  {name:15s} {describe(shift[:, index])}")
    print("against human keypoints (person-box cases found by both, visible keypoints, px):")
    print(f"  mediapipe: {describe(human_errors(todo, args.coco, reference, both))}")
    print(f"  hkpd:      {describe(human_errors(todo, args.coco, ours, both))}")
    print(f"hkpd runner: {np.median(seconds) * 1e3:.1f} ms median per case (incl. loading)")


if __name__ == "__main__":
    main()
