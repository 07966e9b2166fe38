"""Everything in front of the network for one photo: load, occlude, detect, crop, proxy.

:func:`prepare_network_input` chains :func:`~hkpd.prediction.image_input.load_image`,
:func:`~hkpd.prediction.occluders.apply_occluders`, :class:`KeypointDetector`,
:class:`CropTransform` and :func:`hkpd.proxy.build_proxy`, and returns a :class:`NetworkInput`
holding the ``(18, 256, 256)`` proxy plus what is needed to map the network's answer back to
the photo (``crop.crop_to_image``). The predictor adds the network and the posterior.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from PIL import Image

from hkpd.camera_conventions import CROP_SIZE
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.detection.keypoint_detector import KeypointDetection, KeypointDetector
from hkpd.prediction.detection.person_mask import PersonMask
from hkpd.prediction.evidence_rule import NO_OCCLUDERS, evidence_frame, evidence_mask
from hkpd.prediction.image_input import MAX_IMAGE_SIDE, LoadedImage, load_image, short_source
from hkpd.prediction.occluders import OccluderBoxes, Occluders, apply_occluders
from hkpd.proxy import DEFAULT_IMAGE_PROXY, build_proxy


@dataclass(frozen=True, eq=False)
class NetworkInput:
    """The network's input for one person in one photo, and the maps back to the photo.

    Attributes:
        proxy: ``(18, S, S)`` float32, ``S = crop_size`` (256 by default): Canny edges of the
            crop, then 17 COCO joint heatmaps (joints below the proxy's confidence threshold
            left empty).
        crop: the square crop (original-photo pixels <-> crop pixels).
        crop_rgb: ``(S, S, 3)`` uint8 RGB crop the edges were taken from (occluders painted).
        keypoints_crop: ``(17, 2)`` detected keypoints in crop pixels.
        confidences: ``(17,)`` detector confidences, zeroed where the keypoint is not evidence
            (below the threshold or under an occluder).
        evidence: ``(17,)`` bool, the keypoints that are evidence
            (:func:`hkpd.prediction.evidence_rule.evidence_mask`): the ones the heatmaps show
            and the fit is conditioned on.
        detection: the detector's raw result on the unpainted photo (original-photo pixels,
            confidences untouched).
        image: the photo as loaded, occluders painted.
        occluders: the boxes painted over the photo (original-photo pixels).
        crop_silhouette: ``(S, S)`` bool person mask of the crop (occluders removed), for
            networks that read a silhouette; None otherwise.
        person_mask: ``(S, S)`` float32 in [0, 1]: BlazePose's segmentation mapped into the
            crop (:func:`crop_person_mask`), the probability that the pixel shows the person;
            None when the detector gave no mask (``KeypointDetector(segmentation=False)``).
        person_mask_known: ``(S, S)`` bool, False where the photo says neither body nor
            background (inside occluder boxes, outside the photo); None with ``person_mask``.
        extremities_crop: ``(10, 2)`` BlazePose's hand and foot landmarks in crop pixels
            (``detection.extremities`` mapped as the keypoints are); None when the detection
            has none.
        extremity_evidence: ``(10,)`` bool, the landmarks that are evidence by the keypoints'
            rule (confident, inside the frame, under no occluder); None with
            ``extremities_crop``. They feed the fit's landmark term, not the heatmaps.
    """

    proxy: torch.Tensor
    crop: CropTransform
    crop_rgb: np.ndarray
    keypoints_crop: np.ndarray
    confidences: np.ndarray
    evidence: np.ndarray
    detection: KeypointDetection
    image: LoadedImage
    occluders: Occluders
    crop_silhouette: np.ndarray | None = None
    person_mask: np.ndarray | None = None
    person_mask_known: np.ndarray | None = None
    extremities_crop: np.ndarray | None = None
    extremity_evidence: np.ndarray | None = None

    def __repr__(self) -> str:
        """One line of at most 200 characters: the proxy's shape, the crop, the evidence, the
        occluders, the person mask and the photo (never the arrays: the default was 10 kB)."""
        (u, v), side = self.crop.centre, self.crop.side
        evidence = int(np.count_nonzero(self.evidence))
        mask = "person mask" if self.person_mask is not None else "no person mask"
        width, height = self.image.original_size
        return (
            f"NetworkInput(proxy={tuple(self.proxy.shape)}, crop {side:.0f} px at ({u:.0f}, "
            f"{v:.0f}), evidence {evidence}/{len(self.evidence)} keypoints, "
            f"{len(self.occluders)} occluders, {mask}, photo {width}x{height} "
            f"{short_source(self.image.source, 40)!r})"
        )

    @property
    def box_keypoints_crop(self) -> np.ndarray:
        """``(17, 2)`` float64 crop pixels: the keypoints that placed the crop box, by the
        training crops' rule (:meth:`CropTransform.from_keypoints`): every keypoint the detector
        returned, evidence or not, moved onto the photo's border when outside it. A second view
        of the crop (the upright copy) framed on these is framed as the crop itself was, and
        painting an occluder does not move it."""
        width, height = self.detection.image_size
        points = np.asarray(self.detection.keypoints, dtype=np.float64)
        return self.crop.image_to_crop(np.clip(points, -0.5, [width - 0.5, height - 0.5]))


def prepare_network_input(
    image: str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage,
    detector: KeypointDetector,
    *,
    bbox: Sequence[float] | np.ndarray | None = None,
    occluders: Occluders | OccluderBoxes = NO_OCCLUDERS,
    max_side: int = MAX_IMAGE_SIDE,
    crop_size: int = CROP_SIZE,
    image_proxy: str = DEFAULT_IMAGE_PROXY,
    silhouette: np.ndarray | None = None,
    detection: KeypointDetection | None = None,
) -> NetworkInput:
    """Load a photo, paint occluders, detect the person, crop, and build the proxy.

    The detector runs on the *unpainted* photo; occluders are then painted before edge
    extraction, and the keypoints that are not evidence
    (:func:`hkpd.prediction.evidence_rule.evidence_mask`: below the confidence threshold,
    outside the photo or the searched box, or under an occluder) get confidence 0, so the
    heatmaps show exactly the evidence. (Detecting on the painted photo let BlazePose put
    confident keypoints just outside a box.) Without occluders nothing changes.

    Args:
        image: anything :func:`load_image` accepts.
        detector: the (shared, reusable) keypoint detector.
        bbox: optional ``(x0, y0, x1, y1)`` search region, original-photo pixels.
        occluders: black boxes, original-photo pixels (:class:`Occluders` or what
            :meth:`Occluders.of` takes).
        max_side: working-resolution cap passed to :func:`load_image`.
        crop_size: side of the crop and proxy in pixels (the network's input size).
        image_proxy: the proxy's image part (:data:`hkpd.proxy.IMAGE_PROXIES`, the network's).
        silhouette: ``(H, W)`` bool person mask, original resolution, for the ``"silhouette"``
            proxy (e.g. a COCO person mask; occluders are removed from it); ignored otherwise.
        detection: the detector's result on this unpainted photo (in ``bbox``) when known
            (:class:`hkpd.prediction.photo_reading.PhotoReading`): not detected again.

    Returns:
        The :class:`NetworkInput`.

    Raises:
        ImageInputError: unreadable or unusable image.
        NoPersonFoundError: nobody found (in ``bbox``).
        ValueError: malformed ``bbox`` or occluder boxes, keypoints too degenerate to crop, or
            a silhouette proxy without a (well-sized) silhouette.
    """
    occluders = Occluders.of(occluders)
    loaded = load_image(image, max_side=max_side)
    if image_proxy == "silhouette":
        silhouette = _checked_silhouette(silhouette, loaded)
    detection = detector.detect(loaded, bbox=bbox) if detection is None else detection
    if len(occluders):
        loaded = apply_occluders(loaded, occluders)
    frame = evidence_frame(detection.image_size, detection.search_box)
    evidence = evidence_mask(detection.keypoints, detection.confidences, occluders, frame=frame)
    confidences = np.where(evidence, detection.confidences, 0.0)
    crop = CropTransform.from_keypoints(
        detection.keypoints, detection.confidences, image_size=detection.image_size, size=crop_size
    )
    crop_rgb = crop.crop_image(loaded.pixels, loaded.scale)
    keypoints_crop = crop.image_to_crop(detection.keypoints)
    crop_silhouette = None
    if image_proxy == "silhouette":
        crop_silhouette = _crop_silhouette(silhouette, occluders, crop)
    person_mask, person_mask_known = _mask_evidence(detection, crop, occluders)
    proxy_mask = _proxy_mask(image_proxy, crop_silhouette, person_mask, person_mask_known)
    proxy = build_proxy(crop_rgb, keypoints_crop, confidences, image_proxy, proxy_mask)
    return NetworkInput(
        proxy=proxy,
        crop=crop,
        crop_rgb=crop_rgb,
        keypoints_crop=keypoints_crop,
        confidences=confidences,
        evidence=evidence,
        detection=detection,
        image=loaded,
        occluders=occluders,
        crop_silhouette=crop_silhouette,
        person_mask=person_mask,
        person_mask_known=person_mask_known,
        **_extremities(detection, crop, occluders, frame),
    )


def _extremities(
    detection: KeypointDetection, crop: CropTransform, occluders: Occluders, frame: np.ndarray
) -> dict[str, np.ndarray | None]:
    """:class:`NetworkInput`'s ``extremities_crop`` (the detection's hand and foot landmarks in
    ``crop``) and ``extremity_evidence`` (the keypoints' rule, :func:`evidence_mask`); None
    without them."""
    if detection.extremities is None or detection.extremity_confidences is None:
        return {"extremities_crop": None, "extremity_evidence": None}
    shown = evidence_mask(
        detection.extremities, detection.extremity_confidences, occluders, frame=frame
    )
    points = crop.image_to_crop(np.asarray(detection.extremities, np.float64))
    return {"extremities_crop": points, "extremity_evidence": shown}


def _mask_evidence(
    detection: KeypointDetection, crop: CropTransform, occluders: Occluders
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The detection's mask in ``crop`` and where it is evidence; ``(None, None)`` without one."""
    if detection.person_mask is None:
        return None, None
    known = mask_known(crop, detection.image_size, occluders)
    return crop_person_mask(detection.person_mask, crop), known


def _crop_silhouette(
    silhouette: np.ndarray, occluders: Occluders, crop: CropTransform
) -> np.ndarray:
    """``(S, S)`` bool: the photo's ``(H, W)`` silhouette minus the occluders, in the crop."""
    if len(occluders):
        silhouette = apply_occluders(silhouette, occluders)  # the photo's own pixels
    return crop.crop_image(silhouette.astype(np.uint8) * 255) >= 128


def _proxy_mask(
    image_proxy: str,
    crop_silhouette: np.ndarray | None,
    person_mask: np.ndarray | None,
    known: np.ndarray | None,
) -> np.ndarray | None:
    """What :func:`build_proxy` gets as its ``silhouette``: the given silhouette for the
    ``"silhouette"`` proxy, the detector's mask for ``"edges+mask"``, else None."""
    if image_proxy == "edges+mask":
        return proxy_person_mask(person_mask, known)
    return crop_silhouette


def proxy_person_mask(
    person_mask: np.ndarray | None, known: np.ndarray | None
) -> np.ndarray | None:
    """The ``"edges+mask"`` proxy's mask plane: ``(S, S)`` float32 person probability, zero
    where the photo says nothing (occluders, outside the photo); None without a mask (the
    plane is then all zero, as for the training examples without one)."""
    if person_mask is None or known is None:
        return None
    return np.where(known, person_mask, 0.0).astype(np.float32)


def crop_person_mask(mask: PersonMask, crop: CropTransform) -> np.ndarray:
    """``(S, S)`` float32 in [0, 1]: ``mask`` resampled once into ``crop``'s pixels (the
    landmark crop's affine map composed with the crop's; bilinear; 0 outside the landmark
    region)."""
    return mask.in_frame(crop.affine_matrix(), (crop.size, crop.size))


def mask_known(
    crop: CropTransform, image_size: tuple[int, int], occluders: Occluders
) -> np.ndarray:
    """``(S, S)`` bool: crop pixels whose centre lies on a photo pixel that no occluder paints
    (:meth:`Occluders.covers`): where the photo says "person" or "background". False outside
    the photo and inside the boxes (no evidence either way)."""
    # The crop is an axis-aligned square: a pixel's photo u depends on its column only.
    steps = np.arange(crop.size, dtype=np.float64)
    u, v = crop.crop_to_image(np.stack([steps, steps], axis=-1)).T
    width, height = image_size
    in_u = (np.floor(u + 0.5) >= 0) & (np.floor(u + 0.5) < width)
    in_v = (np.floor(v + 0.5) >= 0) & (np.floor(v + 0.5) < height)
    known = in_v[:, None] & in_u[None, :]
    if len(occluders):
        centres = np.empty((crop.size, crop.size, 2))
        centres[..., 0], centres[..., 1] = u[None, :], v[:, None]
        known &= ~occluders.covers(centres)
    return known


def _checked_silhouette(silhouette: np.ndarray | None, loaded: LoadedImage) -> np.ndarray:
    """``silhouette`` as an ``(H, W)`` bool array of the original photo's size, or a clear
    ValueError."""
    if silhouette is None:
        raise ValueError(
            "this network reads a person silhouette: pass silhouette=<(H, W) bool mask of the "
            "person> (e.g. a COCO person mask or a segmentation of the photo)"
        )
    mask = np.asarray(silhouette)
    width, height = loaded.original_size
    if mask.shape != (height, width):
        raise ValueError(
            f"the silhouette must be ({height}, {width}) like the photo, got {mask.shape}"
        )
    return mask.astype(bool)
