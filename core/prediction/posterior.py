"""``BodyPosterior``: the predicted distribution over one person's body, ready to sample.

It wraps the :class:`hkpd.distributions.BodyDistribution` predicted for one image (the
hierarchical matrix-Fisher parameters of the 23 relative joint rotations, the shape Gaussian,
the global rotation and the weak-perspective camera) with the crop that maps the network's
256-pixel view back to the photo, the evidence and where the distribution came from. Meshes
come back in the *camera-aligned body frame*: the pelvis at the origin, axes of the OpenCV
camera (x right, y down, z away from the viewer), metres.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from numbers import Real
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.body.extremity_landmarks import NUM_EXTREMITY, extremity_landmarks
from hkpd.body.measurements import body_measurer
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution, KinematicMatrixFisher
from hkpd.kinematic_tree import BODY_JOINT_NAMES, body_joint_index
from hkpd.prediction.posterior_summaries import part_uncertainty, posterior_log_prob
from hkpd.prediction.quality import ReadingQuality, reading_quality
from hkpd.prediction.sex_latent import FaceWord, gaussian_measurements
from hkpd.uncertainty import vertex_uncertainty

if TYPE_CHECKING:
    from hkpd.conditioning import KeypointFit, StatedBody
    from hkpd.prediction.network_input import NetworkInput
    from hkpd.prediction.sex_latent import SexShapes

PosteriorSource = Literal["network", "evidence"]
"""Where a posterior's distribution comes from: the network alone (the paper's method), or the
network's distribution conditioned on the photo's 2D keypoints (``docs/evidence.md``)."""

RealNumber = float | np.floating | np.integer | np.ndarray | torch.Tensor
"""A scale factor: any real number (python, numpy, a 0-d array, a one-element tensor)."""

MAX_SHAPE_STD = 1e6
"""Largest shape standard deviation :meth:`BodyPosterior.with_shape_std` may make (shape
coefficients are in units of the body-shape prior's standard deviation, 1): far past any
meaningful body, and far inside float32 for the sampled vertices and their spreads (std 1e6
gives a vertex uncertainty of 1.6e4 m; 1e30 gave inf)."""

MAX_CONCENTRATION = 1e12
"""Largest proper singular value of a joint's ``F`` that :meth:`BodyPosterior.with_concentration`
may make (a spread of about 1e-6 rad, a point mass for any use), far below where the float32
sampler overflows (about 3e38)."""

UNCERTAINTY_CHUNK = 500
"""Meshes built at a time by :meth:`BodyPosterior.vertex_uncertainty` (~80 MB of vertices)."""


class CropToImage(Protocol):
    """Anything that maps crop pixels back to original-image pixels (e.g. a ``CropTransform``).

    Attributes:
        size: side of the crop in pixels (the network's input size).
    """

    size: int

    def crop_to_image(self, points: torch.Tensor) -> torch.Tensor: ...


@dataclass
class BodyMeshes:
    """N bodies (the mode, or samples), in the camera-aligned body frame, metres.

    Attributes:
        vertices: ``(N, V, 3)``.
        joints: ``(N, 24, 3)``.
        keypoints3d: ``(N, 17, 3)`` COCO keypoints.
        keypoints2d: ``(N, 17, 2)`` COCO keypoints reprojected into ORIGINAL image pixels.
        betas: ``(N, 10)`` shape coefficients.
        body_pose: ``(N, 23, 3, 3)`` relative joint rotations.
        foot_keypoints2d: ``(N, 6, 2)`` COCO-WholeBody's foot points reprojected into ORIGINAL
            image pixels, its order: left big toe, left small toe, left heel, right big toe,
            right small toe, right heel (:mod:`hkpd.body.extremity_landmarks`).
        extremity_keypoints2d: ``(N, 10, 2)`` BlazePose's hand and foot landmarks (17-22,
            29-32: pinky, index, thumb, heel, foot index; left then right of each) reprojected
            into ORIGINAL image pixels
            (:data:`hkpd.body.extremity_landmarks.BLAZEPOSE_EXTREMITY_NAMES` order).
    """

    vertices: torch.Tensor
    joints: torch.Tensor
    keypoints3d: torch.Tensor
    keypoints2d: torch.Tensor
    betas: torch.Tensor
    body_pose: torch.Tensor
    foot_keypoints2d: torch.Tensor
    extremity_keypoints2d: torch.Tensor

    def __repr__(self) -> str:
        count, vertices = self.vertices.shape[0], self.vertices.shape[1]
        return f"BodyMeshes({count} bodies of {vertices} vertices, metres; keypoints2d in photo px)"


@dataclass(frozen=True)
class BodyPosterior:
    """The body distribution predicted for one person.

    Attributes:
        distribution: the unbatched distribution (batch shape ``()``): ``F`` ``(23, 3, 3)``
            (already including any concentration scaling), ``shape_mean`` and ``shape_std``
            ``(10,)``, ``global_orient`` ``(3, 3)``, ``camera`` ``(3,)`` weak-perspective
            ``[s, tx, ty]`` of the 256-pixel crop; each is also a read-only property of the
            posterior.
        crop: maps crop pixels to original-image pixels.
        keypoints: ``(17, 2)`` detected COCO keypoints, original-image pixels.
        confidences: ``(17,)`` their detector confidences.
        body: the body model used to turn parameters into meshes.
        network_input: what the network saw (proxy, crop, detection), when the posterior came
            from a photo through :class:`hkpd.prediction.Predictor`.
        source: ``"evidence"`` when the distribution is conditioned on the 2D keypoints,
            ``"network"`` for the network's own.
        prior: for an evidence posterior, the network's posterior it updated (same crop), so
            the two can be compared; None otherwise.
        evidence_fit: the keypoint fit's report (iterations, cost, robust weights, time), or
            why it fell back (``evidence_fit.reason``); None when no fit was asked for.
        evidence: ``(17,)`` bool, the keypoints that counted as evidence (confident and not
            under an occluder); None when unknown.
        upright_tilt_degrees: the network read a copy of the crop turned upright by this many
            degrees (the detected torso's lean, clockwise on screen, or, when the evidence shows
            no torso, the lean of the body the network read) and its answer was mapped back to
            the photo; None when it read the crop as it is.
        mirror_read: the network's reading (for an evidence posterior: the reading its fit
            started from) came from the left-right mirror image of the crop, mapped back,
            because its body fitted the shown keypoints better than the reading of the crop
            itself (:mod:`hkpd.prediction.readings.mirror`).
        sexes: the shape with sex as a latent (:mod:`hkpd.prediction.sex_latent`): each sex's
            shape posterior and probability; ``distribution`` is then the more probable sex's
            and samples come from the mixture. None for the network's own posterior and for
            body models without sex priors.
        stated: what the user stated about the person (sex, measurements), or None.
        face: what the face said (:class:`hkpd.prediction.sex_latent.FaceWord`: its calibrated
            P(male) or why it said nothing, its apparent age); None when it was not read.
        turned: this is the turned-around reading (:meth:`turned_around`).
        turner: makes the turned-around posterior (set by the predictor).
    """

    distribution: BodyDistribution
    crop: CropToImage
    keypoints: torch.Tensor
    confidences: torch.Tensor
    body: BodyModel
    network_input: NetworkInput | None = None
    source: PosteriorSource = "network"
    prior: BodyPosterior | None = None
    evidence_fit: KeypointFit | None = None
    evidence: torch.Tensor | None = None
    upright_tilt_degrees: float | None = None
    mirror_read: bool = False
    sexes: SexShapes | None = None
    stated: StatedBody | None = None
    face: FaceWord | None = None
    turned: bool = False
    turner: Callable[[BodyPosterior], BodyPosterior] | None = field(
        default=None, repr=False, compare=False
    )

    def turned_around(self) -> BodyPosterior:
        """The same keypoints fitted by a body facing the other way, left and right swapped
        (:mod:`hkpd.prediction.turning`): the reading for a person seen from behind whom the
        detector labelled as facing the camera, or the other way round. Turning twice gives
        this posterior back (the same object). :attr:`turned` says which one this is.

        Raises:
            ValueError: this posterior cannot be turned (not an evidence posterior from
                :meth:`hkpd.prediction.Predictor.predict`, or the turned fit failed).
        """
        if self.turner is None:
            raise ValueError(
                "this posterior cannot be turned around: only an evidence posterior from "
                "Predictor.predict (evidence=True, the fit succeeded) can"
            )
        return self.turner(self)

    def __repr__(self) -> str:
        sex = "" if self.sexes is None else f", {self.sex} p={self.sex_probability:.2f}"
        return f"BodyPosterior(source={self.source!r}{sex}, samples via .sample(n))"

    @property
    def sex_probabilities(self) -> dict[str, float] | None:
        """``{"female": p, "male": 1 - p}``: how probable each sex is given the photo and what
        was stated (1 for a stated sex); None without sexes (see :attr:`sexes`)."""
        return None if self.sexes is None else dict(self.sexes.probabilities)

    @property
    def sex(self) -> str | None:
        """The more probable sex (None without sexes); :attr:`drawn_sex` says whose body
        :meth:`mode` draws."""
        return None if self.sexes is None else self.sexes.most_probable

    @property
    def drawn_sex(self) -> str | None:
        """Whose body :meth:`mode` draws: :attr:`sex` when it is sure, ``"neutral"`` (neither
        sex's chest and hips) when it is not or the reading is in doubt
        (:attr:`hkpd.prediction.sex_latent.SexShapes.drawn`); None without sexes."""
        return None if self.sexes is None else self.sexes.drawn

    @property
    def sex_evidence(self) -> dict[str, float | None] | None:
        """``{"face": p_male or None, "keypoints": p_male}``: what each source says of the sex
        on its own (the face None when it said nothing or was not read); None without sexes,
        or when the sex was stated."""
        if self.sexes is None or self.sexes.evidence is None:
            return None
        return self.sexes.evidence.as_dict()

    @property
    def sex_probability(self) -> float | None:
        """The probability of :attr:`sex`."""
        return None if self.sexes is None else self.sexes.probabilities[self.sexes.most_probable]

    def log_prob(self, body_pose: torch.Tensor, betas: torch.Tensor) -> torch.Tensor:
        """``(N,)`` float64 log density of N bodies under this posterior, nats: the 23 joints'
        hierarchical matrix-Fisher density (w.r.t. the Haar probability measure on each joint's
        SO(3)) plus the shape's (w.r.t. Lebesgue measure on β): the mixture over the sexes
        when sex is a latent, else the shape Gaussian. The global rotation and the camera are
        point estimates and take no part (:mod:`hkpd.prediction.posterior_summaries`).

        Args:
            body_pose: ``(N, 23, 3, 3)`` relative joint rotations.
            betas: ``(N, K)`` shape coefficients.
        """
        total = posterior_log_prob(self.distribution, body_pose, betas)
        if self.sexes is None:
            return total
        diagonal = self.distribution.to(torch.float64).shape_distribution()
        exact_betas = betas.to(torch.float64)
        return total - diagonal.log_prob(exact_betas) + self.sexes.log_prob(exact_betas)

    def part_uncertainty(self, num_samples: int = 100, seed: int | None = 0) -> dict[str, float]:
        """``{part name: metres}``: the mean per-vertex uncertainty
        (:meth:`vertex_uncertainty` of ``num_samples`` samples) of each body part's vertices
        (the body model's ``part_names``; NaN for a part without vertices)."""
        uncertainty = self.vertex_uncertainty(num_samples, seed=seed)
        return part_uncertainty(uncertainty, self.body.part_labels, self.body.part_names)

    def measurements(self) -> dict[str, tuple[float, float]]:
        """``{name: (mean, std)}``: height, mass, chest, waist and hip girths and shoulder
        width (metres, kilograms; :mod:`hkpd.body.measurements` says where each is taken) under
        the shape posterior, over both sexes when sex is a latent (linearised per sex)."""
        measurer = body_measurer(self.body)
        if self.sexes is not None:
            return self.sexes.measurements(measurer)
        return gaussian_measurements(measurer, self.shape_mean, self.shape_std)

    @property
    def F(self) -> torch.Tensor:
        """``(23, 3, 3)`` matrix-Fisher parameters of the relative joint rotations."""
        return self.distribution.F

    @property
    def shape_mean(self) -> torch.Tensor:
        """``(10,)`` mean shape coefficients."""
        return self.distribution.shape_mean

    @property
    def shape_std(self) -> torch.Tensor:
        """``(10,)`` standard deviations of the shape coefficients."""
        return self.distribution.shape_std

    @property
    def global_orient(self) -> torch.Tensor:
        """``(3, 3)`` body-to-camera rotation."""
        return self.distribution.global_orient

    @property
    def camera(self) -> torch.Tensor:
        """``(3,)`` weak-perspective ``[s, tx, ty]`` of the crop."""
        return self.distribution.camera

    @property
    def conditioned(self) -> bool:
        """True when the distribution is conditioned on the photo's keypoints."""
        return self.source == "evidence"

    @property
    def person_box(self) -> tuple[float, float, float, float] | None:
        """``(x0, y0, x1, y1)`` photo pixels: the box of the person this reading is of (all 33
        BlazePose landmarks, clipped to the photo; ``summary.json``'s ``detected_bbox``), so
        :meth:`hkpd.prediction.Predictor.predict_all`'s posteriors say who each is. None when
        the posterior did not come from a photo."""
        if self.network_input is None:
            return None
        x0, y0, x1, y1 = (float(v) for v in self.network_input.detection.person_box[:4])
        return (x0, y0, x1, y1)

    @property
    def fallback_reason(self) -> str | None:
        """Why an evidence posterior was asked for but the network's is returned (else None)."""
        if self.evidence_fit is None or self.conditioned:
            return None
        return self.evidence_fit.reason or "the keypoint fit failed"

    @functools.cached_property
    def quality(self) -> ReadingQuality:
        """How far to trust this reading (:mod:`hkpd.prediction.quality`): ``score`` in [0, 1]
        (calibrated: among readings scored ``s``, about ``s`` are not off) and ``flags``
        (short names of what looks wrong). Computed once, from what the posterior already
        holds (no fit is run again)."""
        return reading_quality(self)

    @functools.cached_property
    def pose_distribution(self) -> KinematicMatrixFisher:
        """The hierarchical matrix-Fisher distribution, batch shape ``(1,)``; built (with its
        SVD) once per posterior."""
        return self.distribution.map(lambda tensor: tensor[None]).pose_distribution()

    @property
    def shape_distribution(self) -> torch.distributions.Independent:
        """The shape Gaussian, batch shape ``(1,)``, event shape ``(10,)``."""
        return self.distribution.map(lambda tensor: tensor[None]).shape_distribution()

    def _meshes(self, betas: torch.Tensor, body_pose: torch.Tensor) -> BodyMeshes:
        count = betas.shape[0]
        orient = self.global_orient.expand(count, 3, 3)
        with torch.no_grad():
            posed = self.body(betas, body_pose, orient)
        root = posed.joints[:, :1]
        keypoints3d = posed.keypoints - root
        landmarks = extremity_landmarks(self.body).of_mesh(posed.vertices) - root  # (N, 16, 3)
        pixels = self._photo_pixels(torch.cat((keypoints3d, landmarks), dim=1))
        return BodyMeshes(
            vertices=posed.vertices.sub_(root),  # in place: one copy of n meshes, not two
            joints=posed.joints - root,
            keypoints3d=keypoints3d,
            keypoints2d=pixels[:, :17],
            betas=betas,
            body_pose=body_pose,
            foot_keypoints2d=pixels[:, 17 + NUM_EXTREMITY :],
            extremity_keypoints2d=pixels[:, 17 : 17 + NUM_EXTREMITY],
        )

    def _photo_pixels(self, points: torch.Tensor) -> torch.Tensor:
        """``(N, P, 3)`` root-relative points (metres) -> ``(N, P, 2)`` original-photo pixels
        through the posterior's weak-perspective camera and crop."""
        ndc = weak_perspective_project(points, self.camera.expand(points.shape[0], 3))
        pixels = self.crop.crop_to_image(ndc_to_pixels(ndc, self.crop.size))
        return torch.as_tensor(pixels, dtype=points.dtype)

    def mode(self) -> BodyMeshes:
        """The most likely body: modal rotations and the mean shape (N = 1)."""
        return self._meshes(self.shape_mean[None], self.pose_distribution.mode)

    def _draw(self, n: int, seed: int | None) -> tuple[torch.Tensor, torch.Tensor]:
        """``betas (n, K)`` and ``body_pose (n, 23, 3, 3)`` drawn from the posterior."""
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"the number of samples must be an integer >= 1, got {n!r}")
        generator = torch.Generator(device=self.F.device)
        if seed is None:
            generator.seed()
        else:
            generator.manual_seed(int(seed))
        with torch.no_grad():
            body_pose = self.pose_distribution.sample(n, generator=generator)[:, 0]
            noise = torch.randn(n, self.shape_mean.shape[0], generator=generator,
                                device=self.F.device, dtype=self.shape_mean.dtype)  # fmt: skip
            if self.sexes is not None:
                uniform = torch.rand(n, generator=generator, device=self.F.device)
                return self.sexes.sample_betas(noise, uniform), body_pose
        return self.shape_mean + noise * self.shape_std, body_pose

    def sample(self, n: int, seed: int | None = None) -> BodyMeshes:
        """``n`` bodies drawn from the posterior with the rejection sampler (N = n).

        Every mesh is returned (``n × V × 3`` floats: about 160 kB a body); for the spread of
        many samples use :meth:`vertex_uncertainty`, which works in bounded memory.

        Args:
            n: number of samples (>= 1).
            seed: makes the draw reproducible; None draws fresh randomness.
        """
        betas, body_pose = self._draw(n, seed)
        return self._meshes(betas, body_pose)

    def vertex_uncertainty(
        self, n: int = 100, seed: int | None = 0, chunk: int = UNCERTAINTY_CHUNK
    ) -> torch.Tensor:
        """``(V,)`` mean distance of ``n`` sampled meshes' vertices from their mean, metres.

        The samples are the ones :meth:`sample` draws for the same ``n`` and ``seed``; meshes
        are built ``chunk`` at a time (twice when ``n > chunk``: once for the mean, once for
        the distances), so memory stays bounded whatever ``n`` is.
        """
        if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
            raise ValueError(f"chunk must be an integer >= 1, got {chunk!r}")
        betas, body_pose = self._draw(n, seed)
        if n <= chunk:
            return vertex_uncertainty(self._meshes(betas, body_pose).vertices)
        pieces = [slice(start, min(start + chunk, n)) for start in range(0, n, chunk)]
        total = None
        for piece in pieces:
            part = self._vertices(betas[piece], body_pose[piece]).sum(0)
            total = part if total is None else total + part
        mean = total / n
        distance = torch.zeros(mean.shape[0], dtype=mean.dtype, device=mean.device)
        for piece in pieces:
            vertices = self._vertices(betas[piece], body_pose[piece])
            distance += torch.linalg.vector_norm(vertices - mean, dim=-1).sum(0)
        return distance / n

    def _vertices(self, betas: torch.Tensor, body_pose: torch.Tensor) -> torch.Tensor:
        """``(N, V, 3)`` root-relative vertices (no keypoints or reprojection)."""
        count = betas.shape[0]
        with torch.no_grad():
            posed = self.body(betas, body_pose, self.global_orient.expand(count, 3, 3))
            return posed.vertices.sub_(posed.joints[:, :1])

    def with_concentration(
        self, joint: int | str | Sequence[int | str] | None, factor: RealNumber
    ) -> BodyPosterior:
        """A posterior whose selected joints' concentrations are scaled by ``factor``.

        Factors multiply: scaling twice by 2 is scaling by 4. ``joint=None`` scales all 23.
        Principal axes and modes do not change, only how tightly samples gather around them.

        Raises:
            TypeError: ``factor`` is not a real number (python, numpy or a one-element torch
                tensor; bools and complex numbers are not).
            ValueError: ``factor`` is not finite and > 0, or would push a selected joint's
                proper singular value past :data:`MAX_CONCENTRATION` (the message gives the
                largest factor allowed).
        """
        if joint is None:
            selected = list(range(len(BODY_JOINT_NAMES)))
        elif isinstance(joint, (int, str)) and not isinstance(joint, bool):
            selected = [body_joint_index(joint)]
        elif isinstance(joint, Sequence) and not isinstance(joint, (str, bool)):
            selected = [body_joint_index(_joint_key(j)) for j in joint]
        else:
            raise TypeError(
                f"joint must be a joint index, a name, a list of them or None, got {joint!r}"
            )
        largest = float(self.pose_distribution.joints.S[..., selected, :].abs().max())
        factor = _scale_factor(
            "concentration factor", factor, largest, MAX_CONCENTRATION, "concentration"
        )
        scaled = self.pose_distribution.scale_concentration(selected, factor)
        edited = replace(self, distribution=replace(self.distribution, F=scaled.F[0]))
        edited.__dict__["pose_distribution"] = scaled  # keeps the reused SVD (cached_property)
        return edited

    def with_shape_std(self, factor: RealNumber) -> BodyPosterior:
        """A posterior whose shape standard deviations are scaled by ``factor`` (> 0).

        Raises:
            TypeError, ValueError: as :meth:`with_concentration`, the bound being
                :data:`MAX_SHAPE_STD` for every shape standard deviation.
        """
        largest = float(self.shape_std.abs().max())
        factor = _scale_factor("shape std factor", factor, largest, MAX_SHAPE_STD, "shape std")
        shape_std = self.shape_std * factor
        sexes = None if self.sexes is None else self.sexes.scaled(factor)
        edited = replace(
            self, distribution=replace(self.distribution, shape_std=shape_std), sexes=sexes
        )
        edited.__dict__["pose_distribution"] = self.pose_distribution  # pose unchanged
        return edited


def _scale_factor(name: str, factor: RealNumber, largest: float, limit: float, what: str) -> float:
    """``factor`` as a float, or one message for every refusal: it must be finite, > 0 and keep
    the largest scaled value (``largest`` now) at most ``limit``."""
    value = _real_number(name, factor)
    ceiling = limit / largest if largest > 0 else math.inf
    if not (math.isfinite(value) and 0 < value <= ceiling):
        raise ValueError(
            f"{name} must be a finite number > 0 and at most {limit:g} / the largest {what} "
            f"({ceiling:.3g} for this posterior), got {value:g}"
        )
    return value


def _real_number(name: str, factor: RealNumber) -> float:
    """``factor`` as a float (inf if it overflows one): any real python or numpy number, a 0-d
    numpy array or a one-element torch tensor of a real dtype; not a bool or complex number."""
    if isinstance(factor, torch.Tensor):
        real = factor.numel() == 1 and not (factor.dtype.is_complex or factor.dtype == torch.bool)
    elif isinstance(factor, np.ndarray):
        real = factor.ndim == 0 and factor.dtype.kind in "iuf"
    else:
        real = isinstance(factor, Real) and not isinstance(factor, (bool, np.bool_))
    if not real:
        raise TypeError(
            f"{name} must be a real number (an int or float, or a numpy or torch scalar), "
            f"got {factor!r}"
        )
    try:
        return float(factor)
    except OverflowError:  # an int beyond float64
        return math.inf


def _joint_key(joint: int | str) -> int | str:
    if isinstance(joint, bool) or not isinstance(joint, (int, str)):
        raise TypeError(f"joints must be indices or names, got {joint!r}")
    return joint
