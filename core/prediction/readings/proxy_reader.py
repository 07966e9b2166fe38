"""The reading stage for inputs that are already proxies (the synthetic test sets, or anyone's
own edges + heatmaps).

:class:`ProxyReader` wraps a distribution network like the network itself (proxies in, a
:class:`BodyDistribution` out) and reads through :class:`hkpd.prediction.readings.ReadingStage`
(mirror reading, upright copies of leaning people, lean search for torso-less views). The shown
keypoints are the heatmaps' peaks; an upright copy is the proxy's image planes (edges, or
whichever image proxy the network reads) warped, nearest pixel, with the heatmaps drawn again
at the turned keypoints (:class:`PlaneTurnedProxy`). Relative joint rotations and shape do not
depend on the view; the global rotation and camera are mapped back to the crop's frame.

The copy is framed by the crop rule (:meth:`hkpd.prediction.crop.CropTransform.from_keypoints`)
on the keypoints the crop itself was framed on, when the caller has them (``crop_keypoints``:
the synthetic data's crops surround all 17 keypoints, hidden ones included, as the predictor's
surround every detected keypoint), else on the keypoints the heatmaps show. The difference is
not small: framing an upright synthetic test crop again on its shown keypoints alone, without
turning it, raises the shipped network's 2D error from 5.1 to 6.6 px, since crops framed on
part of a person are not what it learnt.

For photos, :class:`hkpd.prediction.Predictor` reads through the same stage, its copies made
from the RGB crop (edges are found again on the turned photo rather than warped).
"""

from __future__ import annotations

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.distributions import BodyDistribution
from hkpd.prediction.readings import ReadingConfig, ReadingInput, Readings, ReadingStage
from hkpd.prediction.readings.upright_view import UprightView
from hkpd.proxy import NUM_KEYPOINTS, assemble_proxy, proxy_image_planes
from hkpd.proxy.heatmaps import heatmap_peaks


class PlaneTurnedProxy:
    """Upright copies of ready-made proxies: image planes warped, heatmaps drawn again.

    Args:
        proxy: ``(B, C + 17, S, S)`` the proxies.
        keypoints: ``(B, 17, 2)`` float64 their heatmaps' peaks, crop pixels.
        present: ``(B, 17)`` bool, which heatmaps show a keypoint.
    """

    def __init__(self, proxy: torch.Tensor, keypoints: np.ndarray, present: torch.Tensor) -> None:
        self.proxy, self.keypoints, self.present = proxy, keypoints, present
        self._planes: np.ndarray | None = None

    def __call__(self, example: int, view: UprightView) -> torch.Tensor:
        """The ``(C + 17, S, S)`` proxy of ``example`` turned by ``view``, on the proxies'
        device."""
        if self._planes is None:
            self._planes = proxy_image_planes(self.proxy).cpu().numpy()
        planes = torch.from_numpy(view.warp_planes(self._planes[example]))
        points = torch.as_tensor(view.points(self.keypoints[example]), dtype=torch.float32)
        present = self.present[example, None].cpu()
        return assemble_proxy(planes[None], points[None], present)[0].to(self.proxy.device)


def proxy_reading_input(
    proxy: torch.Tensor, crop_keypoints: torch.Tensor | None = None
) -> ReadingInput:
    """The reading stage's input for ``(B, C + 17, S, S)`` proxies: the shown keypoints are
    the heatmaps' peaks; the copies are framed on ``crop_keypoints`` (``(B, 17, 2)`` crop
    pixels, the keypoints each crop was framed on) when given, else on the shown keypoints.

    Raises:
        ValueError: ``crop_keypoints`` not ``(B, 17, 2)``.
    """
    peaks, present = heatmap_peaks(proxy[:, proxy.shape[1] - NUM_KEYPOINTS :])
    keypoints = peaks.cpu().double().numpy()
    if crop_keypoints is not None and tuple(crop_keypoints.shape) != tuple(peaks.shape):
        raise ValueError(f"crop_keypoints must be {tuple(peaks.shape)}, got "
                         f"{tuple(crop_keypoints.shape)}")  # fmt: skip
    framing = None if crop_keypoints is None else crop_keypoints.cpu().double().numpy()
    turned = PlaneTurnedProxy(proxy, keypoints, present)
    return ReadingInput(proxy, keypoints, present.cpu().numpy(), turned, framing)


class ProxyReader(torch.nn.Module):
    """``network``, reading proxies through the reading stage.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` or a wrapper of one (its
            ``config`` is exposed).
        config: the reading settings (mirror reading, upright start, lean search).
        upright: read leaning and torso-less examples from upright copies; False reads every
            proxy as it is (with ``config.mirror``: as it is and mirrored).
        body: the body model that poses the readings (on the network's device); None: the
            shipped one, loaded when first needed.

    Attributes:
        last_readings: the last call's :class:`Readings` (None before the first call).
    """

    def __init__(
        self,
        network: torch.nn.Module,
        config: ReadingConfig | None = None,
        upright: bool = True,
        body: BodyModel | None = None,
    ) -> None:
        super().__init__()
        self.stage = ReadingStage(network, body, config)
        self.config = network.config
        self.upright = upright
        self.last_readings: Readings | None = None

    def forward(
        self, proxy: torch.Tensor, crop_keypoints: torch.Tensor | None = None
    ) -> BodyDistribution:
        """The chosen readings of ``(B, C + 17, S, S)`` proxies, each in its own frame.

        Args:
            proxy: the proxies.
            crop_keypoints: ``(B, 17, 2)`` crop pixels: the keypoints each crop was framed on
                (for synthetic batches, ``TrainingBatch.keypoints2d``); the upright copies are
                framed on them. None: on the keypoints the heatmaps show.
        """
        batch = proxy_reading_input(proxy, crop_keypoints)
        self.last_readings = self.stage.read(batch, upright=self.upright)
        return self.last_readings.chosen()

    @property
    def last_tilts_degrees(self) -> np.ndarray:
        """``(B,)`` float64 of the last call: the lean undone per example (NaN for examples
        read as they were)."""
        return np.empty(0) if self.last_readings is None else self.last_readings.tilts_degrees
