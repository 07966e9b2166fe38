"""From a photo to a body posterior: image loading, 2D keypoint detection, cropping, the
`Predictor` and the `hkpd-predict` command.

- :class:`Predictor` -> :class:`BodyPosterior`: the whole path, photo to a distribution over
  bodies that samples meshes (:class:`BodyMeshes`) and maps them back to the photo.
- ``hkpd-predict`` (:mod:`hkpd.prediction.cli`): the command line, with mesh/npz/JSON exports and
  an overview picture.

The pieces:

- :func:`load_image` -> :class:`LoadedImage`: any path/array/PIL image as ``(H, W, 3)`` uint8
  RGB (EXIF orientation, grayscale, alpha on white, 16-bit, downscale of huge photos), with the
  map back to original-photo pixels; bad input raises :class:`ImageInputError`.
- :class:`KeypointDetector` -> :class:`KeypointDetection`: COCO-17 keypoints of one person from
  BlazePose (optionally inside a ``bbox``); :class:`NoPersonFoundError` when there is none.
- :class:`CropTransform`: the square 256-pixel crop around a person and the exact pixel maps
  between crop and photo.
- :class:`Occluders`, :func:`apply_occluders`: black boxes painted over a photo before edge
  extraction (:func:`points_under_boxes`: which keypoints they hide).
- :func:`prepare_network_input` -> :class:`NetworkInput`: all of the above plus the
  ``(18, 256, 256)`` proxy, i.e. everything in front of the network.
- :class:`ReadingConfig`: how the network reads a crop (mirrored too, upright copies of leaning
  people, lean search; :mod:`hkpd.prediction.readings`, the stage ``Predictor`` and
  ``hkpd-eval`` share).
- :class:`ReadingQuality` (``posterior.quality``): how far to trust a reading, a calibrated
  score in [0, 1] and named flags (:mod:`hkpd.prediction.quality`).
- :func:`combine_shapes` -> :class:`CombinedShape`: one shape from several photos of the same
  person (product of the photos' shape Gaussians, or the plain mean as a baseline).
"""

from hkpd.prediction.crop import BOX_CONFIDENCE_THRESHOLD, CropTransform
from hkpd.prediction.detection.keypoint_detector import (
    COCO_FROM_BLAZEPOSE,
    KeypointDetection,
    KeypointDetector,
    NoPersonFoundError,
)
from hkpd.prediction.image_input import (
    MAX_IMAGE_PIXELS,
    MAX_IMAGE_SIDE,
    MIN_IMAGE_SIDE,
    ImageInputError,
    LoadedImage,
    load_image,
)
from hkpd.prediction.network_input import NetworkInput, prepare_network_input
from hkpd.prediction.occluders import Occluders, apply_occluders, points_under_boxes
from hkpd.prediction.posterior import BodyMeshes, BodyPosterior
from hkpd.prediction.predictor import Predictor
from hkpd.prediction.quality import ReadingQuality
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.shape_combination import CombinedShape, combine_shapes

__all__ = [
    "BOX_CONFIDENCE_THRESHOLD",
    "COCO_FROM_BLAZEPOSE",
    "MAX_IMAGE_PIXELS",
    "MAX_IMAGE_SIDE",
    "MIN_IMAGE_SIDE",
    "BodyMeshes",
    "BodyPosterior",
    "CombinedShape",
    "CropTransform",
    "ImageInputError",
    "KeypointDetection",
    "KeypointDetector",
    "LoadedImage",
    "NetworkInput",
    "NoPersonFoundError",
    "Occluders",
    "Predictor",
    "ReadingConfig",
    "ReadingQuality",
    "apply_occluders",
    "combine_shapes",
    "load_image",
    "points_under_boxes",
    "prepare_network_input",
]
