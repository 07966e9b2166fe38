"""NanoDet's person boxes (pre/post-processing, no model) and how ``detect_all`` merges them
with BlazePose's detections so that nobody is listed twice (stand-in runners: fast); last, the
real models on the shipped photo with a person pasted inside the man's box."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from hkpd.prediction.detection.blazepose import PersonCandidate, PoseLandmarks
from hkpd.prediction.detection.boxes import box_iou
from hkpd.prediction.detection.keypoint_detector import (
    KeypointDetector,
    people_by_size,
    reading_box,
)
from hkpd.prediction.detection.person_detector import (
    NANODET_BINS,
    NANODET_OUTPUTS,
    NANODET_SIZE,
    NANODET_STRIDES,
    PersonBox,
    PersonDetector,
    decoded_boxes,
    letterboxed,
    suppressed,
)
from hkpd.prediction.detection.person_merge import (
    box_owners,
    inside_fraction,
    kept_people,
    read_fits_box,
    unowned_boxes,
)
from hkpd.prediction.detection.warp import Region


def box(*corners: float) -> np.ndarray:
    return np.array(corners, np.float64)


# --- the merge rules ----------------------------------------------------------------------------


def test_each_box_is_owned_once_by_the_best_overlapping_detection() -> None:
    person = box(100, 100, 200, 400)
    whole, upper_body = box(105, 110, 195, 390), box(110, 110, 190, 250)
    assert box_owners([upper_body, whole], [person]) == [None, 0]
    assert unowned_boxes([upper_body, whole], [person]) == []
    assert unowned_boxes([], [person]) == [0]
    # A detection read in a box owns it, whatever the overlap.
    assert box_owners([upper_body, whole], [person], read_in=[0, None]) == [0, None]


def test_a_box_that_leaves_out_outstretched_arms_is_still_the_persons() -> None:
    # NanoDet boxed a small person's body without the arms; their landmark box is wider.
    body, arms_out = box(674, 290, 747, 473), box(634, 311, 810, 471)
    big_person, big_read = box(362, 153, 794, 576), box(373, 182, 798, 582)
    assert box_owners([big_read, arms_out], [big_person, body]) == [0, 1]
    assert kept_people([big_read, arms_out], [big_person, body]) == [0, 1]
    # A box merely overlapping (not held by) the landmark box is not owned below OWNER_IOU.
    assert box_owners([arms_out], [box(700, 200, 900, 400)]) == [None]


def test_a_person_read_twice_inside_their_own_box_is_listed_once() -> None:
    # The catcher: BlazePose read him whole and again as a part inside his own box.
    catcher, umpire = box(300, 200, 420, 330), box(250, 100, 380, 330)
    whole_catcher, part_of_catcher = box(305, 205, 415, 325), box(320, 210, 380, 280)
    umpire_read = box(255, 105, 375, 325)
    kept = kept_people([whole_catcher, part_of_catcher, umpire_read], [catcher, umpire])
    assert kept == [0, 2]


def test_a_person_inside_another_persons_box_with_a_box_of_their_own_is_kept() -> None:
    adult, child = box(100, 50, 400, 600), box(200, 350, 300, 580)
    adult_read, child_read = box(110, 60, 390, 590), box(205, 355, 295, 575)
    assert inside_fraction(child_read, adult) == 1.0
    assert kept_people([adult_read, child_read], [adult, child]) == [0, 1]
    # Without a box of their own the child inside the adult's box is taken for the adult
    # read again (the rule that drops the catcher's second read) ...
    assert kept_people([adult_read, child_read], [adult]) == [0]
    # ... but a person NanoDet missed who stands in nobody's box is kept.
    assert kept_people([adult_read, box(500, 60, 600, 400)], [adult]) == [0, 1]


def test_a_read_fits_its_box_when_its_confident_keypoints_lie_inside() -> None:
    person = box(100, 100, 200, 300)
    inside = np.tile([150.0, 200.0], (17, 1))
    outside = np.tile([400.0, 200.0], (17, 1))
    all_confident = np.ones(17, bool)
    assert read_fits_box(inside, all_confident, person)
    assert not read_fits_box(outside, all_confident, person)
    # Hidden limbs guessed outside the box do not count against it.
    guessed = inside.copy()
    guessed[11:] = [150.0, 900.0]
    assert read_fits_box(guessed, np.arange(17) < 11, person)
    assert not read_fits_box(guessed, all_confident, person)
    assert not read_fits_box(inside, np.zeros(17, bool), person)


# --- NanoDet's pre- and post-processing ----------------------------------------------------------


def nanodet_outputs(cell: tuple[int, int, int], distances: tuple[int, int, int, int], score: float):
    """Stand-in outputs: every cell scores 0.01 except ``(stride index, row, column)``, whose
    distribution puts all weight on bins ``distances`` (left, top, right, bottom)."""
    outputs = {}
    for level, (stride, (score_name, box_name)) in enumerate(
        zip(NANODET_STRIDES, NANODET_OUTPUTS, strict=True)
    ):
        cells = (NANODET_SIZE // stride) ** 2
        scores = torch.full((1, cells, 80), 0.01)
        logits = torch.zeros((1, cells, 4, NANODET_BINS))
        if level == cell[0]:
            index = cell[1] * (NANODET_SIZE // stride) + cell[2]
            scores[0, index, 0] = score
            for side, bin_index in enumerate(distances):
                logits[0, index, side, bin_index] = 50.0
        outputs[score_name], outputs[box_name] = scores, logits.reshape(1, cells, 44)
    return outputs


def test_decoded_boxes_are_the_cell_centre_moved_by_the_expected_distances() -> None:
    outputs = nanodet_outputs((1, 10, 4), (2, 3, 4, 5), 0.9)  # stride 16, row 10, column 4
    boxes, scores = decoded_boxes(outputs)
    assert boxes.shape == (52 * 52 + 26 * 26 + 13 * 13, 4)
    best = int(np.argmax(scores))
    assert scores[best] == pytest.approx(0.9)
    centre_u, centre_v = (4 + 0.5) * 16, (10 + 0.5) * 16
    expected = [centre_u - 2 * 16, centre_v - 3 * 16, centre_u + 4 * 16, centre_v + 5 * 16]
    np.testing.assert_allclose(boxes[best], expected, atol=1e-6)


def test_letterbox_keeps_the_aspect_and_normalises_as_nanodet() -> None:
    pixels = np.zeros((208, 832, 3), np.uint8)
    pixels[..., 0] = 255  # pure red
    batch, scale = letterboxed(pixels)
    assert batch.shape == (1, 3, 416, 416) and scale == pytest.approx(0.5)
    # BGR order: channel 2 is red, channel 0 blue; the image fills the top 104 rows.
    assert float(batch[0, 2, 50, 200]) == pytest.approx((255 - 123.675) / 58.395, abs=1e-4)
    assert float(batch[0, 0, 50, 200]) == pytest.approx(-103.53 / 57.375, abs=1e-4)
    assert float(batch[0, 2, 300, 200]) == pytest.approx(-123.675 / 58.395, abs=1e-4)
    with pytest.raises(ValueError, match="RGB image"):
        letterboxed(np.zeros((10, 10), np.uint8))


def test_suppression_keeps_the_best_of_overlapping_boxes() -> None:
    boxes = np.array([[0, 0, 10, 10], [1, 0, 11, 10], [50, 50, 60, 60]], np.float64)
    assert suppressed(boxes, np.array([0.5, 0.9, 0.4])) == [1, 2]


def test_person_detector_maps_boxes_back_to_the_image_and_applies_its_threshold() -> None:
    outputs = nanodet_outputs((2, 1, 6), (1, 1, 1, 3), 0.8)  # stride 32, centre (208, 48)
    finder = PersonDetector(threshold=0.5, model=lambda batch: outputs)
    found = finder.find(np.zeros((208, 832, 3), np.uint8))  # scale 0.5
    assert len(found) == 1 and found[0].score == pytest.approx(0.8)
    # Input (176, 16, 240, 144) at scale 0.5, its bottom clipped to the image.
    np.testing.assert_allclose(found[0].box, [352, 32, 480, 208], atol=1e-6)
    assert (
        PersonDetector(threshold=0.9, model=lambda batch: outputs).find(
            np.zeros((208, 832, 3), np.uint8)
        )
        == []
    )


# --- detect_all with stand-in models ------------------------------------------------------------


class FigureRunner:
    """Stands in for BlazePose on photos of upright rectangular figures, each painted with its
    own green value (its id). Its detector finds the figures whose red value is >= 220 (a dim
    figure is a person it misses), one candidate each, and a figure of red 250 twice: whole and
    its upper part alone (the catcher). The landmark model reads the figure under the region's
    centre: its 33 landmarks spread over the part of its extent inside the region's square."""

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]:
        people = []
        for figure in np.unique(pixels[..., 1][pixels[..., 1] > 0]):
            ys, xs = np.nonzero(pixels[..., 1] == figure)
            red = int(pixels[ys[0], xs[0], 0])
            if red < 220:
                continue
            x0, y0, x1, y1 = xs.min(), ys.min(), xs.max() + 1.0, ys.max() + 1.0
            centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
            side = 1.25 * float(max(x1 - x0, y1 - y0))
            people.append(PersonCandidate(0.9, np.r_[x0, y0, x1, y0 + 10], np.tile(centre, (4, 1)),
                                          Region(centre, side, 0.0)))  # fmt: skip
            if red == 250:  # the upper part alone, a second candidate
                top = np.array([centre[0], y0 + (x1 - x0) / 2])
                part = Region(top, x1 - x0, 0.0)
                people.append(PersonCandidate(0.8, np.r_[x0, y0, x1, y0 + 10],
                                              np.tile(top, (4, 1)), part))  # fmt: skip
        return people

    def landmarks(self, pixels, region: Region, segmentation: bool = False) -> PoseLandmarks:
        u, v = np.round(region.centre).astype(int)
        height, width = pixels.shape[:2]
        nobody = PoseLandmarks(np.zeros((33, 2)), np.zeros(33), 0.0, region, None)
        if not (0 <= u < width and 0 <= v < height) or pixels[v, u, 1] == 0:
            return nobody
        ys, xs = np.nonzero(pixels[..., 1] == pixels[v, u, 1])
        half = region.size / 2
        low = np.maximum([xs.min(), ys.min()], region.centre - half)
        high = np.minimum([xs.max() + 1.0, ys.max() + 1.0], region.centre + half)
        points = low + np.linspace(0.05, 0.95, 33)[:, None] * (high - low)
        return PoseLandmarks(points, np.full(33, 0.9), 0.99, region, None)


class BoxFinder:
    """Stands in for NanoDet: the given boxes (photo pixels)."""

    def __init__(self, boxes: list[np.ndarray]) -> None:
        self.boxes = boxes

    def find(self, pixels: np.ndarray) -> list[PersonBox]:
        return [PersonBox(b.copy(), 0.9) for b in self.boxes]


def paint(photo: np.ndarray, figure: int, corners: tuple[int, int, int, int], red: int) -> None:
    x0, y0, x1, y1 = corners
    photo[y0:y1, x0:x1] = (red, figure, 0)


def listed_boxes(found) -> list[list[int]]:
    return sorted(np.round(d.person_box).astype(int).tolist() for d in found)


def test_a_person_the_face_detector_misses_is_read_in_their_box() -> None:
    # Three women; BlazePose's detector misses the third (dim).
    photo = np.zeros((400, 700, 3), np.uint8)
    for figure, (x0, red) in enumerate([(50, 255), (250, 255), (450, 150)], start=1):
        paint(photo, figure, (x0, 100, x0 + 80, 340), red)
    boxes = [box(x0 - 5, 95, x0 + 85, 345) for x0 in (50, 250, 450)]
    alone = KeypointDetector(runner=FigureRunner(), segmentation=False).detect_all(photo, tiles=1)
    assert len(alone) == 2
    detector = KeypointDetector(
        runner=FigureRunner(), segmentation=False, person_finder=BoxFinder(boxes)
    )
    found = detector.detect_all(photo, tiles=1)
    assert len(found) == 3
    third = [d for d in found if d.person_box[0] > 400]
    assert len(third) == 1 and third[0].detector_score is None
    np.testing.assert_array_equal(reading_box(third[0]), boxes[2])
    for person in found:  # each predicts in the box handed on, as predict_all does
        again = detector.detect(photo, bbox=reading_box(person))
        np.testing.assert_allclose(again.person_box, person.person_box)


def test_the_catcher_read_twice_inside_his_own_box_is_listed_once() -> None:
    photo = np.zeros((400, 600, 3), np.uint8)
    paint(photo, 1, (100, 60, 180, 360), 250)  # the catcher: found whole and as a part
    paint(photo, 2, (350, 60, 430, 360), 255)
    alone = KeypointDetector(runner=FigureRunner(), segmentation=False).detect_all(photo, tiles=1)
    assert len(alone) == 3  # what the menu listed before person boxes
    finder = BoxFinder([box(95, 55, 185, 365), box(345, 55, 435, 365)])
    detector = KeypointDetector(runner=FigureRunner(), segmentation=False, person_finder=finder)
    assert listed_boxes(detector.detect_all(photo, tiles=1)) == [
        [104, 75, 176, 345],
        [354, 75, 426, 345],
    ]


def test_a_person_inside_another_persons_box_is_listed_once_and_read_in_their_box() -> None:
    photo = np.zeros((500, 500, 3), np.uint8)
    paint(photo, 1, (100, 40, 400, 480), 255)  # an adult, arms wide
    paint(photo, 2, (120, 300, 200, 470), 255)  # a child in front, inside the adult's box
    finder = BoxFinder([box(95, 35, 405, 485), box(115, 295, 205, 475)])
    detector = KeypointDetector(runner=FigureRunner(), segmentation=False, person_finder=finder)
    found = detector.detect_all(photo, tiles=1)
    assert listed_boxes(found) == [[115, 62, 385, 458], [124, 308, 196, 462]]
    for person in found:
        again = detector.detect(photo, bbox=reading_box(person))
        np.testing.assert_allclose(again.person_box, person.person_box)
    # In the adult's box, the detector finds both; the adult, whose landmarks fill the box, is
    # taken (before: the first found, here the child).
    adult = detector.detect(photo, bbox=(95, 35, 405, 485))
    assert adult.person_box[2] - adult.person_box[0] > 250


# --- the real models ----------------------------------------------------------------------------

SHIPPED_PHOTO = Path(__file__).parents[1] / "assets" / "photos" / "warrior_lunge.jpg"


def person_inside_anothers_box() -> np.ndarray:
    """The shipped photo (CC0) with a copy of its man, at 0.4 of his size, pasted between his
    outstretched right arm and his back leg: a person inside another person's box."""
    photo = Image.open(SHIPPED_PHOTO).convert("RGB")
    small = photo.crop((350, 130, 860, 610)).resize((204, 192), Image.Resampling.BILINEAR)
    photo.paste(small, (630, 290))
    return np.asarray(photo)


def test_the_real_models_list_a_person_inside_anothers_box_once_each() -> None:
    pixels = person_inside_anothers_box()
    with KeypointDetector(segmentation=False) as detector:
        found = people_by_size(detector.detect_all(pixels))
        assert len(found) == 2
        big, small = found
        assert inside_fraction(small.person_box, big.person_box) > 0.9  # inside his box
        assert small.person_box[0] > 600 and small.person_box[2] - small.person_box[0] < 250
        for person, other in ((big, small), (small, big)):
            again = detector.detect(pixels, bbox=reading_box(person))  # as predict_all reads
            assert box_iou(again.person_box, person.person_box) >= 0.8
            assert box_iou(again.person_box, other.person_box) < 0.5


@pytest.mark.slow
def test_predict_all_reads_the_person_inside_anothers_box_once_each() -> None:
    from hkpd.prediction import Predictor

    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    posteriors = predictor.predict_all(person_inside_anothers_box(), sex="male")
    assert len(posteriors) == 2
    big, small = (np.asarray(p.person_box, np.float64) for p in posteriors)
    assert box_iou(big, small) < 0.5  # two people, not one read twice
    assert inside_fraction(small, big) > 0.9 and small[0] > 600
