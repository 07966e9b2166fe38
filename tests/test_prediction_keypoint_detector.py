"""KeypointDetector: COCO index mapping, coordinate maps (with a stand-in graph), errors, threads,
and real BlazePose runs (on demo photos when /work/shared/data is present)."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hkpd.body.asset import COCO_KEYPOINT_NAMES
from hkpd.prediction import (
    COCO_FROM_BLAZEPOSE,
    CropTransform,
    KeypointDetector,
    NoPersonFoundError,
    load_image,
)

DEMO_PHOTOS = Path("/work/shared/data/demo_photos")
COCO_MINI = Path("/work/shared/data/coco_mini")
needs_demo_photos = pytest.mark.skipif(
    not DEMO_PHOTOS.is_dir(), reason="demo photos (/work/shared/data/demo_photos) not available"
)


def test_coco_indices_name_the_same_landmarks_in_mediapipe() -> None:
    from mediapipe.python.solutions.pose import PoseLandmark

    names = [PoseLandmark(index).name.lower() for index in COCO_FROM_BLAZEPOSE]
    assert names == list(COCO_KEYPOINT_NAMES)


class MarkerFindingGraph:
    """Stands in for BlazePose: 'detects' every landmark at the centroid of the white pixels of
    the image it is given, and records how many calls overlap in time."""

    def __init__(self) -> None:
        self.calls = 0
        self.active = 0
        self.max_active = 0
        self.shapes: list[tuple[int, ...]] = []

    def process(self, pixels: np.ndarray) -> SimpleNamespace:
        self.active += 1
        self.max_active = max(self.max_active, self.active)
        time.sleep(0.002)
        self.calls += 1
        self.shapes.append(pixels.shape)
        ys, xs = np.nonzero(pixels[:, :, 0] > 127)
        height, width = pixels.shape[:2]
        x, y = (xs.mean() + 0.5) / width, (ys.mean() + 0.5) / height  # MediaPipe: edge = 0
        landmark = SimpleNamespace(x=x, y=y, visibility=0.9)
        self.active -= 1
        return SimpleNamespace(
            pose_landmarks=SimpleNamespace(landmark=[landmark] * 33), segmentation_mask=None
        )

    def close(self) -> None:
        pass


def detector_with(graph: MarkerFindingGraph) -> KeypointDetector:
    detector = KeypointDetector()
    detector._pose = graph
    return detector


def marker_photo() -> np.ndarray:
    """800 x 400 photo with a white 4x4 marker whose centre is original pixel (601.5, 101.5)."""
    photo = np.zeros((400, 800, 3), np.uint8)
    photo[100:104, 600:604] = 255
    return photo


@pytest.mark.parametrize("max_side", [800, 200])
@pytest.mark.parametrize("bbox", [None, (500.0, 50.0, 700.0, 300.0)])
def test_keypoints_come_back_in_original_pixels(max_side: int, bbox: tuple | None) -> None:
    graph = MarkerFindingGraph()
    loaded = load_image(marker_photo(), max_side=max_side)
    detection = detector_with(graph).detect(loaded, bbox=bbox)
    np.testing.assert_allclose(detection.keypoints, np.tile([601.5, 101.5], (17, 1)), atol=1e-9)
    assert detection.image_size == (800, 400)
    np.testing.assert_allclose(detection.confidences, 0.9)
    np.testing.assert_allclose(detection.person_box, [601.5, 101.5, 601.5, 101.5], atol=1e-9)
    if bbox is None:
        assert detection.search_box is None
        assert graph.shapes[0][:2] == loaded.pixels.shape[:2]
    else:
        np.testing.assert_array_equal(detection.search_box, bbox)
        # The search region is the bbox widened by 10 % per side, (480, 25)-(720, 325) in
        # original pixel edges, rounded outwards in working pixels.
        scale = max_side / 800
        rows = np.ceil(325 * scale) - np.floor(25 * scale)
        cols = np.ceil(720 * scale) - np.floor(480 * scale)
        assert graph.shapes[0][:2] == (rows, cols)
    assert detection.seconds > 0


def test_bbox_validation() -> None:
    detector = detector_with(MarkerFindingGraph())
    with pytest.raises(ValueError, match="four finite numbers"):
        detector.detect(marker_photo(), bbox=(1, 2, 3))
    with pytest.raises(ValueError, match="x1 > x0"):
        detector.detect(marker_photo(), bbox=(300, 10, 200, 100))
    with pytest.raises(ValueError, match="outside"):
        detector.detect(marker_photo(), bbox=(900, 10, 1000, 100))
    with pytest.raises(ValueError, match="covers only"):
        detector.detect(marker_photo(), bbox=(798, 10, 820, 100))


def test_calls_from_several_threads_are_serialised() -> None:
    graph = MarkerFindingGraph()
    detector = detector_with(graph)
    photo = marker_photo()
    errors: list[BaseException] = []

    def work() -> None:
        try:
            for _ in range(5):
                detector.detect(photo)
        except BaseException as error:  # pragma: no cover - reported below
            errors.append(error)

    threads = [threading.Thread(target=work) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors
    assert graph.calls == 20 and graph.max_active == 1


def test_closed_detector_refuses_work() -> None:
    with detector_with(MarkerFindingGraph()) as detector:
        detector.detect(marker_photo())
    with pytest.raises(RuntimeError, match="closed"):
        detector.detect(marker_photo())


def test_blank_photo_raises_no_person_found_with_advice() -> None:
    with KeypointDetector() as detector, pytest.raises(NoPersonFoundError, match="--bbox"):
        detector.detect(np.full((240, 320, 3), 90, np.uint8))


@needs_demo_photos
def test_frontal_t_pose_photo_gives_a_plausible_skeleton() -> None:
    with KeypointDetector(segmentation=True) as detector:
        detection = detector.detect(DEMO_PHOTOS / "yogait_t5.jpg")
    k = dict(zip(COCO_KEYPOINT_NAMES, detection.keypoints, strict=True))
    assert detection.image_size == (1080, 720)
    assert (detection.confidences > 0.5).all()
    # Facing the camera: the person's left is on the viewer's right.
    assert k["left_wrist"][0] > k["left_shoulder"][0] > k["right_shoulder"][0] > k["right_wrist"][0]
    assert k["nose"][1] < k["left_shoulder"][1] < k["left_hip"][1] < k["left_knee"][1]
    assert k["left_knee"][1] < k["left_ankle"][1] < 720
    assert k["left_wrist"][0] - k["right_wrist"][0] > 300  # arms out wide
    # The segmentation box holds every keypoint's neighbourhood: it is the person.
    x0, y0, x1, y1 = detection.mask_box
    assert x0 < detection.keypoints[:, 0].min() and detection.keypoints[:, 0].max() < x1
    assert y0 < detection.keypoints[:, 1].min() and detection.keypoints[:, 1].max() < y1


@needs_demo_photos
def test_detection_agrees_with_coco_annotation_and_across_bbox_and_downscale() -> None:
    annotations = COCO_MINI / "annotations" / "person_keypoints_train2017.json"
    if not annotations.is_file():
        pytest.skip("coco_mini annotations not available")
    people = [
        a for a in json.loads(annotations.read_text())["annotations"] if a["image_id"] == 234748
    ]
    truth = np.array(max(people, key=lambda a: a["num_keypoints"])["keypoints"], float)
    truth = truth.reshape(17, 3)
    labelled = truth[:, 2] > 0
    person_height = np.ptp(truth[labelled, 1])

    photo = DEMO_PHOTOS / "coco_000000234748.jpg"
    with KeypointDetector() as detector:
        full = detector.detect(photo)
        # COCO pixel coordinates put pixel centres at +0.5; ours at integers.
        error = np.linalg.norm(full.keypoints - (truth[:, :2] - 0.5), axis=1)[labelled]
        assert np.median(error) < 0.05 * person_height

        restricted = detector.detect(photo, bbox=full.person_box)
        small = detector.detect(load_image(photo, max_side=320))
    for other in (restricted, small):
        shift = np.linalg.norm(other.keypoints - full.keypoints, axis=1)
        assert np.median(shift) < 0.03 * person_height
    crop = CropTransform.from_keypoints(
        full.keypoints, full.confidences, image_size=full.image_size
    )
    inside = crop.image_to_crop(full.keypoints)
    assert ((inside > 0) & (inside < 255)).all()
