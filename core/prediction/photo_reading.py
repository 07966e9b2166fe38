"""How a photo is read: decided once on the photo without occluders, kept while occluders change.

An occluder says "this part of the photo gives no evidence". It removes evidence; it must not
change how the photo is read. Before issue 58 every prediction decided everything again on the
boxed photo, and a box over one shin of the shipped photo flipped the choice to read the mirror
image, which moved the left elbow's arrows, the right wrist's uncertainty (27 %) and the sex
(59 % -> 53 %). A :class:`PhotoReading` holds what belongs to the photo, decided on it without
occluders:

- the detection (BlazePose on the unpainted photo, in the person box; the detector always ran
  on the unpainted photo, so this is also what a boxed prediction detected);
- the readings' choices: which upright copy (if any) the network reads, and for each reading
  whether its mirror image was read (:class:`hkpd.prediction.readings.Readings`);
- per setting of the fit (stated body, person mask, landmarks, evidence settings), the sexes as
  the evidence fit of the photo without occluders weighed them
  (:class:`hkpd.prediction.sex_latent.SexShapes`);
- photo-level evidence that no occluder edit changes: the face's word on the sex
  (:attr:`PhotoReading.face`, issue 57), read once per photo.

With occluders, :meth:`hkpd.prediction.Predictor.predict` re-uses all of it and re-runs only what
depends on the boxes: the proxy with the boxes painted, the network's reading of it (each
reading once, mirrored as the photo chose), the fit and the samples. Without occluders it
returns what it always returned (the same computation). The predictor keeps the last few
photo readings (:class:`PhotoReadingCache`, keyed by the photo's pixels and the reading
settings), so callers such as the explorer need not hold them; a caller may also pass one back
explicitly (``predict(..., reading=predictor.read_photo(photo))``).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Hashable
from dataclasses import dataclass, field

import numpy as np

from hkpd.prediction.detection.keypoint_detector import KeypointDetection
from hkpd.prediction.image_input import LoadedImage
from hkpd.prediction.network_input import NetworkInput
from hkpd.prediction.readings import Readings
from hkpd.prediction.sex_fits import FaceWord
from hkpd.prediction.sex_latent import SexShapes

PHOTO_READINGS_KEPT = 4
"""Photo readings a predictor keeps (the explorer's photo, its person boxes, a compare column)."""


@dataclass(eq=False)
class PhotoReading:
    """How one person in one photo is read (the module docstring).

    Attributes:
        clear: the network input of the photo without occluders (it holds the loaded photo,
            :attr:`detection`, the crop and the unboxed proxy).
        readings: the network's readings of :attr:`clear`: the upright copy chosen
            (``views``) and, per reading, whether the mirror image was read (``mirrored``).
        key: what the reading was made from (photo pixels, person box, upright, reading
            settings), as :class:`PhotoReadingCache` keys it; None when not cached.
        face: what the face said of the sex (:class:`hkpd.prediction.sex_fits.FaceWord`), read
            once per photo; None: not read. Photo-level evidence on the sex goes here, beside
            the fit's, so that occluder edits never read it again.
        sexes: per fit setting (:meth:`hkpd.prediction.Predictor.fit_setting`), the sexes as
            weighed on the photo without occluders (filled by the predictor on first use).
    """

    clear: NetworkInput
    readings: Readings
    key: Hashable | None = None
    face: FaceWord | None = None
    sexes: dict[Hashable, SexShapes] = field(default_factory=dict)

    @property
    def detection(self) -> KeypointDetection:
        """BlazePose's detection on the unpainted photo (original-photo pixels)."""
        return self.clear.detection

    @property
    def image(self) -> LoadedImage:
        """The photo as loaded, nothing painted."""
        return self.clear.image

    @property
    def mirrored(self) -> np.ndarray:
        """``(R,)`` bool: which of the photo's readings are of the mirror image."""
        return self.readings.mirrored

    def __repr__(self) -> str:
        views = ["as it is" if view is None else "upright copy" for view in self.readings.views]
        return (
            f"PhotoReading({self.clear!r}, read {', '.join(views)}, mirrored "
            f"{self.mirrored.tolist()}, {len(self.sexes)} sex reading(s), face "
            f"{'read' if self.face is not None else 'not read'})"
        )


def photo_key(image: LoadedImage, *settings: Hashable) -> Hashable:
    """A key naming ``image``'s pixels (a BLAKE2 digest of the working-resolution pixels and
    the original size) and ``settings`` (person box, upright, ...)."""
    digest = hashlib.blake2b(np.ascontiguousarray(image.pixels).data, digest_size=16)
    digest.update(repr((image.pixels.shape, image.original_size)).encode())
    return (digest.hexdigest(), *settings)


class PhotoReadingCache:
    """The last :data:`PHOTO_READINGS_KEPT` photo readings, by :func:`photo_key` (least recently
    used dropped first). Not thread-safe on its own: the predictor uses it under its lock."""

    def __init__(self, size: int = PHOTO_READINGS_KEPT) -> None:
        self.size = size
        self._readings: OrderedDict[Hashable, PhotoReading] = OrderedDict()

    def get(self, key: Hashable) -> PhotoReading | None:
        """The reading kept under ``key`` (now the most recently used), or None."""
        reading = self._readings.get(key)
        if reading is not None:
            self._readings.move_to_end(key)
        return reading

    def put(self, reading: PhotoReading) -> None:
        """Keep ``reading`` under its :attr:`~PhotoReading.key`."""
        self._readings[reading.key] = reading
        self._readings.move_to_end(reading.key)
        while len(self._readings) > self.size:
            self._readings.popitem(last=False)

    def clear(self) -> None:
        """Forget every reading."""
        self._readings.clear()
