"""Apparent sex from the face (hkpd.prediction.detection.face_sex) on labelled real photos.

Every person labelled female or male in ``people_labels.json`` (beside this script) is found
by the shipped BlazePose inside their labelled box (``KeypointDetector.detect``; a detection
whose keypoints do not match the annotated ones counts as not found), their face is cut from
BlazePose's face landmarks and read by faceres. Printed:

1. the gates' outcomes per split and labelled face visibility;
2. on train2017 + the demo photos (the choices): faceres's raw ranking (AUC) and balanced
   accuracy by smallest face size read;
3. the calibration fitted on train2017 + demo photos (class-balanced maximum likelihood: the
   probability is a likelihood ratio under even odds, as the sex latent uses it);
4. per split: people, found, read, balanced accuracy (all read / faces >= 60 px), expected
   calibration error, and the shipped photo's P(male);
5. the age output (faces passing the other gates) for children and adults.

    python docs/experiments/face_sex_eval.py /work/shared/data/coco_mini \\
        --demo /work/shared/data/demo_photos [--faceres path/to/faceres.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from hkpd.prediction.detection.face_sex import (
    FACE_GATE_REASONS,
    MIN_FACE_PX,
    FaceSexReader,
    calibrated_p_male,
)
from hkpd.prediction.detection.keypoint_detector import KeypointDetector, NoPersonFoundError
from hkpd.prediction.image_input import load_image

LABELS = Path(__file__).with_name("people_labels.json")
SHIPPED_PHOTO = Path(__file__).parents[2] / "assets" / "photos" / "warrior_lunge.jpg"
MATCH_ERROR = 0.1
"""A detection is the labelled person when its head keypoints (nose, eyes, ears) lie within this
fraction of the box's diagonal of the annotated ones (median over those annotated; all annotated
keypoints when no head keypoint is; with fewer than 2 annotated: the detected eyes' midpoint
lies in the labelled box widened by 10 %)."""
LARGE_FACE_PX = 60.0


def photo_path(key: str, coco: Path, demo: Path) -> tuple[str, Path]:
    """``(split, photo)`` of a label key (``train2017/<id>/<ann>``, ``demo_photos/<file>/<n>``,
    ``assets/photos/<file>/<n>``)."""
    parts = key.split("/")
    if parts[0] in ("train2017", "val2017"):
        return parts[0], coco / parts[0] / f"{parts[1]}.jpg"
    if parts[0] == "demo_photos":
        return "demo", demo / parts[1]
    return "shipped", SHIPPED_PHOTO


def annotated_keypoints(coco: Path) -> dict[str, np.ndarray]:
    """``(17, 3)`` COCO keypoints of each annotation, keyed as the labels are."""
    found = {}
    for split in ("train2017", "val2017"):
        data = json.loads((coco / "annotations" / f"person_keypoints_{split}.json").read_text())
        for annotation in data["annotations"]:
            key = f"{split}/{annotation['image_id']:012d}/{annotation['id']}"
            found[key] = np.asarray(annotation["keypoints"], np.float64).reshape(17, 3)
    return found


def is_labelled_person(detection, label: dict, annotated: np.ndarray | None) -> bool:
    """Whether ``detection`` found the labelled person (see :data:`MATCH_ERROR`)."""
    box = np.asarray(label["bbox"], np.float64)
    seen = np.zeros(17, bool) if annotated is None else annotated[:, 2] > 0
    if seen.sum() < 2:
        eyes = detection.keypoints[1:3].mean(0)
        margin = 0.1 * (box[2:] - box[:2])
        return bool(np.all(eyes >= box[:2] - margin) and np.all(eyes <= box[2:] + margin))
    head = seen & (np.arange(17) < 5)
    used = head if head.any() else seen
    error = np.linalg.norm(detection.keypoints[used] - annotated[used, :2], axis=1)
    return float(np.median(error)) <= MATCH_ERROR * float(np.hypot(*(box[2:] - box[:2])))


def collect(coco: Path, demo: Path, reader: FaceSexReader) -> list[dict]:
    """One record per person labelled female or male, or a child: the label, whether the
    detector found them and the raw face reading (no size gate, no calibration)."""
    labels = json.loads(LABELS.read_text())["people"]
    annotated = annotated_keypoints(coco)
    records = []
    with KeypointDetector(segmentation=False) as detector:
        for key, label in labels.items():
            if label["face"] == "crowd" or (label["sex"] == "unsure" and not label["child"]):
                continue
            split, path = photo_path(key, coco, demo)
            record = {"key": key, "split": split, **label, "found": False, "reason": None}
            loaded = load_image(path)
            try:
                detection = detector.detect(loaded, label["bbox"])
            except NoPersonFoundError:
                records.append(record)
                continue
            record["found"] = is_labelled_person(detection, label, annotated.get(key))
            reading = reader.read(loaded, detection)
            record.update(
                reason=reading.reason,
                logit=reading.logit,
                face_px=reading.face_px,
                age=reading.age_years,
                facing=reading.facing,
            )
            records.append(record)
    return records


def balanced_accuracy(male: np.ndarray, p_male: np.ndarray) -> float:
    """Mean of the per-class accuracies of ``p_male > 0.5`` (NaN for an absent class)."""
    said = p_male > 0.5
    rates = [said[male].mean() if male.any() else np.nan]
    rates.append((~said[~male]).mean() if (~male).any() else np.nan)
    return float(np.mean(rates))


def expected_calibration_error(male: np.ndarray, p_male: np.ndarray, bins: int = 5) -> float:
    """Mean |P(male) - fraction male| over ``bins`` equal-width bins, weighted by count."""
    edges = np.linspace(0, 1, bins + 1)
    index = np.clip(np.digitize(p_male, edges) - 1, 0, bins - 1)
    error = 0.0
    for b in range(bins):
        inside = index == b
        if inside.any():
            error += inside.sum() * abs(p_male[inside].mean() - male[inside].mean())
    return float(error / max(len(p_male), 1))


def auc(male: np.ndarray, score: np.ndarray) -> float:
    """P(a man's score > a woman's), ties half."""
    men, women = score[male][:, None], score[~male][None, :]
    if men.size == 0 or women.size == 0:
        return float("nan")
    return float(((men > women) + 0.5 * (men == women)).mean())


def adults(records: list[dict], splits: tuple[str, ...]) -> list[dict]:
    """Found, labelled-sex adults of ``splits``."""
    return [
        r
        for r in records
        if r["split"] in splits and r["found"] and r["sex"] != "unsure" and not r["child"]
    ]


def read_faces(records: list[dict], min_face_px: float) -> list[dict]:
    """Records whose face passes the gates with the size gate at ``min_face_px``."""
    return [r for r in records if r["reason"] is None and r["face_px"] >= min_face_px]


def print_gates(records: list[dict]) -> None:
    print("\n## Gates (found people with a labelled sex or a child; size gate not applied)\n")
    print("| split | labelled face | people | read | " + " | ".join(FACE_GATE_REASONS) + " |")
    print("|---" * (4 + len(FACE_GATE_REASONS)) + "|")
    for split in ("train2017", "demo", "val2017"):
        for face in ("frontal", "profile", "back", "hidden", "too_small"):
            rows = [r for r in records if r["split"] == split and r["found"] and r["face"] == face]
            if not rows:
                continue
            counts = [sum(r["reason"] == g for r in rows) for g in FACE_GATE_REASONS]
            read = sum(r["reason"] is None for r in rows)
            cells = " | ".join(str(c) for c in counts)
            print(f"| {split} | {face} | {len(rows)} | {read} | {cells} |")


def print_size_sweep(records: list[dict]) -> None:
    print("\n## Smallest face read (train2017 + demo adults; raw faceres, threshold 0.5)\n")
    print("| min face px | read | women | AUC | balanced acc |")
    print("|---|---|---|---|---|")
    pool = adults(records, ("train2017", "demo"))
    for threshold in (0, 12, 16, 20, 24, 28, 32, 40):
        read = read_faces(pool, threshold)
        male = np.array([r["sex"] == "male" for r in read])
        logit = np.array([r["logit"] for r in read])
        print(
            f"| {threshold} | {len(read)} | {(~male).sum()} | {auc(male, logit):.2f} | "
            f"{balanced_accuracy(male, 1 / (1 + np.exp(-logit))):.2f} |"
        )


def fit_calibration(records: list[dict]) -> tuple[float, float, float]:
    """Class-balanced maximum likelihood of :func:`calibrated_p_male`'s three numbers on the
    read faces of train2017 + demo adults, with a weak Gaussian prior (sd 1) around (0, 1, 0).
    A smaller face cannot make faceres surer, so the size slope is kept >= 0 (refitted at 0 when
    the free fit makes it negative)."""
    read = read_faces(adults(records, ("train2017", "demo")), MIN_FACE_PX)
    male = torch.tensor([r["sex"] == "male" for r in read], dtype=torch.float64)
    logit = torch.tensor([r["logit"] for r in read], dtype=torch.float64)
    size = torch.tensor([r["face_px"] for r in read], dtype=torch.float64)
    doublings = torch.clamp(torch.log2(size / 60.0), -2, 2)
    weight = torch.where(male > 0, 0.5 / male.sum(), 0.5 / (1 - male).sum()) * len(read)
    start = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)

    def fit(size_free: bool) -> torch.Tensor:
        params = start.clone().requires_grad_(True)
        mask = torch.tensor([1.0, 1.0, 1.0 if size_free else 0.0], dtype=torch.float64)
        optimiser = torch.optim.LBFGS([params], max_iter=200)

        def loss() -> torch.Tensor:
            optimiser.zero_grad()
            a, b, c = params * mask
            z = a + torch.clamp(b + c * doublings, min=0.0) * logit
            nll = (weight * F.binary_cross_entropy_with_logits(z, male, reduction="none")).sum()
            total = nll + 0.5 * ((params * mask - start) ** 2).sum()
            total.backward()
            return total

        optimiser.step(loss)
        return (params * mask).detach()

    params = fit(True)
    if params[2] < 0:
        print(f"\n(free fit: size slope {float(params[2]):.3f} < 0; refitted with it at 0)")
        params = fit(False)
    return tuple(round(float(v), 3) for v in params)


def print_results(records: list[dict], calibration: tuple[float, float, float]) -> None:
    print(f"\n## Results (calibration {calibration}, min face {MIN_FACE_PX:g} px)\n")
    print("| split | adults labelled | found | read | women read | balanced (read) | "
          f"read >= {LARGE_FACE_PX:g} px | balanced (>= {LARGE_FACE_PX:g} px) | ECE |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for split in ("train2017", "demo", "val2017"):
        labelled = [
            r for r in records if r["split"] == split and r["sex"] != "unsure" and not r["child"]
        ]
        read = read_faces(adults(records, (split,)), MIN_FACE_PX)
        male = np.array([r["sex"] == "male" for r in read], bool)
        p = calibrated_p_male(
            np.array([r["logit"] for r in read]), np.array([r["face_px"] for r in read]),
            calibration,
        )  # fmt: skip
        large = np.array([r["face_px"] >= LARGE_FACE_PX for r in read], bool)
        print(
            f"| {split} | {len(labelled)} | {sum(r['found'] for r in labelled)} | {len(read)} | "
            f"{(~male).sum()} | {balanced_accuracy(male, p):.2f} | {large.sum()} | "
            f"{balanced_accuracy(male[large], p[large]):.2f} | "
            f"{expected_calibration_error(male, p):.3f} |"
        )
    for r in records:
        if r["split"] == "shipped":
            p = calibrated_p_male(r["logit"], r["face_px"], calibration)
            print(f"\nshipped photo {r['key']}: face {r['face_px']:.0f} px, raw "
                  f"{1 / (1 + np.exp(-r['logit'])):.3f}, P(male) {float(p):.3f}")  # fmt: skip


def print_people(records: list[dict], calibration: tuple[float, float, float]) -> None:
    print("\n## Each labelled person found (key, label, face label, gate, face px, P(male))\n")
    for r in sorted(records, key=lambda r: (r["split"], r["key"])):
        if not r["found"] or r["sex"] == "unsure":
            continue
        reason = r["reason"] or ("small_face" if r["face_px"] < MIN_FACE_PX else "read")
        p = calibrated_p_male(r["logit"], r["face_px"], calibration) if reason == "read" else None
        shown = "" if p is None else f"{float(p):.2f}"
        print(f"{r['key']:40s} {r['sex']:6s} child={int(r['child'])} {r['face']:9s} "
              f"{reason:18s} {r['face_px']:6.1f} {shown}")  # fmt: skip


def print_ages(records: list[dict]) -> None:
    print("\n## Age (years, faceres) of read faces: children vs adults\n")
    print("| split | group | n | ages (sorted) |")
    print("|---|---|---|---|")
    for split in (("train2017", "demo"), ("val2017",)):
        for child in (True, False):
            rows = [
                r for r in records
                if r["found"] and r["reason"] in (None, "child") and r["face_px"] >= MIN_FACE_PX
                and r["split"] in split and r["child"] == child
            ]  # fmt: skip
            ages = sorted(round(r["age"]) for r in rows)
            if child:
                ages = sorted((round(r["age"]), r["key"]) for r in rows)
            name = "children" if child else "adults"
            print(f"| {'+'.join(split)} | {name} | {len(rows)} | {ages} |")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coco", type=Path)
    parser.add_argument("--demo", type=Path, required=True)
    parser.add_argument("--faceres", type=Path, help="faceres model.json (default: shipped)")
    parser.add_argument("--val", action="store_true", help="also print val2017 (report only)")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    network = None
    if args.faceres is not None:
        from hkpd.model_runtime import GraphModel

        model = GraphModel.load(args.faceres)

        def network(faces):
            out = model.run({"input_1": faces}, ["gender_pred/BiasAdd", "age_pred/Softmax"])
            return out["gender_pred/BiasAdd"][:, 0], out["age_pred/Softmax"]

    reader = FaceSexReader(network, min_face_px=0.0, calibration=(0.0, 1.0, 0.0))
    records = collect(args.coco, args.demo, reader)
    if not args.val:
        records = [r for r in records if r["split"] != "val2017"]
    print_gates(records)
    print_size_sweep(records)
    calibration = fit_calibration(records)
    print_results(records, calibration)
    print_ages(records)
    print_people(records, calibration)


if __name__ == "__main__":
    main()
