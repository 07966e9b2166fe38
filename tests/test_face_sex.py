"""The face reader (hkpd.prediction.detection.face_sex): the face square's geometry on synthetic
face layouts, the gates, the calibration, the batched reader with a stand-in network, and the
shipped photo's man read as male by the shipped faceres."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from hkpd.prediction.detection.face_sex import (
    FACE_CENTRE_BELOW_EYES,
    FACE_GATE_REASONS,
    FACE_SIDE_PER_SCALE,
    MIN_FACE_PX,
    FaceSexReader,
    calibrated_p_male,
    face_gate,
    face_region,
    facing_score,
)
from hkpd.prediction.detection.warp import crop

SHOULDER_DROP = 3.0
"""How far below the eyes the synthetic shoulders are, in eye distances."""


def face_layout(
    centre=(200.0, 150.0), eye_distance=20.0, mouth_drop=22.0, angle=0.0, visibility=1.0
) -> tuple[np.ndarray, np.ndarray]:
    """``(11, 3)`` BlazePose face landmarks of an upright frontal face turned by ``angle``
    (radians, the photo's x towards its y) about its eyes' midpoint ``centre``, and the
    ``(2,)`` shoulders' midpoint below it. The person's left eye is on the photo's right."""
    local = np.zeros((11, 2))
    local[2] = (eye_distance / 2, 0)  # left eye
    local[5] = (-eye_distance / 2, 0)  # right eye
    local[[1, 3]] = local[2] + [[-3, 0], [3, 0]]
    local[[4, 6]] = local[5] + [[3, 0], [-3, 0]]
    local[0] = (0, mouth_drop / 2)  # nose
    local[7], local[8] = (eye_distance, 2), (-eye_distance, 2)  # ears
    local[9], local[10] = (eye_distance / 3, mouth_drop), (-eye_distance / 3, mouth_drop)
    turn = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    points = local @ turn.T + centre
    shoulders = np.array([0.0, SHOULDER_DROP * eye_distance]) @ turn.T + centre
    face = np.concatenate([points, np.full((11, 1), visibility)], axis=1)
    return face, shoulders


@pytest.mark.parametrize("angle_degrees", [0.0, 25.0, -70.0, 160.0])
def test_face_square_is_level_with_the_eyes_and_sized_by_them(angle_degrees):
    angle = math.radians(angle_degrees)
    face, _ = face_layout(angle=angle, eye_distance=20.0, mouth_drop=18.0)
    region = face_region(face)
    assert math.isclose(math.remainder(region.angle - angle, 2 * math.pi), 0.0, abs_tol=1e-9)
    assert region.size == pytest.approx(FACE_SIDE_PER_SCALE * 20.0)
    eyes = (face[2, :2] + face[5, :2]) / 2
    down = np.array([-math.sin(angle), math.cos(angle)])
    assert region.centre == pytest.approx(eyes + down * FACE_CENTRE_BELOW_EYES * 20.0)
    # in crop coordinates both eyes lie on one row, the left eye to the right, the mouth below
    in_crop = region.from_photo(face[:, :2])
    assert in_crop[2, 1] == pytest.approx(in_crop[5, 1])
    assert in_crop[2, 0] > 0.5 > in_crop[5, 0]
    assert in_crop[9, 1] > in_crop[2, 1]


def test_cut_face_shows_the_eyes_level_on_a_rotated_photo():
    """Two bright dots at the eyes of a face turned 35 degrees land on one row of the crop."""
    face, _ = face_layout(centre=(120.0, 110.0), eye_distance=30.0, angle=math.radians(35))
    pixels = np.zeros((240, 240, 3), np.uint8)
    for index in (2, 5):
        u, v = np.round(face[index, :2]).astype(int)
        pixels[v - 2 : v + 3, u - 2 : u + 3] = 255
    region = face_region(face)
    cut = crop(pixels, region, 224, replicate=True)[..., 0].astype(float)
    rows, cols = np.nonzero(cut > 128)
    left, right = cols > 112, cols <= 112
    assert left.any() and right.any()
    # the dots were placed at whole pixels: up to one photo pixel apart across the eye line
    # (the eyes' rows differ by 30 * sin 35 = 17 photo pixels unlevelled)
    crop_pixels_per_photo_pixel = 224 / region.size
    assert abs(rows[left].mean() - rows[right].mean()) < 1.2 * crop_pixels_per_photo_pixel


def test_profile_keeps_its_size_from_the_mouth():
    """Eyes nearly coinciding (a profile): the square is sized by the eyes-to-mouth distance
    and levelled by the mouth axis."""
    face, _ = face_layout(eye_distance=2.0, mouth_drop=20.0, angle=math.radians(10))
    region = face_region(face)
    assert region.size == pytest.approx(FACE_SIDE_PER_SCALE * 20.0)
    assert math.degrees(region.angle) == pytest.approx(10.0, abs=6.0)


def test_facing_score_tells_front_from_back():
    front, shoulders = face_layout()
    back = front.copy()
    back[[2, 5]] = back[[5, 2]]  # the person's left eye on the photo's left: seen from behind
    assert facing_score(front, shoulders) == pytest.approx(1.0)
    assert facing_score(back, shoulders) == pytest.approx(-1.0)
    assert facing_score(front, None) is None


def _gate(face, shoulders, size=(400, 300)):
    return face_gate(face, shoulders, size)[0]


def test_gates():
    face, shoulders = face_layout()
    assert _gate(face, shoulders) is None
    assert _gate(None, shoulders) == "no_face"
    back = face.copy()
    back[[2, 5]] = back[[5, 2]]
    assert _gate(back, shoulders) == "back_view"
    small, small_shoulders = face_layout(eye_distance=4.0, mouth_drop=4.0)
    assert 4.0 * FACE_SIDE_PER_SCALE < MIN_FACE_PX
    assert _gate(small, small_shoulders) == "small_face"
    unsure = face.copy()
    unsure[9, 2] = 0.2
    assert _gate(unsure, shoulders) == "low_confidence"
    upside_down, _ = face_layout(angle=math.pi)
    assert _gate(upside_down, None) == "upside_down"
    cut_off, cut_shoulders = face_layout(centre=(200.0, -30.0))
    assert _gate(cut_off, cut_shoulders) == "face_outside_photo"
    assert set(FACE_GATE_REASONS) == {
        "no_face", "face_outside_photo", "back_view", "small_face", "low_confidence",
        "upside_down", "child",
    }  # fmt: skip


def test_calibration_is_monotone_and_size_term_clipped():
    logits = np.linspace(-4, 4, 9)
    p = calibrated_p_male(logits, 60.0)
    assert np.all(np.diff(p) > 0) and np.all((p > 0) & (p < 1))
    calibration = (0.0, 1.0, 0.5)
    small, large = (calibrated_p_male(2.0, px, calibration) for px in (30.0, 240.0))
    assert small < large
    assert calibrated_p_male(2.0, 240.0, calibration) == calibrated_p_male(
        2.0, 10_000.0, calibration
    )


class StandInNetwork:
    """Records the faces it sees and answers a logit from the crop's mean brightness."""

    def __init__(self, age: int = 40) -> None:
        self.batches: list[torch.Tensor] = []
        self.age = age

    def __call__(self, faces: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        self.batches.append(faces)
        logit = faces.mean(dim=(1, 2, 3)) / 64.0 - 2.0
        ages = torch.zeros(faces.shape[0], 100)
        ages[:, self.age] = 1.0
        return logit, ages


def test_reader_batches_read_faces_and_skips_gated_ones():
    network = StandInNetwork()
    reader = FaceSexReader(network)
    pixels = np.full((300, 400, 3), 200, np.uint8)
    face, shoulders = face_layout()
    back = face.copy()
    back[[2, 5]] = back[[5, 2]]
    with_shoulders = [np.concatenate([f, np.zeros((22, 3))]) for f in (face, back)]
    for points in with_shoulders:
        points[11:13, :2] = shoulders
    readings = reader.read_all(pixels, with_shoulders)
    assert len(network.batches) == 1 and network.batches[0].shape == (1, 224, 224, 3)
    assert network.batches[0].max() <= 255 and network.batches[0].min() >= 0
    front, turned = readings
    assert front.reason is None and front.age_years == pytest.approx(40.0)
    assert front.logit == pytest.approx(200 / 64 - 2.0, abs=1e-4)
    assert front.p_male == pytest.approx(float(calibrated_p_male(front.logit, front.face_px)))
    assert front.face_px == pytest.approx(FACE_SIDE_PER_SCALE * 22.0)
    assert turned.reason == "back_view" and turned.p_male is None and turned.raw is None
    nobody = reader.read_all(pixels, [])
    assert nobody == [] and len(network.batches) == 1


def test_child_face_gives_no_word_but_keeps_its_age():
    face, _ = face_layout()
    pixels = np.full((300, 400, 3), 90, np.uint8)
    child = FaceSexReader(StandInNetwork(age=8)).read(pixels, face)
    assert child.reason == "child" and child.p_male is None
    assert child.age_years == pytest.approx(8.0) and child.raw is not None
    adult = FaceSexReader(StandInNetwork(age=30)).read(pixels, face)
    assert adult.reason is None and adult.p_male is not None


def test_reader_refuses_bad_input():
    reader = FaceSexReader(StandInNetwork())
    face, _ = face_layout()
    with pytest.raises(ValueError, match="uint8 RGB"):
        reader.read(np.zeros((10, 10), np.uint8), face)
    with pytest.raises(ValueError, match=r"\(11, 3\)"):
        reader.read(np.zeros((10, 10, 3), np.uint8), np.zeros((5, 3)))


@pytest.fixture(scope="module")
def shipped_reader() -> FaceSexReader:
    """One reader with the shipped faceres, shared by this module's tests."""
    torch.set_num_threads(1)
    return FaceSexReader()


def test_shipped_photo_man_reads_male(shipped_reader):
    from hkpd.assets import shipped_file
    from hkpd.prediction.detection.keypoint_detector import KeypointDetector
    from hkpd.prediction.image_input import load_image

    photo = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "reinstall")
    loaded = load_image(photo)
    with KeypointDetector(segmentation=False) as detector:
        detection = detector.detect(loaded)
    reading = shipped_reader.read(loaded, detection)
    assert reading.reason is None
    assert reading.face_px > 60
    assert reading.p_male > 0.9
    assert 15 < reading.age_years < 60
