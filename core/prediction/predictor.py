"""``Predictor``: a photo in, a :class:`BodyPosterior` out.

``predict`` runs the front end (:func:`prepare_network_input`: load, paint occluders, detect
2D keypoints with BlazePose, crop, build the proxy) and the distribution-prediction network,
and wraps the result in a :class:`BodyPosterior` that samples bodies and maps them back to the
photo.
"""

from __future__ import annotations

import importlib.resources
import os
import threading
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from hkpd.body import BodyModel
from hkpd.devices import resolve_device
from hkpd.prediction.image_input import LoadedImage
from hkpd.prediction.keypoint_detector import KeypointDetector
from hkpd.prediction.network_input import prepare_network_input
from hkpd.prediction.posterior import BodyPosterior
from hkpd.training.checkpoint import load_network

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

    Thread safety: ``predict`` may be called from several threads; calls are serialised.
    """

    def __init__(
        self,
        network: torch.nn.Module,
        device: torch.device | str = "cpu",
        body: BodyModel | None = None,
        detector: KeypointDetector | None = None,
    ) -> None:
        self.device = torch.device(device)
        self.network = network.to(self.device).eval()
        self.body = (body or BodyModel()).to(self.device)
        self.detector = detector or KeypointDetector()
        self.crop_size = int(network.config.image_size)
        self._lock = threading.Lock()

    @classmethod
    def from_pretrained(
        cls, path: str | os.PathLike[str] | None = None, device: str = "auto"
    ) -> Predictor:
        """Load a checkpoint (default: the shipped pretrained model).

        Args:
            path: a checkpoint written by ``hkpd-train`` or the shipped weights.
            device: ``auto`` (CUDA when available), ``cpu`` or ``cuda``.
        """
        resolved = resolve_device(device)
        network, _ = load_network(Path(path) if path else shipped_model_path(), resolved)
        return cls(network, resolved)

    @torch.no_grad()
    def predict(
        self,
        image: str | os.PathLike[str] | np.ndarray | Image.Image | LoadedImage,
        occluders: Sequence[Sequence[float]] | np.ndarray | None = None,
        bbox: Sequence[float] | np.ndarray | None = None,
    ) -> BodyPosterior:
        """The body posterior of the person in ``image``.

        Args:
            image: a file path, an ``(H, W, 3)`` uint8 RGB array, a PIL image, or a
                :class:`LoadedImage`.
            occluders: ``(x0, y0, x1, y1)`` boxes in original-photo pixels, painted black
                before detection and edge extraction.
            bbox: ``(x0, y0, x1, y1)``: look for the person only there (pick someone else
                when a photo shows several people).

        Raises:
            ImageInputError: the image is missing, unreadable or unusable.
            NoPersonFoundError: nobody was found.
        """
        with self._lock:
            prepared = prepare_network_input(
                image,
                self.detector,
                bbox=bbox,
                occluders=() if occluders is None else occluders,
                crop_size=self.crop_size,
            )
            output = self.network(prepared.proxy[None].to(self.device))
        return BodyPosterior(
            F=output.F[0].float(),
            shape_mean=output.shape_mean[0].float(),
            shape_std=output.shape_std[0].float(),
            global_orient=output.global_orient[0].float(),
            camera=output.camera[0].float(),
            crop=prepared.crop,
            keypoints=torch.as_tensor(prepared.detection.keypoints, dtype=torch.float32),
            confidences=torch.as_tensor(prepared.confidences, dtype=torch.float32),
            body=self.body,
            network_input=prepared,
        )

    def close(self) -> None:
        """Release the detector's resources."""
        self.detector.close()
