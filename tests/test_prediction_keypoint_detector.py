"""KeypointDetector: COCO index mapping, coordinate maps (with a stand-in runner), errors, threads,
and real BlazePose runs (on demo photos when /work/shared/data is present)."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

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
from hkpd.prediction.detection.blazepose import (
    BLAZEPOSE_LANDMARK_NAMES,
    PersonCandidate,
    PoseLandmarks,
)
from hkpd.prediction.detection.warp import Region

DEMO_PHOTOS = Path("/work/shared/data/demo_photos")
COCO_MINI = Path("/work/shared/data/coco_mini")
needs_demo_photos = pytest.mark.skipif(
    not DEMO_PHOTOS.is_dir(), reason="demo photos (/work/shared/data/demo_photos) not available"
)


def test_coco_indices_name_the_same_landmarks() -> None:
    names = [BLAZEPOSE_LANDMARK_NAMES[index] for index in COCO_FROM_BLAZEPOSE]
    assert names == list(COCO_KEYPOINT_NAMES)


def test_landmark_names_agree_with_mediapipe() -> None:
    pose = pytest.importorskip("mediapipe.python.solutions.pose")

    assert [landmark.name.lower() for landmark in pose.PoseLandmark] == list(
        BLAZEPOSE_LANDMARK_NAMES
    )


class MarkerFindingRunner:
    """Stands in for BlazePose: 'finds' one person at the centroid of the white pixels of the
    image it is given, puts every landmark there, and records how many calls overlap in time."""

    def __init__(self) -> None:
        self.calls = 0
        self.active = 0
        self.max_active = 0
        self.shapes: list[tuple[int, ...]] = []

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]:
        self.active += 1
        self.max_active = max(self.max_active, self.active)
        time.sleep(0.002)
        self.calls += 1
        self.shapes.append(pixels.shape)
        ys, xs = np.nonzero(pixels[:, :, 0] > 127)
        self.active -= 1
        if xs.size == 0:
            return []
        centre = np.array([xs.mean(), ys.mean()])
        region = Region(centre, 10.0, 0.0)
        return [
            PersonCandidate(0.8, np.r_[centre - 5, centre + 5], np.tile(centre, (4, 1)), region)
        ]

    def landmarks(self, pixels: np.ndarray, region: Region, segmentation: bool = False):
        points = np.tile(region.centre, (33, 1))
        return PoseLandmarks(points, np.full(33, 0.9), 0.99, region, None)


def detector_with(runner: MarkerFindingRunner) -> KeypointDetector:
    return KeypointDetector(runner=runner)


def marker_photo() -> np.ndarray:
    """800 x 400 photo with a white 4x4 marker whose centre is original pixel (601.5, 101.5)."""
    photo = np.zeros((400, 800, 3), np.uint8)
    photo[100:104, 600:604] = 255
    return photo


@pytest.mark.parametrize("max_side", [800, 200])
@pytest.mark.parametrize("bbox", [None, (500.0, 50.0, 700.0, 300.0)])
def test_keypoints_come_back_in_original_pixels(max_side: int, bbox: tuple | None) -> None:
    runner = MarkerFindingRunner()
    loaded = load_image(marker_photo(), max_side=max_side)
    detection = detector_with(runner).detect(loaded, bbox=bbox)
    np.testing.assert_allclose(detection.keypoints, np.tile([601.5, 101.5], (17, 1)), atol=1e-9)
    assert detection.image_size == (800, 400)
    np.testing.assert_allclose(detection.confidences, 0.9)
    np.testing.assert_allclose(detection.person_box, [601.5, 101.5, 601.5, 101.5], atol=1e-9)
    if bbox is None:
        assert detection.search_box is None
        assert runner.shapes[0][:2] == loaded.pixels.shape[:2]
    else:
        np.testing.assert_array_equal(detection.search_box, bbox)
        # The search region is the bbox widened by 10 % per side, (480, 25)-(720, 325) in
        # original pixel edges, rounded outwards in working pixels.
        scale = max_side / 800
        rows = np.ceil(325 * scale) - np.floor(25 * scale)
        cols = np.ceil(720 * scale) - np.floor(480 * scale)
        assert runner.shapes[0][:2] == (rows, cols)
    assert detection.seconds > 0


def test_bbox_validation() -> None:
    detector = detector_with(MarkerFindingRunner())
    with pytest.raises(ValueError, match="four finite numbers"):
        detector.detect(marker_photo(), bbox=(1, 2, 3))
    with pytest.raises(ValueError, match="x1 > x0"):
        detector.detect(marker_photo(), bbox=(300, 10, 200, 100))
    with pytest.raises(ValueError, match="outside"):
        detector.detect(marker_photo(), bbox=(900, 10, 1000, 100))
    with pytest.raises(ValueError, match="covers only"):
        detector.detect(marker_photo(), bbox=(798, 10, 820, 100))


def test_calls_from_several_threads_are_serialised() -> None:
    runner = MarkerFindingRunner()
    detector = detector_with(runner)
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
    assert runner.calls == 20 and runner.max_active == 1


def test_closed_detector_refuses_work() -> None:
    with detector_with(MarkerFindingRunner()) as detector:
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


class NobodyRunner(MarkerFindingRunner):
    """Finds nobody; its landmark model 'sees' a person wherever it is pointed."""

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]:
        self.shapes.append(pixels.shape)
        self.regions: list[Region] = []
        return []

    def landmarks(self, pixels: np.ndarray, region: Region, segmentation: bool = False):
        self.regions.append(region)
        return super().landmarks(pixels, region, segmentation)


def test_a_box_the_detector_finds_nobody_in_is_still_read_by_the_landmark_model() -> None:
    runner = NobodyRunner()
    detector = KeypointDetector(runner=runner)
    with pytest.raises(NoPersonFoundError):
        detector.detect(marker_photo())
    found = detector.detect(marker_photo(), bbox=(500.0, 50.0, 700.0, 250.0))
    region, again = runner.regions  # the reading, then the landmark-spread re-read
    assert region.angle == 0.0
    np.testing.assert_allclose(again.centre - region.centre, [0.08 * 250.0, 0.06 * 250.0])
    assert found.landmark_spread is not None
    # Centred on the box (its padded search region is (480, 30)-(720, 270) in pixel edges),
    # 1.25 x its longer side.
    np.testing.assert_allclose(found.keypoints, np.tile([599.5, 149.5], (17, 1)), atol=1e-9)
    assert region.size == pytest.approx(250.0)
    assert found.detector_score is None


class BlobRunner(MarkerFindingRunner):
    """Finds a person only where the part it is shown holds one whole white blob (as a small
    person is found in a part of a photo, not in the whole); landmarks spread over the blob."""

    def find_people(self, pixels):
        self.calls += 1
        ys, xs = np.nonzero(pixels[:, :, 0] > 127)
        if xs.size == 0 or np.ptp(xs) > 40:  # nothing, or two blobs: too small to tell apart
            return []
        centre = np.array([xs.mean(), ys.mean()])
        return [PersonCandidate(0.8, np.r_[centre - 5, centre + 5], np.tile(centre, (4, 1)),
                                Region(centre, 20.0, 0.0))]  # fmt: skip

    def landmarks(self, pixels, region, segmentation=False):
        spread = np.linspace(-8.0, 8.0, 33)[:, None] * np.array([[1.0, 1.5]])
        return PoseLandmarks(region.centre + spread, np.full(33, 0.9), 0.99, region, None)


class TwoBlobRunner(BlobRunner):
    """Finds every blob of the part it is shown (blobs lie 40+ pixels apart in u), scored by
    its brightness (255: 0.9), the best first."""

    def find_people(self, pixels):
        self.calls += 1
        ys, xs = np.nonzero(pixels[:, :, 0] > 100)
        if xs.size == 0:
            return []
        order = np.argsort(xs)
        cuts = np.flatnonzero(np.diff(xs[order]) > 40) + 1
        people = []
        for part in np.split(order, cuts):
            centre = np.array([xs[part].mean(), ys[part].mean()])
            score = 0.9 * pixels[ys[part[0]], xs[part[0]], 0] / 255
            box = np.r_[centre - 5, centre + 5]
            people.append(
                PersonCandidate(score, box, np.tile(centre, (4, 1)), Region(centre, 20.0, 0.0))
            )
        return sorted(people, key=lambda person: -person.score)


def two_blob_photo() -> np.ndarray:
    """600 x 300 photo: a bright blob around (59.5, 49.5), a dimmer one around (529.5, 239.5)."""
    photo = np.zeros((300, 600, 3), np.uint8)
    photo[40:60, 50:70] = 255
    photo[230:250, 520:540] = 200
    return photo


def test_detect_all_returns_one_detection_per_person() -> None:
    found = KeypointDetector(runner=TwoBlobRunner()).detect_all(two_blob_photo(), tiles=1)
    assert [d.detector_score for d in found] == pytest.approx([0.9, 0.9 * 200 / 255])
    np.testing.assert_allclose(found[0].keypoints[0], [59.5 - 8, 49.5 - 12])
    np.testing.assert_allclose(found[1].keypoints[0], [529.5 - 8, 239.5 - 12])
    assert KeypointDetector(runner=NobodyRunner()).detect_all(marker_photo()) == []


def test_detect_all_searches_parts_of_the_photo_and_keeps_each_person_once() -> None:
    photo = np.zeros((300, 600, 3), np.uint8)
    photo[40:60, 50:70] = 255  # two small people far apart: the whole photo shows two blobs
    photo[230:250, 520:540] = 255
    runner = BlobRunner()
    assert KeypointDetector(runner=runner).detect_all(photo, tiles=1) == []
    found = KeypointDetector(runner=runner).detect_all(photo)
    # The whole photo (twice), then the 3 x 3 parts, then each person again in their box, as
    # found and rounded to whole pixels (as the explorer passes it on): 2 x 2.
    assert runner.calls == 1 + 1 + 9 + 2 * 2
    centres = sorted(tuple(np.round((d.person_box[:2] + d.person_box[2:]) / 2, 1)) for d in found)
    assert centres == [(59.5, 49.5), (529.5, 239.5)]  # each once, in photo pixels


def test_tile_bounds_cover_the_photo_with_overlapping_parts() -> None:
    from hkpd.prediction.detection.boxes import box_iou, tile_bounds

    bounds = tile_bounds(600, 300, 3)
    assert (
        bounds[0] == (0, 0, 600, 300)
        and len(bounds) == 10
        and tile_bounds(600, 300, 1) == [(0, 0, 600, 300)]
    )
    covered = np.zeros((300, 600), bool)
    for x0, y0, x1, y1 in bounds[1:]:
        assert 0 <= x0 < x1 <= 600 and 0 <= y0 < y1 <= 300
        assert x1 - x0 <= 300 and y1 - y0 <= 150  # 1.5 cells at most
        covered[y0:y1, x0:x1] = True
    assert covered.all()
    assert box_iou(np.array([0, 0, 10, 10.0]), np.array([5, 0, 15, 10.0])) == pytest.approx(1 / 3)
    assert box_iou(np.zeros(4), np.zeros(4)) == 0.0


SHIPPED_PHOTO = Path(__file__).parents[1] / "assets" / "photos" / "warrior_lunge.jpg"


def test_real_blazepose_on_the_shipped_photo() -> None:
    with KeypointDetector(segmentation=True) as detector:
        found = detector.detect(SHIPPED_PHOTO)
        everyone = detector.detect_all(SHIPPED_PHOTO)
        boxed = detector.detect(SHIPPED_PHOTO, bbox=found.person_box)
    k = dict(zip(COCO_KEYPOINT_NAMES, found.keypoints, strict=True))
    assert found.detector_score > 0.5 and found.presence > 0.5
    assert k["nose"][1] < k["left_hip"][1] < k["left_ankle"][1]
    assert len(everyone) >= 1
    np.testing.assert_allclose(everyone[0].keypoints, found.keypoints, atol=1e-6)
    size = np.ptp(found.keypoints, axis=0).max()
    assert np.median(np.linalg.norm(boxed.keypoints - found.keypoints, axis=1)) < 0.03 * size
    x0, y0, x1, y1 = found.mask_box
    assert (
        x0 <= np.median(found.keypoints[:, 0]) <= x1
        and y0 <= np.median(found.keypoints[:, 1]) <= y1
    )
