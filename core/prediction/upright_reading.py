"""A network that reads leaning people from an upright copy of its input.

:class:`UprightReader` wraps a distribution network for inputs that are already proxies (the
synthetic test sets, or anyone's own edges + heatmaps): for each example whose torso, read off
its shoulder and hip heatmaps, leans more than a threshold from upright, the network reads a
copy turned upright (:class:`hkpd.prediction.upright_view.UprightView`: the edge image (or
whichever image proxy the network reads) warped, the heatmaps drawn again at the turned
keypoints) and its global rotation and camera are mapped back to the original frame.
Relative joint rotations and shape do not depend on the view.

For photos, :meth:`hkpd.prediction.Predictor.predict` does the same from the RGB crop (edges
are found again on the turned photo rather than warped).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import torch

from hkpd.conditioning import EvidenceConfig
from hkpd.network.output import NetworkOutput
from hkpd.prediction.upright_view import UprightView, torso_tilt
from hkpd.proxy import NUM_KEYPOINTS, assemble_proxy, proxy_image_planes
from hkpd.proxy.heatmaps import heatmap_peaks

UPRIGHT_READING_DEGREES = EvidenceConfig().upright_start_degrees
"""Examples leaning more than this (30°) are read from an upright copy, as the predictor does."""


class UprightReader(torch.nn.Module):
    """``network``, reading leaning examples from upright copies of their proxies.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` (its ``config`` is exposed).
        threshold_degrees: lean above which an example is turned upright.

    Attributes:
        last_tilts_degrees: ``(B,)`` float64 of the last call: the lean undone per example (NaN
            for examples read as they were).
    """

    def __init__(
        self, network: torch.nn.Module, threshold_degrees: float = UPRIGHT_READING_DEGREES
    ) -> None:
        super().__init__()
        if not 0.0 <= threshold_degrees <= 180.0:
            raise ValueError(f"threshold_degrees must lie in [0, 180], got {threshold_degrees}")
        self.network = network
        self.config = network.config
        self.threshold = math.radians(threshold_degrees)
        self.last_tilts_degrees = np.empty(0)

    def forward(self, proxy: torch.Tensor) -> NetworkOutput:
        """The network's output for ``(B, C + 17, S, S)`` proxies, each in its own frame."""
        heatmaps_from = proxy.shape[1] - NUM_KEYPOINTS
        keypoints, present = heatmap_peaks(proxy[:, heatmaps_from:])
        points, observed = keypoints.cpu().double().numpy(), present.cpu().numpy()
        size = int(proxy.shape[-1])
        views: dict[int, UprightView] = {}
        self.last_tilts_degrees = np.full(proxy.shape[0], np.nan)
        for index in range(proxy.shape[0]):
            tilt = torso_tilt(points[index], observed[index])
            if tilt is not None and abs(tilt) > self.threshold:
                views[index] = UprightView.from_tilt(tilt, points[index], size, observed[index])
                self.last_tilts_degrees[index] = math.degrees(tilt)
        if not views:
            return self.network(proxy)
        turned = proxy.clone()
        planes = proxy_image_planes(proxy).cpu().numpy()
        for index, view in views.items():
            turned_planes = torch.from_numpy(view.warp_planes(planes[index]))
            turned_points = torch.as_tensor(view.points(points[index]), dtype=torch.float32)
            turned[index] = assemble_proxy(
                turned_planes[None], turned_points[None], present[index, None].cpu()
            )[0].to(proxy.device)
        output = self.network(turned)
        orient, camera = output.global_orient.clone(), output.camera.clone()
        for index, view in views.items():
            orient[index], camera[index] = view.to_crop_frame(
                output.global_orient[index], output.camera[index]
            )
        return replace(output, global_orient=orient, camera=camera)
