"""COCO-17 2D keypoints of the people in a photo, from BlazePose.

:class:`KeypointDetector` runs BlazePose's own two models with hkpd's pipeline
(:mod:`hkpd.prediction.detection.blazepose`; the "full" landmark model, whose weights ship in
``hkpd.assets/blazepose``: nothing is downloaded). BlazePose finds 33 landmarks per person; the
17 COCO keypoints are a subset (:data:`COCO_FROM_BLAZEPOSE`), and each keypoint's confidence is
BlazePose's landmark visibility in [0, 1]. The ten hand and foot landmarks (17-22 knuckles and
thumbs, 29-32 heels and toes: :data:`hkpd.body.extremity_landmarks.BLAZEPOSE_EXTREMITY_INDICES`)
are kept beside them as ``extremities``, with their own visibilities.

- :meth:`KeypointDetector.detect`: one person, the detector's best; ``bbox`` restricts the
  search to one region (widened by :data:`SEARCH_BOX_PADDING`). When the detector finds nobody
  inside the box, the landmark model still looks at the box itself, taken as upright.
- :meth:`KeypointDetector.detect_all`: one detection per person found, by BlazePose's detector
  or by NanoDet's whole-person boxes (:mod:`~hkpd.prediction.detection.person_detector`), each
  person once (:mod:`~hkpd.prediction.detection.person_merge`).

Coordinates are ``(u, v)`` pixels of the ORIGINAL photo (see :mod:`hkpd.prediction.image_input`),
pixel centres at integer coordinates.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_INDICES
from hkpd.prediction.detection.blazepose import (
    POSE_PRESENCE_THRESHOLD,
    REGION_SCALE,
    BlazePose,
    PersonCandidate,
    PoseLandmarks,
)
from hkpd.prediction.detection.boxes import (
    MIN_SEARCH_REGION,
    SEARCH_BOX_PADDING,
    box_iou,
    clipped_box,
    no_person_message,
    search_region,
    tile_bounds,
    validated_box,
)
from hkpd.prediction.detection.landmark_spread import landmark_spread
from hkpd.prediction.detection.person_detector import PersonBox, PersonDetector
from hkpd.prediction.detection.person_mask import PersonMask
from hkpd.prediction.detection.person_merge import kept_people, read_fits_box, unowned_boxes
from hkpd.prediction.detection.warp import Region
from hkpd.prediction.image_input import LoadedImage, load_image
from hkpd.proxy import CONFIDENCE_THRESHOLD

if TYPE_CHECKING:
    from hkpd.prediction.detection.movenet import SecondReading

__all__ = [
    "COCO_FROM_BLAZEPOSE",
    "CONFIDENT_VISIBILITY",
    "MIN_CONFIDENT_KEYPOINTS",
    "MIN_SEARCH_REGION",
    "SEARCH_BOX_PADDING",
    "KeypointDetection",
    "KeypointDetector",
    "NoPersonFoundError",
    "PersonFinder",
    "PoseRunner",
    "people_by_size",
    "reading_box",
    "same_person",
]

COCO_FROM_BLAZEPOSE = (0, 2, 5, 7, 8, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)
"""BlazePose landmark index of each COCO-17 keypoint, in COCO order (nose, left eye, right eye,
left ear, right ear, left/right shoulder, elbow, wrist, hip, knee, ankle)."""

DETECT_ALL_TILES = 3
"""Grid of photo parts :meth:`KeypointDetector.detect_all` also searches (on ``coco_mini``'s
photos of several people it found 11 of 67 people on the whole photo alone, 32 with a 3 × 3
grid; about 0.2 s a photo)."""

SAME_PERSON_IOU = 0.5
"""Two detections whose landmark boxes overlap this much (intersection over union) are one
person found twice (on the whole photo and in a part, or in two parts)."""

SAME_KEYPOINTS_DISTANCE = 0.1
"""Two detections whose keypoints confident in both lie within this fraction of the smaller
landmark box's longer side of each other (median) are one person found twice, however their
boxes overlap (e.g. the whole person and their upper body alone)."""

SAME_KEYPOINTS_MIN = 3
"""Keypoints confident in both detections needed to compare their keypoints."""

MIN_CONFIDENT_KEYPOINTS = 4
"""A detection with fewer COCO keypoints of confidence >= :data:`CONFIDENT_VISIBILITY` counts as
no person (BlazePose occasionally hallucinates a pose on clutter)."""

CONFIDENT_VISIBILITY = 0.5
"""Visibility at which a keypoint counts towards :data:`MIN_CONFIDENT_KEYPOINTS`."""

IN_BOX_CANDIDATES = 3
"""When BlazePose's detector finds several people inside a box, :meth:`KeypointDetector.detect`
reads the first this many and takes the one whose landmark box overlaps the box most (the
person the box is about, not a neighbour whose face is inside it)."""

BOX_REGION_SIDES = (REGION_SCALE, 1.7)
"""Sides, as multiples of a box's longer side, of the upright squares in which
:meth:`KeypointDetector.detect` looks for the person of a box when BlazePose's detector finds
nobody there or its find yields no pose (NanoDet's boxes of small people on coco_mini
train2017: 1.7 read 21 of 36 people, 1.4 16, 1.25 15: the landmark model wants context)."""

BOX_READ_IOU = 0.3
"""A person read in a box of the ``person_finder`` is listed only when their landmark box
overlaps that box this much (IoU): a read of a part of the person (their legs alone, a hand
taken for a person) is not listed (coco_mini train2017, NanoDet at 0.35: precision 0.75 ->
0.86 at the same recall; 0.4: 0.88 with one person fewer)."""

FACE_LANDMARK_COUNT = 11
"""BlazePose's landmarks 0-10 are the face's (kept as ``KeypointDetection.face_landmarks``)."""


class NoPersonFoundError(RuntimeError):
    """The detector found no person; the message suggests what to try."""


@dataclass(frozen=True)
class KeypointDetection:
    """One person's COCO-17 keypoints in original-photo pixels.

    Attributes:
        keypoints: ``(17, 2)`` float64 ``(u, v)`` in original-photo pixels, COCO order. Points
            BlazePose places outside the photo (out-of-frame limbs) are kept as predicted.
        confidences: ``(17,)`` float64 in [0, 1], BlazePose's landmark visibility.
        person_box: ``(4,)`` ``(x0, y0, x1, y1)`` bounding box of all 33 BlazePose landmarks,
            original pixels, clipped to the photo: which person was taken.
        mask_box: ``(4,)`` box of BlazePose's person segmentation mask (includes hair, hands and
            feet), original pixels, clipped to the photo; None when the detector was made with
            ``segmentation=False`` (or when the mask is empty).
        search_box: the ``bbox`` the search was restricted to (original pixels), or None.
        image_size: ``(width, height)`` of the original photo.
        seconds: wall time of the models and decoding (lock wait excluded), seconds.
        detector_score: the person detector's score in [0, 1]; None when the landmark model
            looked at the user's box because the detector found nobody inside it.
        presence: the landmark model's pose-presence score in [0, 1] (None if unknown).
        person_mask: BlazePose's segmentation of this person, mapped to the original photo
            (:class:`PersonMask`: ``in_photo()``, ``in_frame(...)``); None when the detector
            was made with ``segmentation=False``.
        extremities: ``(10, 2)`` float64 BlazePose's hand and foot landmarks (pinky, index,
            thumb, heel, foot index; left then right of each: ``BLAZEPOSE_EXTREMITY_NAMES``) in
            original-photo pixels, mapped as the keypoints are; None when not known (a
            detection made by hand from 17 keypoints).
        extremity_confidences: ``(10,)`` float64 in [0, 1], their visibilities; None with
            ``extremities``.
        landmark_spread: how far the keypoints move, as a fraction of the person's size, when
            the landmark model reads the person again from a slightly moved crop
            (:func:`~hkpd.prediction.detection.landmark_spread.landmark_spread`); None when not
            measured (detections made by hand).
        face_landmarks: ``(11, 3)`` float64 BlazePose's face landmarks 0-10 (nose; left eye
            inner, centre, outer; right eye inner, centre, outer; left ear; right ear; mouth
            left; mouth right) as ``(u, v, visibility)``, original-photo pixels, visibility in
            [0, 1] (:mod:`hkpd.prediction.detection.face_sex` cuts the face from them); None
            when not known (a detection made by hand).
        second_reading: the second keypoint reader's reading of the same person
            (:class:`~hkpd.prediction.detection.movenet.SecondReading`, MoveNet Thunder, issue
            59), made once per photo and person box by the predictor; None when not read.
    """

    keypoints: np.ndarray
    confidences: np.ndarray
    person_box: np.ndarray
    mask_box: np.ndarray | None
    search_box: np.ndarray | None
    image_size: tuple[int, int]
    seconds: float
    detector_score: float | None = None
    presence: float | None = None
    person_mask: PersonMask | None = None
    extremities: np.ndarray | None = None
    extremity_confidences: np.ndarray | None = None
    landmark_spread: float | None = None
    face_landmarks: np.ndarray | None = None
    second_reading: SecondReading | None = None

    def __repr__(self) -> str:
        """One line of at most 200 characters: how many keypoints are confident, the person's
        box, the photo's size, the scores (never the arrays)."""
        confident = int(np.count_nonzero(np.asarray(self.confidences) >= CONFIDENCE_THRESHOLD))
        box = ", ".join(f"{value:.0f}" for value in np.asarray(self.person_box).ravel()[:4])
        score = "" if self.detector_score is None else f", detector_score={self.detector_score:.2f}"
        mask = "" if self.person_mask is None else ", person mask"
        return (
            f"KeypointDetection({len(self.keypoints)} keypoints, {confident} with confidence >= "
            f"{CONFIDENCE_THRESHOLD}, person_box=({box}), photo "
            "{}x{}".format(*self.image_size)
            + f"{score}{mask})"
        )


class PoseRunner(Protocol):
    """What :class:`KeypointDetector` needs from a pose model (:class:`BlazePose`, or a stand-in
    in tests). Coordinates are pixels of the array passed in."""

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]: ...

    def landmarks(
        self, pixels: np.ndarray, region: Region, segmentation: bool = False
    ) -> PoseLandmarks: ...


class PersonFinder(Protocol):
    """What :meth:`KeypointDetector.detect_all` needs from a whole-person detector
    (:class:`PersonDetector`, or a stand-in in tests): boxes in pixels of the array passed in,
    highest score first."""

    def find(self, pixels: np.ndarray) -> list[PersonBox]: ...


def reading_box(detection: KeypointDetection) -> np.ndarray:
    """The box in which :meth:`KeypointDetector.detect` reads ``detection``'s person again:
    the box it was found in (``search_box``: a person box of :meth:`KeypointDetector.detect_all`
    or the user's box), else its landmark box. :meth:`hkpd.prediction.Predictor.predict_all`,
    ``hkpd-predict --all-people`` and the Person menu predict each person in it."""
    return detection.person_box if detection.search_box is None else detection.search_box


def people_by_size(detections: Sequence[KeypointDetection]) -> list[KeypointDetection]:
    """``detections`` ranked by the area of their person boxes, largest first (a stable sort:
    equal sizes keep the detector's order), so people far smaller than the largest, e.g.
    spectators, come after the rest: the order of the Person menu and of
    :meth:`hkpd.prediction.Predictor.predict_all`."""

    def area(detection: KeypointDetection) -> float:
        x0, y0, x1, y1 = (float(v) for v in detection.person_box)
        return max(x1 - x0, 0.0) * max(y1 - y0, 0.0)

    return sorted(detections, key=area, reverse=True)


class KeypointDetector:
    """BlazePose keypoint detector; the models are loaded on first use and reused.

    Thread-safe: calls from several threads are serialised by a lock (the interpreters hold
    state). Close it with :meth:`close` or use it as a context manager.

    Args:
        segmentation: also run BlazePose's person segmentation and report ``person_mask`` and
            ``mask_box`` (on by default: the silhouette evidence; the keypoints are identical
            either way; the head costs about 3.4 ms CPU a call, docs/benchmarks.md).
        min_detection_confidence: BlazePose's person-detector threshold.
        runner: the pose model (default: :class:`BlazePose` with the shipped models).
        person_finder: the whole-person boxes :meth:`detect_all` reads the people BlazePose's
            detector missed in (default: the shipped NanoDet, :class:`PersonDetector`, when
            ``runner`` is the default too; none with a stand-in ``runner``).
    """

    def __init__(
        self,
        segmentation: bool = True,
        min_detection_confidence: float = 0.5,
        runner: PoseRunner | None = None,
        person_finder: PersonFinder | None = None,
    ) -> None:
        self.segmentation = segmentation
        self.min_detection_confidence = min_detection_confidence
        self._runner = runner
        if person_finder is None and runner is None:
            person_finder = PersonDetector()
        self.person_finder = person_finder
        self._lock = threading.Lock()
        self._closed = False

    def __enter__(self) -> KeypointDetector:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Release the models. A later :meth:`detect` raises."""
        with self._lock:
            self._runner = None
            self._closed = True

    def _pose_runner(self) -> PoseRunner:
        """The runner, created on first use (call with the lock held)."""
        if self._closed:
            raise RuntimeError("this KeypointDetector has been closed; create a new one")
        if self._runner is None:
            self._runner = BlazePose(self.min_detection_confidence, segmentation=self.segmentation)
        return self._runner

    def detect(
        self,
        image: LoadedImage | np.ndarray | str,
        bbox: Sequence[float] | np.ndarray | None = None,
    ) -> KeypointDetection:
        """Detect one person's COCO-17 keypoints: the detector's best in the photo or ``bbox``.

        Args:
            image: a :class:`LoadedImage` (coordinates are mapped back to its original photo),
                an ``(H, W, 3)`` uint8 RGB array, or anything else :func:`load_image` accepts.
            bbox: optional ``(x0, y0, x1, y1)`` in original-photo pixels: look for the person
                only there (widened by :data:`SEARCH_BOX_PADDING`, clipped to the photo).

        Returns:
            The :class:`KeypointDetection`.

        Raises:
            NoPersonFoundError: no person (or too few confident keypoints) in the image/region.
            ValueError: a malformed ``bbox``, or one outside the photo.
            ImageInputError: ``image`` could not be loaded.
        """
        loaded = load_image(image)
        if bbox is None:
            return self._detect_whole_photo(loaded)
        return self._detect_in_box(loaded, validated_box(bbox, loaded.original_size))

    def _detect_whole_photo(self, loaded: LoadedImage) -> KeypointDetection:
        """The detector's best person on the whole photo; when it finds nobody there (or too
        few confident keypoints), the first person of :meth:`detect_all` (the Person menu's
        grid search), so that both give one answer."""
        with self._lock:
            runner = self._pose_runner()
            start = time.perf_counter()
            people = runner.find_people(loaded.pixels)
            found = None
            if people:
                found = runner.landmarks(loaded.pixels, people[0].region, self.segmentation)
            seconds = time.perf_counter() - start
            score = people[0].score if people else None
            detection = (
                None
                if found is None
                else _to_detection(found, loaded, (0, 0), None, seconds, score)
            )
            if detection is not None:
                spread = landmark_spread(runner, loaded.pixels, found, COCO_FROM_BLAZEPOSE)
                return replace(detection, landmark_spread=spread)
        listed = self.detect_all(loaded)
        if listed:
            return listed[0]
        raise NoPersonFoundError(
            no_person_message(loaded, None)
            + (
                ""
                if found is None
                else f" (a pose was found but fewer than "
                f"{MIN_CONFIDENT_KEYPOINTS} keypoints were visible with confidence)"
            )
        )

    def _detect_in_box(
        self, loaded: LoadedImage, search_box: np.ndarray, spread: bool = True
    ) -> KeypointDetection:
        """The detector's best person inside the checked ``search_box`` (original pixels);
        ``spread``: also measure its ``landmark_spread``.

        The landmark model looks where BlazePose's detector found the person (of several, the
        one whose landmarks fill the box best: :func:`_person_of_box`); when it found nobody,
        or no person is read there, it looks at the box itself, taken as upright, in squares
        of :data:`BOX_REGION_SIDES` times the box's longer side, the first read person
        taken."""
        x0, y0, x1, y1 = search_region(loaded, search_box)
        pixels = np.ascontiguousarray(loaded.pixels[y0:y1, x0:x1])
        with self._lock:
            runner = self._pose_runner()
            start = time.perf_counter()
            people = runner.find_people(pixels)
            if len(people) > 1:
                sx, sy = loaded.scale
                corners = (search_box + 0.5) * np.array([sx, sy, sx, sy]) - 0.5
                box = corners - np.array([x0, y0, x0, y0], np.float64)
                people = [_person_of_box(runner, pixels, people, box)]
            looks = [(people[0].region, people[0].score)] if people else []
            looks += [(_box_region(x1 - x0, y1 - y0, side), None) for side in BOX_REGION_SIDES]
            for look_at, score in looks:
                found = runner.landmarks(pixels, look_at, self.segmentation)
                seconds = time.perf_counter() - start
                detection = _to_detection(found, loaded, (x0, y0), search_box, seconds, score)
                if detection is not None:
                    break
            if detection is not None and spread:
                moved = landmark_spread(runner, pixels, found, COCO_FROM_BLAZEPOSE)
                detection = replace(detection, landmark_spread=moved)
        if detection is None:
            raise NoPersonFoundError(
                no_person_message(loaded, search_box)
                + f" (a pose was found but fewer than {MIN_CONFIDENT_KEYPOINTS} keypoints were "
                "visible with confidence)"
            )
        return detection

    def detect_all(
        self, image: LoadedImage | np.ndarray | str, tiles: int = DETECT_ALL_TILES
    ) -> list[KeypointDetection]:
        """One detection per person found, the whole photo's people first: the Person menu.

        BlazePose's detector sees the photo at 224 × 224 pixels, where people in a group photo
        are often too small to find; it therefore also looks at a ``tiles × tiles`` grid of
        overlapping parts of the photo (:func:`tile_bounds`; ``tiles=1``: the whole photo
        only). Candidates are taken whole-photo first, then by score. A candidate is listed
        only when (:func:`same_person`, :meth:`_confirmed`):

        - its landmarks pass the presence and confidence checks;
        - it is not a person listed already (overlapping landmark boxes, or the same
          keypoints: a person found twice, e.g. whole and as an upper body, is listed once);
        - :meth:`detect` in its ``person_box`` (as it is, and rounded to whole pixels) takes the
          same person (landmark boxes overlapping by :data:`SAME_PERSON_IOU`): whoever is
          listed can be predicted in their box.

        Then the people BlazePose's detector missed (:meth:`_whole_people`): the
        ``person_finder`` (NanoDet) boxes every person; each box no listed person owns
        (:func:`~hkpd.prediction.detection.person_merge.unowned_boxes`) is read with
        :meth:`detect` in that box, and listed when it takes someone who owns a box, is not
        listed yet and is confirmed as above. Last, a listed person owning no box who lies
        inside a box another listed person owns is that person read twice and is dropped
        (:func:`~hkpd.prediction.detection.person_merge.kept_people`).

        The list is empty when nobody is found (no exception). ``seconds`` of each is the time
        of the grid search (of the read in its box for a person found by ``person_finder``).
        Each listed person's ``landmark_spread`` is measured (one more landmark run each).

        Raises:
            ImageInputError: ``image`` could not be loaded.
        """
        loaded = load_image(image)
        listed: list[KeypointDetection] = []
        read: list[PoseLandmarks] = []
        for detection, found in self._grid_candidates(loaded, tiles):
            if any(same_person(detection, other) for other in listed):
                continue
            if self._confirmed(loaded, detection):
                listed.append(detection)
                read.append(found)
        with self._lock:
            runner = self._pose_runner()
            spreads = [landmark_spread(runner, loaded.pixels, f, COCO_FROM_BLAZEPOSE) for f in read]
        listed = [replace(d, landmark_spread=m) for d, m in zip(listed, spreads, strict=True)]
        return self._whole_people(loaded, listed)

    def _whole_people(
        self, loaded: LoadedImage, listed: list[KeypointDetection]
    ) -> list[KeypointDetection]:
        """``listed`` with the people of the ``person_finder``'s boxes it lacks added, and
        anyone read twice dropped (see :meth:`detect_all`)."""
        if self.person_finder is None:
            return listed
        boxes = [
            _box_to_original(found.box, loaded) for found in self.person_finder.find(loaded.pixels)
        ]
        read_in: list[int | None] = [None] * len(listed)
        for index in unowned_boxes([d.person_box for d in listed], boxes):
            try:
                box = validated_box(boxes[index], loaded.original_size)
                detection = self._detect_in_box(loaded, box)
            except (NoPersonFoundError, ValueError):
                continue
            confident = detection.confidences >= CONFIDENT_VISIBILITY
            fits = read_fits_box(detection.keypoints, confident, box)
            if not fits or box_iou(detection.person_box, box) < BOX_READ_IOU:
                continue
            if not any(same_person(detection, other) for other in listed):
                listed.append(detection)
                read_in.append(index)
        kept = kept_people([d.person_box for d in listed], boxes, read_in)
        return [listed[i] for i in kept]

    def _grid_candidates(
        self, loaded: LoadedImage, tiles: int
    ) -> list[tuple[KeypointDetection, PoseLandmarks]]:
        """Every candidate of the whole photo and the grid whose landmarks pass the checks,
        whole photo first, then by score (duplicates included), with the landmarks it was made
        from."""
        width, height = loaded.size
        with self._lock:
            runner = self._pose_runner()
            start = time.perf_counter()
            candidates = []
            for order, (x0, y0, x1, y1) in enumerate(tile_bounds(width, height, tiles)):
                part = np.ascontiguousarray(loaded.pixels[y0:y1, x0:x1])
                found = runner.find_people(part)
                candidates += [(order > 0, -p.score, _shifted(p, x0, y0)) for p in found]
            candidates.sort(key=lambda candidate: candidate[:2])
            people = [candidate[2] for candidate in candidates]
            found = [runner.landmarks(loaded.pixels, p.region, self.segmentation) for p in people]
            seconds = time.perf_counter() - start
        detections = [
            (_to_detection(landmarks, loaded, (0, 0), None, seconds, person.score), landmarks)
            for landmarks, person in zip(found, people, strict=True)
        ]
        return [(detection, read) for detection, read in detections if detection is not None]

    def _confirmed(self, loaded: LoadedImage, detection: KeypointDetection) -> bool:
        """Whether :meth:`detect` in ``detection.person_box`` takes that person, the box given
        exactly or in whole pixels (as the explorer passes it on)."""
        box = detection.person_box
        width, height = loaded.original_size
        whole = np.round(np.clip(box, 0, [width, height, width, height]))
        searches = (box,) if np.array_equal(whole, box) else (box, whole)
        return all(self._takes(loaded, search, box) for search in searches)

    def _takes(self, loaded: LoadedImage, search_box: np.ndarray, person_box: np.ndarray) -> bool:
        """Whether :meth:`detect` inside ``search_box`` takes the person of ``person_box``."""
        try:
            box = validated_box(search_box, loaded.original_size)
            again = self._detect_in_box(loaded, box, spread=False)
        except (NoPersonFoundError, ValueError):
            return False
        return box_iou(again.person_box, person_box) >= SAME_PERSON_IOU

    def landmarks33(
        self,
        image: LoadedImage | np.ndarray | str,
        bbox: Sequence[float] | np.ndarray | None = None,
    ) -> np.ndarray | None:
        """All 33 BlazePose landmarks of the person :meth:`detect` would take (for comparisons).

        Returns:
            ``(33, 3)`` float64 ``(u, v, visibility)`` in original-photo pixels, or None when no
            pose is present (the confidence check of :meth:`detect` is not applied).
        """
        loaded = load_image(image)
        x0, y0, x1, y1 = 0, 0, *loaded.size
        if bbox is not None:
            x0, y0, x1, y1 = search_region(loaded, validated_box(bbox, loaded.original_size))
        pixels = np.ascontiguousarray(loaded.pixels[y0:y1, x0:x1])
        with self._lock:
            runner = self._pose_runner()
            people = runner.find_people(pixels)
            if not people:
                return None
            found = runner.landmarks(pixels, people[0].region)
        if found.presence < POSE_PRESENCE_THRESHOLD:
            return None
        points = loaded.to_original(found.points + np.array([x0, y0], np.float64))
        return np.concatenate([points, found.visibility[:, None]], axis=1)


def same_person(first: KeypointDetection, second: KeypointDetection) -> bool:
    """Whether two detections are one person found twice: landmark boxes overlapping by
    :data:`SAME_PERSON_IOU` or more, or at least :data:`SAME_KEYPOINTS_MIN` keypoints confident
    in both lying, in the median, within :data:`SAME_KEYPOINTS_DISTANCE` of the smaller box's
    longer side of each other."""
    if box_iou(first.person_box, second.person_box) >= SAME_PERSON_IOU:
        return True
    shared = (first.confidences >= CONFIDENT_VISIBILITY) & (
        second.confidences >= CONFIDENT_VISIBILITY
    )
    if int(shared.sum()) < SAME_KEYPOINTS_MIN:
        return False
    distance = np.linalg.norm(first.keypoints[shared] - second.keypoints[shared], axis=-1)
    sides = [float((box[2:] - box[:2]).max()) for box in (first.person_box, second.person_box)]
    return float(np.median(distance)) <= SAME_KEYPOINTS_DISTANCE * min(sides)


def _person_of_box(
    runner: PoseRunner, pixels: np.ndarray, people: list[PersonCandidate], box: np.ndarray
) -> PersonCandidate:
    """Of the candidates BlazePose's detector found in ``pixels`` (best first), the one among
    the first :data:`IN_BOX_CANDIDATES` whose landmarks' box overlaps ``box`` (``pixels``'s
    coordinates) most; the first on a tie or when no pose is present."""
    best, best_iou = people[0], -1.0
    for person in people[:IN_BOX_CANDIDATES]:
        found = runner.landmarks(pixels, person.region)
        if found.presence < POSE_PRESENCE_THRESHOLD:
            continue
        landmark_box = np.concatenate([found.points.min(axis=0), found.points.max(axis=0)])
        iou = box_iou(landmark_box, box)
        if iou > best_iou:
            best, best_iou = person, iou
    return best


def _box_region(width: int, height: int, side: float = REGION_SCALE) -> Region:
    """The upright landmark region for a search region of ``width × height`` pixels (the box
    widened by :data:`SEARCH_BOX_PADDING`): centred on it, ``side`` × the box's longer side."""
    centre = np.array([width / 2 - 0.5, height / 2 - 0.5])
    return Region(centre, side * max(width, height) / (1 + 2 * SEARCH_BOX_PADDING), 0.0)


def _box_to_original(box: np.ndarray, loaded: LoadedImage) -> np.ndarray:
    """``(x0, y0, x1, y1)`` working-image pixels -> whole original-photo pixels, clipped to
    the photo (whole pixels, as the explorer passes boxes on)."""
    corners = loaded.to_original(np.asarray(box, np.float64).reshape(2, 2))
    return np.round(clipped_box(corners, loaded.original_size))


def _shifted(person: PersonCandidate, dx: int, dy: int) -> PersonCandidate:
    """``person`` found in a part of the photo whose corner is ``(dx, dy)``, in photo pixels."""
    shift = np.array([dx, dy], np.float64)
    region = Region(person.region.centre + shift, person.region.size, person.region.angle)
    return PersonCandidate(
        person.score, person.box + np.tile(shift, 2), person.keypoints + shift, region
    )


def _to_detection(
    found: PoseLandmarks,
    loaded: LoadedImage,
    offset: tuple[int, int],
    search_box: np.ndarray | None,
    seconds: float,
    score: float | None,
) -> KeypointDetection | None:
    """Landmarks of a working-image region -> a detection in original pixels; None when the
    pose is absent or too few COCO keypoints are confident."""
    if found.presence < POSE_PRESENCE_THRESHOLD:
        return None
    shift = np.array(offset, np.float64)
    original = loaded.to_original(found.points + shift)
    confidences = np.clip(found.visibility[list(COCO_FROM_BLAZEPOSE)], 0.0, 1.0)
    if int((confidences >= CONFIDENT_VISIBILITY).sum()) < MIN_CONFIDENT_KEYPOINTS:
        return None
    person_mask, mask_box = None, None
    if found.mask is not None:
        person_mask = found.mask.moved(_to_original_matrix(loaded, shift), loaded.original_size)
        corners = person_mask.box()
        if corners is not None:
            mask_box = clipped_box(corners.reshape(2, 2), loaded.original_size)
    return KeypointDetection(
        keypoints=original[list(COCO_FROM_BLAZEPOSE)],
        confidences=confidences,
        person_box=clipped_box(original, loaded.original_size),
        mask_box=mask_box,
        search_box=search_box,
        image_size=loaded.original_size,
        seconds=seconds,
        detector_score=score,
        presence=found.presence,
        person_mask=person_mask,
        extremities=original[list(BLAZEPOSE_EXTREMITY_INDICES)],
        extremity_confidences=np.clip(
            found.visibility[list(BLAZEPOSE_EXTREMITY_INDICES)], 0.0, 1.0
        ),
        face_landmarks=np.concatenate(
            [
                original[:FACE_LANDMARK_COUNT],
                np.clip(found.visibility[:FACE_LANDMARK_COUNT, None], 0.0, 1.0),
            ],
            axis=1,
        ),
    )


def _to_original_matrix(loaded: LoadedImage, shift: np.ndarray) -> np.ndarray:
    """``(2, 3)`` affine: pixels of a working-image part whose corner is ``shift`` -> original
    photo pixels (:meth:`LoadedImage.to_original` after the shift)."""
    sx, sy = loaded.scale
    return np.array(
        [
            [1 / sx, 0.0, (shift[0] + 0.5) / sx - 0.5],
            [0.0, 1 / sy, (shift[1] + 0.5) / sy - 0.5],
        ]
    )
