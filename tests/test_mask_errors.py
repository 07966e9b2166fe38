"""BlazePose's mask against COCO masks: IoU, the error split, edge offsets, and the table of
``hkpd-eval --mask-errors`` on a tiny COCO folder built here."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from hkpd.evaluation import cli
from hkpd.evaluation.mask_errors import (
    compare_masks,
    mask_error_table,
    split_mask_errors,
)
from hkpd.evaluation.real_photos import load_coco_people
from hkpd.prediction.detection.keypoint_detector import KeypointDetection
from hkpd.prediction.detection.person_mask import PersonMask

SIZE = 256
EVERYWHERE = np.ones((SIZE, SIZE), bool)
NOBODY = np.zeros((SIZE, SIZE), bool)


def disc(radius: float, centre: tuple[float, float] = (128.0, 128.0)) -> np.ndarray:
    rows, cols = np.mgrid[0:SIZE, 0:SIZE]
    return (cols - centre[0]) ** 2 + (rows - centre[1]) ** 2 <= radius**2


def test_the_same_mask_has_no_error() -> None:
    truth = disc(50)
    errors = compare_masks(truth, truth, NOBODY, EVERYWHERE)
    assert errors.iou == 1.0 and errors.blobs == 0
    assert errors.boundary_outward == errors.boundary_inward == errors.missed_parts == 0
    assert np.abs(errors.offsets).max() < 0.6 and abs(errors.offsets.mean()) < 0.2


@pytest.mark.parametrize("radius", [54.0, 46.0])
def test_a_grown_or_shrunk_mask_is_a_boundary_error_of_its_offset(radius: float) -> None:
    truth, predicted = disc(50), disc(radius)
    errors = compare_masks(predicted, truth, NOBODY, EVERYWHERE)
    assert errors.iou == pytest.approx(min(radius, 50) ** 2 / max(radius, 50) ** 2, abs=0.02)
    assert errors.offsets.mean() == pytest.approx(radius - 50, abs=0.5)
    assert errors.offsets.std() < 0.6
    ring = abs(radius**2 - 50**2) / 50**2
    if radius > 50:
        assert errors.boundary_outward == pytest.approx(ring, abs=0.02)
        assert errors.boundary_inward == 0 and (errors.offsets > 0).all()
    else:
        assert errors.boundary_inward == pytest.approx(ring, abs=0.02)
        assert errors.boundary_outward == 0 and (errors.offsets <= 0).all()
    assert errors.missed_parts == errors.other_people == errors.background == 0


def test_far_blobs_on_another_person_or_the_background_and_a_missed_limb() -> None:
    body = disc(40)
    arm = np.zeros_like(body)
    arm[125:131, 180:230] = True  # 12 px from the body: all of it further than the band
    truth = body | arm
    others = np.zeros_like(body)
    others[20:60, 20:60] = True
    predicted = body.copy()
    predicted[30:40, 30:40] = True  # on the other person
    predicted[200:208, 40:48] = True  # on the background
    predicted[240:243, 240:243] = True  # too small to be a blob
    errors = compare_masks(predicted, truth, others, EVERYWHERE)
    area = truth.sum()
    assert errors.missed_parts == pytest.approx(arm.sum() / area)
    assert errors.other_people == pytest.approx(100 / area)
    assert errors.background == pytest.approx((64 + 9) / area)
    assert errors.blobs == 2
    # Pixels outside the photo do not count: hiding the arm hides the miss.
    known = EVERYWHERE.copy()
    known[:, 170:] = False
    assert compare_masks(predicted, truth, others, known).missed_parts == 0


def write_tiny_coco(root: Path) -> None:
    """Two splits, one photo each; val2017's photo has two overlapping people."""
    people = {"train2017": [(60, 40, 80, 200)], "val2017": [(60, 40, 80, 200), (120, 60, 80, 180)]}
    (root / "annotations").mkdir(parents=True)
    for split, boxes in people.items():
        (root / split).mkdir()
        Image.new("RGB", (320, 280), (90, 90, 90)).save(root / split / "1.jpg")
        annotations = []
        for index, (x, y, w, h) in enumerate(boxes):
            keypoints = []
            for k in range(17):
                keypoints += [x + w * (0.2 + 0.6 * (k % 2)), y + h * (0.05 + 0.9 * k / 16), 2]
            polygon = [x, y, x + w, y, x + w, y + h, x, y + h]
            annotations.append(
                {"id": index + 1, "image_id": 1, "keypoints": keypoints, "bbox": [x, y, w, h],
                 "segmentation": [polygon], "iscrowd": 0, "num_keypoints": 17}
            )  # fmt: skip
        data = {"images": [{"id": 1, "file_name": "1.jpg", "width": 320, "height": 280}],
                "annotations": annotations}  # fmt: skip
        (root / "annotations" / f"person_keypoints_{split}.json").write_text(json.dumps(data))


class UnionDetector:
    """Finds each person at their annotated keypoints; the mask is everyone in the photo (a
    segmentation that cannot tell people apart), as probabilities in photo pixels."""

    def __init__(self, everyone) -> None:
        self.by_photo: dict[str, list] = {}
        for person in everyone:
            self.by_photo.setdefault(str(person.image_path), []).append(person)

    def detect(self, image, bbox=None) -> KeypointDetection:
        people = self.by_photo[str(image)]
        centre = (np.asarray(bbox[:2]) + np.asarray(bbox[2:])) / 2
        person = min(people, key=lambda p: np.abs((p.bbox[:2] + p.bbox[2:]) / 2 - centre).sum())
        union = np.zeros((280, 320), np.float32)
        for someone in people:
            union = np.maximum(union, someone.silhouette())
        mask = PersonMask(cv2.GaussianBlur(union, (5, 5), 1.0), np.eye(2, 3), (320, 280))
        return KeypointDetection(
            person.keypoints, np.full(17, 0.9), person.bbox, mask.box(), None, (320, 280), 0.0,
            person_mask=mask,
        )  # fmt: skip


def test_the_mask_error_table_on_a_tiny_coco_folder(tmp_path: Path) -> None:
    write_tiny_coco(tmp_path)
    everyone = load_coco_people(tmp_path, 0)
    results = split_mask_errors(UnionDetector(everyone), load_coco_people(tmp_path, 6), everyone)
    assert list(results) == ["train2017", "val2017"]
    train, val = results["train2017"], results["val2017"]
    assert train.people == 1 and val.people == 2 and train.failed == val.failed == 0
    assert train.mean_iou > 0.97 and train.other_people == 0  # alone: the mask is the person
    assert val.mean_iou < 0.9 and val.other_people > 0.1  # the other person is counted as such
    table = mask_error_table(results)
    lines = table.splitlines()
    assert lines[0].startswith("| split | mean IoU |") and "FP other people" in lines[0]
    assert lines[2].startswith("| train2017 | ") and lines[3].startswith("| val2017 | ")
    assert float(lines[2].split("|")[2]) == pytest.approx(train.mean_iou, abs=1e-3)


def test_mask_errors_needs_coco(tmp_path: Path, capsys) -> None:
    checkpoint = tmp_path / "model.pt"
    checkpoint.write_bytes(b"not read: the arguments are checked first")
    assert cli.main([str(checkpoint), "--no-synthetic", "--mask-errors"]) == 2
    assert "--mask-errors" in capsys.readouterr().err
