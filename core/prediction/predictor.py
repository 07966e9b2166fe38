"""``Predictor``: a photo in, a :class:`BodyPosterior` out.

``predict`` runs the front end (:func:`prepare_network_input`: load, detect 2D keypoints with
BlazePose, paint occluders, crop, build the proxy) and the distribution-prediction network.
By default it then conditions the network's distribution on the detected keypoints
(:func:`hkpd.conditioning.condition_on_keypoints`; ``docs/evidence.md``): the network's
distribution is the prior, the confident keypoints that no occluder covers are the evidence.
The network reads the crop through the reading stage (:mod:`hkpd.prediction.readings`): as it
is and mirrored, and, when the torso leans more than ``ReadingConfig.upright_start_degrees``,
also from a copy of the crop turned upright (:mod:`hkpd.prediction.readings.upright_view`); the fit
starts from both answers. When the evidence shows no torso, the lean is searched for
(:mod:`hkpd.prediction.readings.lean`). ``evidence=False`` returns the network's own
distribution (the paper's method); for a leaning person that is its answer on the upright copy,
mapped back to the photo (on held-out photos this reading alone cut the network's error by a
third), unless ``upright=False``.
"""

from __future__ import annotations

import copy
import functools
import math
import os
import threading
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from hkpd.assets import shipped_file
from hkpd.body import BodyModel
from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_NAMES, extremity_landmarks
from hkpd.conditioning import (
    EvidenceConfig,
    EvidenceTerm,
    KeypointEvidence,
    KeypointFit,
    SilhouetteEvidence,
    SilhouetteTerm,
    StatedBody,
    SurfaceSamples,
    condition_on_keypoints,
)
from hkpd.conditioning.landmark_term import LandmarkEvidence, LandmarkTerm
from hkpd.devices import resolve_device
from hkpd.distributions import BodyDistribution
from hkpd.network.checkpoint import load_network, stored_evidence_config
from hkpd.prediction.detection.face_sex import FaceSexReader
from hkpd.prediction.detection.keypoint_detector import (
    KeypointDetector,
    people_by_size,
    reading_box,
)
from hkpd.prediction.detection.movenet import SecondReader
from hkpd.prediction.face_evidence import face_word
from hkpd.prediction.image_input import LoadedImage, load_image
from hkpd.prediction.network_input import (
    NetworkInput,
    prepare_network_input,
    proxy_person_mask,
)
from hkpd.prediction.occluders import OccluderBoxes, Occluders
from hkpd.prediction.photo_reading import PhotoReading, PhotoReadingCache, photo_key
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.readings import ReadingConfig, ReadingInput, Readings, ReadingStage
from hkpd.prediction.readings.upright_view import UprightView
from hkpd.prediction.second_evidence import combined_keypoint_evidence, landmark_evidence
from hkpd.prediction.sex_fits import fit_each_sex, with_drawn_body, with_sex_shape
from hkpd.prediction.sex_latent import FaceWord, SexShapes
from hkpd.prediction.turning import turn_around
from hkpd.proxy import build_proxy
from hkpd.stated_body import StatedValue

SHIPPED_MODEL = ("models", "hkpd_hierarchical.pt")
"""The pretrained weights inside the ``hkpd.assets`` package."""


def shipped_model_path() -> Path:
    """Path of the shipped pretrained weights.

    Raises:
        FileNotFoundError: they are not installed, with what to do instead.
    """
    remedy = "pass a checkpoint from `hkpd-train` (e.g. runs/hkpd/last.pt) instead"
    return shipped_file(SHIPPED_MODEL, "the pretrained model", remedy)


class Predictor:
    """Predicts body posteriors from photos with a trained network.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` (eval mode).
        device: where the network and body model run.
        body: the body model (default: the shipped one).
        detector: the 2D keypoint detector (default: BlazePose, created on first use).
        evidence_config: how the keypoint evidence updates the network's distribution.
        reading_config: how the network reads each crop (:mod:`hkpd.prediction.readings`):
            as it is and mirrored, keeping the reading whose most likely body fits the shown
            keypoints more closely (``mirror``; False reads each once), and from which lean an
            upright copy is read too (``upright_start_degrees``).
        silhouette_evidence: also condition on the detector's person mask
            (:class:`hkpd.conditioning.SilhouetteTerm`, ``docs/shape.md``): the body's outline
            should match the mask's where the photo shows it. Off by default until it is
            measured on photos; a detector without segmentation, or a photo without a mask,
            falls back to the keypoints alone (``posterior.evidence_fit.terms`` says which
            evidence the fit used).
        landmark_evidence: also condition on BlazePose's hand and foot landmarks (knuckles,
            thumbs, heels, toes: :class:`hkpd.conditioning.landmark_term.LandmarkTerm`), the
            ones confident and under no occluder; they say how the hands and feet are turned
            (``docs/evidence.md``, "Hand and foot landmarks"). The attribute of the same name
            switches it later.

    Attributes:
        network: the distribution network (eval mode, on ``device``).
        reading: the reading stage (its ``network`` is what reads a batch of proxies: the
            network, wrapped for the mirror reading unless ``reading_config.mirror`` is off).

    Thread safety: ``predict`` may be called from several threads; calls are serialised.
    """

    def __init__(
        self,
        network: torch.nn.Module,
        device: torch.device | str = "cpu",
        body: BodyModel | None = None,
        detector: KeypointDetector | None = None,
        evidence_config: EvidenceConfig | None = None,
        reading_config: ReadingConfig | None = None,
        silhouette_evidence: bool = False,
        landmark_evidence: bool = True,
    ) -> None:
        self.device = torch.device(device)
        network = network.to(self.device).eval()
        self.body = (body or BodyModel()).to(self.device)
        self.network = network
        self.reading = ReadingStage(network, self.body, reading_config)
        self.detector = detector or KeypointDetector()
        self.crop_size = int(network.config.image_size)
        self.image_proxy = str(network.config.image_proxy)
        self.evidence_config = evidence_config or EvidenceConfig()
        self.silhouette_evidence = silhouette_evidence
        self.landmark_evidence = landmark_evidence
        self._lock = threading.Lock()
        self._body64: BodyModel | None = None
        self._surface: SurfaceSamples | None = None
        self._photo_readings = PhotoReadingCache()
        self.second_reader = SecondReader()
        self.face_reader = FaceSexReader()

    @classmethod
    def from_pretrained(
        cls,
        path: str | os.PathLike[str] | None = None,
        device: str = "auto",
        reading_config: ReadingConfig | None = None,
        evidence_config: EvidenceConfig | None = None,
        silhouette_evidence: bool = False,
    ) -> Predictor:
        """Load a checkpoint (default: the shipped pretrained model).

        Args:
            path: a checkpoint written by ``hkpd-train`` or the shipped weights.
            device: ``auto`` (CUDA when available), ``cpu`` or ``cuda``.
            reading_config: as for the constructor.
            evidence_config: None takes the evidence settings stored with the weights
                (``hkpd-tune-evidence --write-to``; the defaults when none are stored).
            silhouette_evidence: as for the constructor.
        """
        resolved = resolve_device(device)
        source = Path(path) if path else shipped_model_path()
        network, payload = load_network(source, resolved)
        if evidence_config is None:
            evidence_config = EvidenceConfig.from_dict(stored_evidence_config(payload), str(source))
        return cls(
            network,
            resolved,
            evidence_config=evidence_config,
            reading_config=reading_config,
            silhouette_evidence=silhouette_evidence,
        )

    @torch.no_grad()
    def predict(
        self,
        image: str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage,
        occluders: Occluders | OccluderBoxes | None = None,
        bbox: Sequence[float] | np.ndarray | None = None,
        evidence: bool = True,
        upright: bool = True,
        silhouette: np.ndarray | None = None,
        sex: str | None = None,
        measurements: Mapping[str, StatedValue] | None = None,
        reading: PhotoReading | None = None,
        second_reader: bool = True,
        read_face: bool = True,
    ) -> BodyPosterior:
        """The body posterior of the person in ``image``, read as :meth:`read_photo` reads the
        photo without occluders (a box removes evidence; it does not change how the photo is
        read: :mod:`hkpd.prediction.photo_reading`).

        Args:
            image: a file path, an ``(H, W, 3)`` uint8 RGB array, a PIL image, or a
                :class:`LoadedImage`.
            occluders: ``(x0, y0, x1, y1)`` boxes in original-photo pixels: "this part of the
                photo gives no evidence". They are painted black for the edge channel, and the
                keypoints under them are dropped from the heatmaps and from the evidence.
            bbox: ``(x0, y0, x1, y1)``: look for the person only there (pick someone else
                when a photo shows several people).
            evidence: condition the network's distribution on the detected keypoints (the
                default); False returns the network's own distribution. When the fit cannot
                be made (too few keypoints, non-finite numbers), the network's distribution is
                returned and ``posterior.fallback_reason`` says why.
            upright: when the detected torso leans more than
                ``reading_config.upright_start_degrees``, let the network also read a copy of
                the crop turned upright (``posterior.upright_tilt_degrees`` says by how much):
                with ``evidence`` the fit starts from both answers, without it the upright
                copy's answer is the network's posterior. When the evidence shows no torso
                (nor a stand-in for it), the lean is that of the body the network reads
                (:mod:`hkpd.prediction.readings.lean`). False reads the crop as it is.
            silhouette: ``(H, W)`` bool mask of the person, original-photo pixels: only for
                networks that read a silhouette instead of edges (the proxy ablation's
                ``network.config.image_proxy == "silhouette"``), which need one.
            sex: "female" or "male" when known; None (the default) lets the photo decide:
                the shape is fitted under each sex's population prior and
                ``posterior.sex_probabilities`` says how probable each is
                (:mod:`hkpd.prediction.sex_latent`).
            measurements: what is known of the body, ``{name: value}`` or
                ``{name: (value, std)}`` with names ``"height_m"``, ``"mass_kg"``,
                ``"chest_m"``, ``"waist_m"``, ``"hip_m"``, ``"shoulder_width_m"`` (metres,
                kilograms; default stds :data:`hkpd.stated_body.DEFAULT_STATED_STD`):
                evidence on the shape, weighed before the fit.
            reading: a :class:`PhotoReading` from :meth:`read_photo` to use (``image``,
                ``bbox``, ``upright``, ``silhouette`` then unread); None: the one kept or new.
            second_reader: also read the person with MoveNet Thunder; False: BlazePose alone.
            read_face: let the face tell the sex too (:mod:`hkpd.prediction.face_evidence`:
                HSE FaceRes on the face square cut from BlazePose's face landmarks, read once
                per photo and person, calibrated; ``posterior.sex_evidence`` keeps its word
                apart from the keypoints'); it says nothing for back views, small or unclear
                faces. A stated ``sex`` overrides it. False: the body's proportions alone.

        Raises:
            ImageInputError: the image is missing, unreadable or unusable.
            NoPersonFoundError: nobody was found.
            ValueError: a silhouette network without a silhouette of the photo's size; a sex or
                measurement that is unknown or implausible, or stated with ``evidence=False``
                or a body model without sex priors.
        """
        stated = self._stated(sex, measurements, evidence)
        with self._lock:
            photo = reading or self._photo_reading(
                image, bbox, upright, silhouette, second_reader, read_face
            )
            prepared, readings = self._boxed(photo, Occluders.of(occluders), silhouette)
            starts = _float_cpu(readings.distribution)
            if not evidence:  # the upright copy's reading when there is one
                chosen = readings.chosen_rows[0]
                return self._posterior(starts, chosen, prepared, readings)
            network_posterior = self._posterior(starts, 0, prepared, readings)
            fit, sexes = self._fit(starts, prepared, stated, photo)
            posterior = self._evidence_posterior(starts, prepared, readings, network_posterior,
                                                 fit, sexes, stated)  # fmt: skip
            return with_drawn_body(replace(posterior, face=photo.face))

    @torch.no_grad()
    def read_photo(
        self,
        image: str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage,
        bbox: Sequence[float] | np.ndarray | None = None,
        upright: bool = True,
        silhouette: np.ndarray | None = None,
        second_reader: bool = True,
        read_face: bool = True,
    ) -> PhotoReading:
        """How the person in ``image`` is read, decided on the photo without occluders
        (:mod:`hkpd.prediction.photo_reading`): the detection, the upright copy, the mirror
        choice; the sexes' weights are added by the first evidence prediction of each fit
        setting. Kept (the last :data:`~hkpd.prediction.photo_reading.PHOTO_READINGS_KEPT`)
        and given back for the same pixels and settings. Arguments and errors as
        :meth:`predict`'s."""
        with self._lock:
            return self._photo_reading(image, bbox, upright, silhouette, second_reader, read_face)

    def _photo_reading(
        self,
        image: str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage,
        bbox: Sequence[float] | np.ndarray | None,
        upright: bool,
        silhouette: np.ndarray | None,
        second_reader: bool = True,
        read_face: bool = True,
    ) -> PhotoReading:
        """:meth:`read_photo` without the lock: the kept reading, or a new one (kept unless a
        silhouette was given: its pixels are not part of the key)."""
        loaded = load_image(image)
        box = None if bbox is None else tuple(float(v) for v in np.asarray(bbox).ravel())
        settings = (box, upright, self.reading.config, self.image_proxy, id(self.detector),
                    second_reader, read_face)  # fmt: skip
        key = None if silhouette is not None else photo_key(loaded, *settings)
        kept = None if key is None else self._photo_readings.get(key)
        if kept is not None:
            return kept
        clear = prepare_network_input(
            loaded,
            self.detector,
            bbox=bbox,
            crop_size=self.crop_size,
            image_proxy=self.image_proxy,
            silhouette=silhouette,
        )
        if second_reader:
            clear = self._with_second_reading(clear)
        batch = self._reading_input(clear)
        readings = self.reading.read(batch, upright=upright, keep_as_it_is=True)
        face = self._read_face(clear) if read_face else None
        photo = PhotoReading(clear, readings, key, face=face)
        if key is not None:
            self._photo_readings.put(photo)
        return photo

    def _read_face(self, clear: NetworkInput) -> FaceWord | None:
        """What the face of ``clear``'s person says of the sex (:mod:`hkpd.prediction.
        face_evidence`); None without sex priors (nothing would read it)."""
        if not self.body.has_sex_priors:
            return None
        return face_word(self.face_reader.read(clear.image, clear.detection))

    def _with_second_reading(self, clear: NetworkInput) -> NetworkInput:
        """``clear`` whose detection carries the second reader's reading of the person
        (``detection.second_reading``; occluder edits keep the detection, so it is read once)."""
        second = self.second_reader.read(clear.image, clear.detection)
        return replace(clear, detection=replace(clear.detection, second_reading=second))

    def _boxed(
        self, photo: PhotoReading, occluders: Occluders, silhouette: np.ndarray | None
    ) -> tuple[NetworkInput, Readings]:
        """The network input and readings of ``photo`` with ``occluders``: without any, the
        photo's own; else the boxes painted on the same detection and crop, each reading read
        once, from the photo's upright copy and mirrored as the photo chose."""
        if not len(occluders):
            return photo.clear, photo.readings
        prepared = prepare_network_input(
            photo.image,
            self.detector,
            occluders=occluders,
            crop_size=self.crop_size,
            image_proxy=self.image_proxy,
            silhouette=silhouette,
            detection=photo.detection,
        )
        views, mirrored = list(photo.readings.views), photo.mirrored
        batch = self._reading_input(prepared)
        readings = self.reading.read_views(batch, views, keep_as_it_is=True, mirrored=mirrored)
        return prepared, readings

    def fit_setting(self, stated: StatedBody) -> Hashable:
        """What the sexes' weights depend on besides the photo: what was stated and the fit's
        settings (the key of :attr:`PhotoReading.sexes`)."""
        measurements = tuple(sorted(stated.measurements.items()))
        switches = (self.silhouette_evidence, self.landmark_evidence)
        return (stated.sex, measurements, switches, self.evidence_config)

    def _fit(
        self, starts: BodyDistribution, prepared: NetworkInput, stated: StatedBody,
        photo: PhotoReading,
    ) -> tuple[KeypointFit, SexShapes | None]:  # fmt: skip
        """The evidence fit of ``prepared`` from ``starts`` and, with sex priors, the sexes:
        on the photo without occluders weighed by the fits (and kept in ``photo``), with
        occluders the photo's weights (found first on the photo without them when unknown)."""
        if not self.body.has_sex_priors:
            return self._fit_sexes(starts, prepared, stated, photo, None)
        setting = self.fit_setting(stated)
        decided = None
        if len(prepared.occluders):
            decided = photo.sexes.get(setting)
            if decided is None:
                clear_starts = _float_cpu(photo.readings.distribution)
                decided = self._fit(clear_starts, photo.clear, stated, photo)[1]
        fit, sexes = self._fit_sexes(starts, prepared, stated, photo, decided)
        if decided is None and sexes is not None:
            photo.sexes[setting] = sexes
        return fit, sexes

    def _fit_sexes(
        self, starts: BodyDistribution, prepared: NetworkInput, stated: StatedBody,
        photo: PhotoReading, decided: SexShapes | None,
    ) -> tuple[KeypointFit, SexShapes | None]:  # fmt: skip
        """The fit (:mod:`hkpd.prediction.sex_fits` when the body model has sex priors, with
        the photo's face and ``decided`` sexes) and its sexes (None without sex priors)."""
        keypoints_crop, observed = combined_keypoint_evidence(prepared)
        keypoint_evidence = KeypointEvidence(
            torch.as_tensor(keypoints_crop, dtype=torch.float64),
            torch.as_tensor(observed),
            self.crop_size,
        )
        mask_terms = self._mask_terms(prepared)
        config = self.evidence_config
        config = config.for_mask_evidence() if mask_terms else config
        mask_terms = mask_terms + self._landmark_terms(prepared)
        body64 = self._float64_body()
        if not self.body.has_sex_priors:
            fit = condition_on_keypoints(body64, starts, keypoint_evidence, config, mask_terms)
            return fit, None
        fits = fit_each_sex(body64, starts, keypoint_evidence, config, mask_terms, stated,
                            face=photo.face, decided=decided)  # fmt: skip
        return fits.winner, fits.shapes

    def _evidence_posterior(
        self,
        starts: BodyDistribution,
        prepared: NetworkInput,
        readings: Readings,
        network_posterior: BodyPosterior,
        fit: KeypointFit,
        sexes: SexShapes | None,
        stated: StatedBody,
    ) -> BodyPosterior:
        """The network's readings conditioned on the photo's evidence (``fit``: keypoints, and
        the mask when asked for) and on what was stated, with the sexes when the body model has
        sex priors; the network's posterior when the fit failed."""
        if fit.conditioned is None:
            fallback = replace(network_posterior, evidence_fit=fit, stated=stated)
            return fallback if sexes is None else with_sex_shape(fallback, sexes)
        prior = self._posterior(starts, fit.start, prepared, readings)
        return replace(
            prior,
            distribution=fit.conditioned.map(self._on_device),
            source="evidence",
            prior=prior,
            evidence_fit=fit,
            sexes=sexes,
            stated=stated,
            turner=functools.partial(turn_around, self),
        )

    def _stated(
        self,
        sex: str | None,
        measurements: Mapping[str, StatedValue] | None,
        evidence: bool,
    ) -> StatedBody:
        """The checked sex and measurements (before any heavy work), or a ValueError."""
        stated = StatedBody.of(sex, measurements)
        if stated.empty:
            return stated
        if not evidence:
            raise ValueError(
                "a stated sex or measurement conditions the shape, which needs the evidence "
                "posterior; drop evidence=False (--no-evidence)"
            )
        if not self.body.has_sex_priors:
            raise ValueError(
                "this body model has no sex-specific shape priors, so a stated sex or "
                "measurement cannot be used; use the shipped body model"
            )
        return stated

    def _reading_input(self, prepared: NetworkInput) -> ReadingInput:
        """The reading stage's input for one photo: its proxy; the shown keypoints are the
        evidence; upright copies are framed as the crop was (on every detected keypoint), not
        on the evidence alone: the network learnt crops framed around the whole person, and
        covering a limb must not move the copy."""
        return ReadingInput(
            proxy=prepared.proxy[None].to(self.device),
            keypoints=prepared.keypoints_crop[None],
            shown=prepared.evidence[None],
            turned_proxy=PhotoTurnedProxy(prepared, self.image_proxy),
            framing=prepared.box_keypoints_crop[None],
        )

    def _posterior(
        self,
        starts: BodyDistribution,
        row: int,
        prepared: NetworkInput,
        readings: Readings,
    ) -> BodyPosterior:
        """The network's posterior of reading ``row`` of ``readings`` (0: the crop as it is;
        1: its upright copy, already in the crop's frame), as ``starts`` holds it."""
        view = readings.row_views[row]
        return BodyPosterior(
            upright_tilt_degrees=None if view is None else math.degrees(view.tilt),
            mirror_read=bool(readings.mirrored[row]),
            distribution=starts.rows(row).map(self._on_device),
            crop=prepared.crop,
            keypoints=torch.as_tensor(prepared.detection.keypoints, dtype=torch.float32),
            confidences=torch.as_tensor(prepared.confidences, dtype=torch.float32),
            body=self.body,
            network_input=prepared,
            evidence=torch.as_tensor(prepared.evidence),
        )

    def _mask_terms(self, prepared: NetworkInput) -> list[EvidenceTerm]:
        """The silhouette term of the photo's person mask, when asked for and the detector
        gave a mask; else none (the fit then uses the keypoints alone)."""
        if not self.silhouette_evidence or prepared.person_mask is None:
            return []
        if self._surface is None:
            self._surface = SurfaceSamples.of(self._float64_body())
        evidence = SilhouetteEvidence.from_arrays(prepared.person_mask, prepared.person_mask_known)
        return [SilhouetteTerm(evidence, self._surface)]

    def _landmark_terms(self, prepared: NetworkInput) -> list[EvidenceTerm]:
        """The hand and foot landmark term (:mod:`hkpd.conditioning.landmark_term`) when
        switched on and the photo shows at least one of them as evidence; else none."""
        shown = landmark_evidence(prepared)  # less those hanging from a disputed keypoint
        if not self.landmark_evidence or prepared.extremities_crop is None or shown is None:
            return []
        if not shown.any():
            return []
        evidence = LandmarkEvidence(
            torch.as_tensor(prepared.extremities_crop, dtype=torch.float64),
            torch.as_tensor(shown),
            self.crop_size,
        )
        regressor = extremity_landmarks(self._float64_body()).rows(BLAZEPOSE_EXTREMITY_NAMES)
        config = self.evidence_config
        return [LandmarkTerm(evidence, regressor, config.keypoint_sigma, config.robust_scale)]

    def _on_device(self, tensor: torch.Tensor) -> torch.Tensor:
        """``tensor`` as the posterior holds it: float32 on the predictor's device."""
        return tensor.float().to(self.device)

    def float64_body_model(self) -> BodyModel:
        """The float64 CPU copy of the body model the fits use (made once)."""
        return self._float64_body()

    def _float64_body(self) -> BodyModel:
        """A float64 CPU copy of the body model for the fit (made once)."""
        if self._body64 is None:
            self._body64 = float64_body(self.body)
        return self._body64

    def predict_many(
        self,
        photos: Sequence[str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage],
        **options: object,
    ) -> list[BodyPosterior]:
        """:meth:`predict` of every photo, in order, with the same ``options`` (occluders,
        evidence, sex, measurements, …). Raises as :meth:`predict` on the first photo that
        fails; to keep going past bad photos, call :meth:`predict` per photo."""
        return [self.predict(photo, **options) for photo in photos]  # type: ignore[arg-type]

    def predict_all(
        self,
        image: str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage,
        **options: object,
    ) -> list[BodyPosterior]:
        """One posterior per person the detector finds in ``image``, in the Person menu's
        order (:func:`people_by_size`: larger people first), each predicted in its own box
        (:func:`~hkpd.prediction.detection.keypoint_detector.reading_box`: the person box it
        was found in, or its landmark box) with the same ``options`` as :meth:`predict`
        (``bbox`` is set per person).

        Returns:
            An empty list when nobody is found.

        Raises:
            ImageInputError: the image is missing, unreadable or unusable.
            ValueError: ``options`` holds ``bbox`` (each person has their own).
        """
        if "bbox" in options:
            raise ValueError("predict_all predicts every person in their own box: drop bbox")
        loaded = load_image(image)
        people = people_by_size(self.detector.detect_all(loaded))
        return [
            self.predict(loaded, bbox=reading_box(person), **options)  # type: ignore[arg-type]
            for person in people
        ]

    def close(self) -> None:
        """Release the detector's resources."""
        self.detector.close()


def _float_cpu(distribution: BodyDistribution) -> BodyDistribution:
    """``distribution`` detached, float32, on the CPU (the fit's starts)."""
    return distribution.map(lambda tensor: tensor.detach().float().cpu())


def float64_body(body: BodyModel) -> BodyModel:
    """A float64 CPU copy of ``body``, for the keypoint fit (which works in float64)."""
    return copy.deepcopy(body).cpu().double()


def refuse_silhouette_model(predictor: Predictor, tool: str) -> None:
    """Close ``predictor`` and raise a ValueError when its network reads person silhouettes
    (a proxy-ablation model), which ``tool`` cannot give it: hkpd has no person segmentation."""
    if predictor.image_proxy == "silhouette":
        predictor.close()
        raise ValueError(
            f"this model reads person silhouettes (a proxy-ablation model) and {tool} has no "
            "person segmentation; use an edge model such as the shipped one"
        )


class PhotoTurnedProxy:
    """Upright copies of a photo's crop (:class:`hkpd.prediction.readings.TurnedProxy`): the
    crop (and its silhouette) turned, the image proxy found again on it, heatmaps drawn at the
    turned keypoints.

    Args:
        prepared: the photo's network input.
        image_proxy: the image part of the proxy (the network's ``config.image_proxy``).
    """

    def __init__(self, prepared: NetworkInput, image_proxy: str) -> None:
        self.prepared, self.image_proxy = prepared, image_proxy

    def __call__(self, example: int, view: UprightView) -> torch.Tensor:
        """The ``(C + 17, S, S)`` proxy of the crop (``example`` 0) turned by ``view``."""
        prepared, silhouette = self.prepared, None
        if prepared.crop_silhouette is not None:
            silhouette = view.warp(prepared.crop_silhouette.astype(np.uint8) * 255) >= 128
        elif self.image_proxy == "edges+mask":
            mask = proxy_person_mask(prepared.person_mask, prepared.person_mask_known)
            silhouette = None if mask is None else view.warp(mask)
        return build_proxy(
            view.warp(prepared.crop_rgb),
            view.points(prepared.keypoints_crop),
            prepared.confidences,
            self.image_proxy,
            silhouette,
        )
