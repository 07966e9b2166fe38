"""``Predictor``: a photo in, a :class:`BodyPosterior` out.

``predict`` runs the front end (:func:`prepare_network_input`: load, detect 2D keypoints with
BlazePose, paint occluders, crop, build the proxy) and the distribution-prediction network.
By default it then conditions the network's distribution on the detected keypoints
(:func:`hkpd.conditioning.condition_on_keypoints`; ``docs/evidence.md``): the network's
distribution is the prior, the confident keypoints that no occluder covers are the evidence.
When the torso leans more than ``EvidenceConfig.upright_start_degrees``, the network also reads
a copy of the crop turned upright (:mod:`hkpd.prediction.upright_view`) and the fit starts from
both answers; when the evidence shows no torso, the lean is read off the network's own reading
(:mod:`hkpd.prediction.network_lean`). ``evidence=False`` returns the network's own
distribution (the paper's method); for a leaning person that is its answer on the upright copy,
mapped back to the photo (on held-out photos this reading alone cut the network's error by a
third), unless ``upright=False``.
"""

from __future__ import annotations

import copy
import importlib.resources
import math
import os
import threading
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from hkpd.body import BodyModel
from hkpd.conditioning import EvidenceConfig, KeypointEvidence, condition_on_keypoints
from hkpd.devices import resolve_device
from hkpd.distributions import BodyDistribution
from hkpd.network.checkpoint import load_network, stored_evidence_config
from hkpd.prediction.image_input import LoadedImage
from hkpd.prediction.keypoint_detector import KeypointDetector
from hkpd.prediction.mirror_reading import MirrorChoosingReader
from hkpd.prediction.network_input import NetworkInput, prepare_network_input
from hkpd.prediction.network_lean import (
    LEAN_CANDIDATES_DEGREES,
    TURNED_FIT_MARGIN,
    mode_keypoint_misfits,
    mode_torso_tilts,
)
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.upright_view import UprightView, torso_tilt
from hkpd.proxy import build_proxy

SHIPPED_MODEL = ("models", "hkpd_hierarchical.pt")
"""The pretrained weights inside the ``hkpd.assets`` package."""


def shipped_model_path() -> Path:
    """Path of the shipped pretrained weights.

    Raises:
        FileNotFoundError: they are not installed, with what to do instead.
    """
    resource = importlib.resources.files("hkpd.assets").joinpath(*SHIPPED_MODEL)
    if not resource.is_file():
        raise FileNotFoundError(
            f"the pretrained model {'/'.join(SHIPPED_MODEL)} is not in this installation of "
            "hkpd; pass a checkpoint from `hkpd-train` (e.g. runs/hkpd/last.pt) instead"
        )
    return Path(str(resource))


class Predictor:
    """Predicts body posteriors from photos with a trained network.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` (eval mode).
        device: where the network and body model run.
        body: the body model (default: the shipped one).
        detector: the 2D keypoint detector (default: BlazePose, created on first use).
        evidence_config: how the keypoint evidence updates the network's distribution.
        mirror_reading: let the network read every crop (and upright copy) as it is and
            mirrored, keeping the reading whose most likely body fits the shown keypoints more
            closely (:mod:`hkpd.prediction.mirror_reading`); False reads each once.

    Thread safety: ``predict`` may be called from several threads; calls are serialised.
    """

    def __init__(
        self,
        network: torch.nn.Module,
        device: torch.device | str = "cpu",
        body: BodyModel | None = None,
        detector: KeypointDetector | None = None,
        evidence_config: EvidenceConfig | None = None,
        mirror_reading: bool = True,
    ) -> None:
        self.device = torch.device(device)
        network = network.to(self.device).eval()
        self.body = (body or BodyModel()).to(self.device)
        self.mirror_reading = mirror_reading
        self.network = MirrorChoosingReader(network, self.body) if mirror_reading else network
        self.detector = detector or KeypointDetector()
        self.crop_size = int(network.config.image_size)
        self.image_proxy = str(network.config.image_proxy)
        self.evidence_config = evidence_config or EvidenceConfig()
        self._lock = threading.Lock()
        self._body64: BodyModel | None = None

    @classmethod
    def from_pretrained(
        cls,
        path: str | os.PathLike[str] | None = None,
        device: str = "auto",
        mirror_reading: bool = True,
        evidence_config: EvidenceConfig | None = None,
    ) -> Predictor:
        """Load a checkpoint (default: the shipped pretrained model).

        Args:
            path: a checkpoint written by ``hkpd-train`` or the shipped weights.
            device: ``auto`` (CUDA when available), ``cpu`` or ``cuda``.
            mirror_reading: as for the constructor.
            evidence_config: None takes the evidence settings stored with the weights
                (``hkpd-tune-evidence --write-to``; the defaults when none are stored).
        """
        resolved = resolve_device(device)
        source = Path(path) if path else shipped_model_path()
        network, payload = load_network(source, resolved)
        if evidence_config is None:
            evidence_config = EvidenceConfig.from_dict(stored_evidence_config(payload), str(source))
        return cls(
            network, resolved, evidence_config=evidence_config, mirror_reading=mirror_reading
        )

    @torch.no_grad()
    def predict(
        self,
        image: str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage,
        occluders: Sequence[Sequence[float]] | np.ndarray | None = None,
        bbox: Sequence[float] | np.ndarray | None = None,
        evidence: bool = True,
        upright: bool = True,
        silhouette: np.ndarray | None = None,
    ) -> BodyPosterior:
        """The body posterior of the person in ``image``.

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
                ``evidence_config.upright_start_degrees``, let the network also read a copy of
                the crop turned upright (``posterior.upright_tilt_degrees`` says by how much):
                with ``evidence`` the fit starts from both answers, without it the upright
                copy's answer is the network's posterior. When the evidence shows no torso
                (nor a stand-in for it), the lean is that of the body the network reads
                (:mod:`hkpd.prediction.network_lean`). False reads the crop as it is.
            silhouette: ``(H, W)`` bool mask of the person, original-photo pixels: only for
                networks that read a silhouette instead of edges (the proxy ablation's
                ``network.config.image_proxy == "silhouette"``), which need one.

        Raises:
            ImageInputError: the image is missing, unreadable or unusable.
            NoPersonFoundError: nobody was found.
            ValueError: a silhouette network without a silhouette of the photo's size.
        """
        with self._lock:
            prepared = prepare_network_input(
                image,
                self.detector,
                bbox=bbox,
                occluders=() if occluders is None else occluders,
                crop_size=self.crop_size,
                image_proxy=self.image_proxy,
                silhouette=silhouette,
            )
            observed = prepared.confidences > 0
            tilt = torso_tilt(prepared.keypoints_crop, observed) if upright else None
            view = None
            proxies = [prepared.proxy]
            if tilt is not None and abs(tilt) > self._upright_threshold:
                view = self._upright_view(tilt, prepared)
            elif upright and tilt is None:  # no torso in the evidence: the network's lean
                view = self._view_from_network_lean(prepared)
            if view is not None:
                tilt = view.tilt
                proxies.append(_upright_proxy(view, prepared, self.image_proxy))
            output = self.network(torch.stack(proxies).to(self.device))
            mirrored = self._mirrored(len(proxies))
            starts = _starts(output, view)
            if not evidence:  # the upright copy's reading when there is one
                last = len(proxies) - 1
                return self._posterior(starts, last, prepared, observed, tilt, mirrored[last])
            network_posterior = self._posterior(starts, 0, prepared, observed, tilt, mirrored[0])
            keypoint_evidence = KeypointEvidence(
                torch.as_tensor(prepared.keypoints_crop, dtype=torch.float64),
                torch.as_tensor(observed),
                self.crop_size,
            )
            fit = condition_on_keypoints(
                self._float64_body(), starts, keypoint_evidence, self.evidence_config
            )
        if fit.conditioned is None:
            return replace(network_posterior, evidence_fit=fit)
        prior = self._posterior(starts, fit.start, prepared, observed, tilt, mirrored[fit.start])
        conditioned = fit.conditioned
        return replace(
            prior,
            F=conditioned.F.float().to(self.device),
            shape_mean=conditioned.shape_mean.float().to(self.device),
            shape_std=conditioned.shape_std.float().to(self.device),
            global_orient=conditioned.global_orient.float().to(self.device),
            camera=conditioned.camera.float().to(self.device),
            source="evidence",
            prior=prior,
            evidence_fit=fit,
        )

    def _mirrored(self, count: int) -> list[bool]:
        """Which of the last network call's ``count`` readings came from the mirror image."""
        if isinstance(self.network, MirrorChoosingReader):
            return [bool(flag) for flag in self.network.last_mirrored]
        return [False] * count

    @property
    def _upright_threshold(self) -> float:
        """Lean (radians) from which the network also reads an upright copy."""
        return math.radians(self.evidence_config.upright_start_degrees)

    def _upright_view(self, tilt: float, prepared: NetworkInput) -> UprightView:
        """The upright copy undoing ``tilt``, framed as the crop was (on every detected
        keypoint), not on the evidence alone: the network learnt crops framed around the whole
        person, and covering a limb must not move the copy."""
        return UprightView.from_tilt(tilt, prepared.box_keypoints_crop, self.crop_size)

    def _view_from_network_lean(self, prepared: NetworkInput) -> UprightView | None:
        """For a crop whose evidence shows no torso: the upright copy turned by the lean, among
        :data:`LEAN_CANDIDATES_DEGREES` and the lean of the network's own reading, whose reading
        fits the shown keypoints best (:mod:`hkpd.prediction.network_lean`); None unless it fits
        them :data:`TURNED_FIT_MARGIN` closer than the crop read as it is."""
        keypoints = prepared.keypoints_crop[None]
        observed = (prepared.confidences > 0)[None]
        as_it_is = self.network(prepared.proxy[None].to(self.device))
        best = mode_keypoint_misfits(as_it_is, self.body, self.crop_size, keypoints, observed)[0]
        leans = [math.radians(degrees) for degrees in LEAN_CANDIDATES_DEGREES]
        (own_lean,) = mode_torso_tilts(as_it_is, self.body, self.crop_size)
        if own_lean is not None and abs(own_lean) > self._upright_threshold:
            leans.append(own_lean)
        views = [self._upright_view(lean, prepared) for lean in leans]
        turned = torch.stack([_upright_proxy(view, prepared, self.image_proxy) for view in views])
        output = self.network(turned.to(self.device))
        mapped = [
            view.to_crop_frame(output.global_orient[index].cpu(), output.camera[index].cpu())
            for index, view in enumerate(views)
        ]
        output = replace(
            output,
            global_orient=torch.stack([orient for orient, _ in mapped]).to(self.device),
            camera=torch.stack([camera for _, camera in mapped]).to(self.device),
        )
        count = len(views)
        misfits = mode_keypoint_misfits(
            output,
            self.body,
            self.crop_size,
            np.repeat(keypoints, count, 0),
            np.repeat(observed, count, 0),
        )
        winner = int(np.argmin(misfits))
        return views[winner] if misfits[winner] < (1.0 - TURNED_FIT_MARGIN) * best else None

    def _posterior(
        self,
        starts: BodyDistribution,
        index: int,
        prepared: NetworkInput,
        observed: np.ndarray,
        tilt: float | None,
        mirror_read: bool = False,
    ) -> BodyPosterior:
        """The network's posterior of start ``index`` (0: the crop; 1: its upright copy,
        already in the crop's frame, that undid ``tilt`` radians), read from the mirror image
        when ``mirror_read``."""
        return BodyPosterior(
            upright_tilt_degrees=math.degrees(tilt) if index == 1 and tilt is not None else None,
            mirror_read=mirror_read,
            F=starts.F[index].float().to(self.device),
            shape_mean=starts.shape_mean[index].float().to(self.device),
            shape_std=starts.shape_std[index].float().to(self.device),
            global_orient=starts.global_orient[index].float().to(self.device),
            camera=starts.camera[index].float().to(self.device),
            crop=prepared.crop,
            keypoints=torch.as_tensor(prepared.detection.keypoints, dtype=torch.float32),
            confidences=torch.as_tensor(prepared.confidences, dtype=torch.float32),
            body=self.body,
            network_input=prepared,
            evidence=torch.as_tensor(observed),
        )

    def _float64_body(self) -> BodyModel:
        """A float64 CPU copy of the body model for the fit (made once)."""
        if self._body64 is None:
            self._body64 = copy.deepcopy(self.body).cpu().double()
        return self._body64

    def close(self) -> None:
        """Release the detector's resources."""
        self.detector.close()


def refuse_silhouette_model(predictor: Predictor, tool: str) -> None:
    """Close ``predictor`` and raise a ValueError when its network reads person silhouettes
    (a proxy-ablation model), which ``tool`` cannot give it: hkpd has no person segmentation."""
    if predictor.image_proxy == "silhouette":
        predictor.close()
        raise ValueError(
            f"this model reads person silhouettes (a proxy-ablation model) and {tool} has no "
            "person segmentation; use an edge model such as the shipped one"
        )


def _upright_proxy(view: UprightView, prepared: NetworkInput, image_proxy: str) -> torch.Tensor:
    """The ``(C + 17, S, S)`` proxy of the upright copy: the crop (and its silhouette) turned,
    the image proxy found again on it, heatmaps drawn at the turned keypoints."""
    silhouette = None
    if prepared.crop_silhouette is not None:
        silhouette = view.warp(prepared.crop_silhouette.astype(np.uint8) * 255) >= 128
    return build_proxy(
        view.warp(prepared.crop_rgb),
        view.points(prepared.keypoints_crop),
        prepared.confidences,
        image_proxy,
        silhouette,
    )


def _starts(output: BodyDistribution, view: UprightView | None) -> BodyDistribution:
    """The network's answers as fit starts on the CPU, the upright copy's mapped back to the
    crop's frame."""
    F, shape_mean, shape_std, orient, camera = (
        getattr(output, name).detach().float().cpu()
        for name in ("F", "shape_mean", "shape_std", "global_orient", "camera")
    )
    if view is not None:
        orient, camera = orient.clone(), camera.clone()
        orient[1], camera[1] = view.to_crop_frame(orient[1], camera[1])
    return BodyDistribution(F, shape_mean, shape_std, orient, camera)
