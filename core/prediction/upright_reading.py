"""A network that reads leaning people from an upright copy of its input.

:class:`UprightReader` wraps a distribution network for inputs that are already proxies (the
synthetic test sets, or anyone's own edges + heatmaps): for each example whose torso, read off
its shoulder and hip heatmaps, leans more than a threshold from upright, the network reads a
copy turned upright (:class:`hkpd.prediction.upright_view.UprightView`: the edge image (or
whichever image proxy the network reads) warped, the heatmaps drawn again at the turned
keypoints) and its global rotation and camera are mapped back to the original frame.
Relative joint rotations and shape do not depend on the view. Examples whose heatmaps show no
torso are read at several leans and turned by the one whose reading fits the shown keypoints
best (:mod:`hkpd.prediction.network_lean`).

The copy is framed by the crop rule (:meth:`hkpd.prediction.crop.CropTransform.from_keypoints`)
on the keypoints the crop itself was framed on, when the caller has them (``crop_keypoints``:
the synthetic data's crops surround all 17 keypoints, hidden ones included, as the predictor's
surround every detected keypoint), else on the keypoints the heatmaps show. The difference is
not small: framing an upright synthetic test crop again on its shown keypoints alone, without
turning it, raises the shipped network's 2D error from 5.1 to 6.6 px, since crops framed on
part of a person are not what it learnt.

For photos, :meth:`hkpd.prediction.Predictor.predict` does the same from the RGB crop (edges
are found again on the turned photo rather than warped).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.conditioning import EvidenceConfig
from hkpd.distributions import BodyDistribution
from hkpd.prediction.network_lean import (
    LEAN_CANDIDATES_DEGREES,
    TURNED_FIT_MARGIN,
    mode_keypoint_misfits,
    mode_torso_tilts,
)
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
        lean_from_network: for examples whose heatmaps show no torso, take the lean from the
            network's own reading (:mod:`hkpd.prediction.network_lean`); False reads them as
            they are.
        body: the body model that poses those readings (on the network's device); None: the
            shipped one, loaded when first needed.

    Attributes:
        last_tilts_degrees: ``(B,)`` float64 of the last call: the lean undone per example (NaN
            for examples read as they were).
    """

    def __init__(
        self,
        network: torch.nn.Module,
        threshold_degrees: float = UPRIGHT_READING_DEGREES,
        lean_from_network: bool = True,
        body: BodyModel | None = None,
    ) -> None:
        super().__init__()
        if not 0.0 <= threshold_degrees <= 180.0:
            raise ValueError(f"threshold_degrees must lie in [0, 180], got {threshold_degrees}")
        self.network = network
        self.config = network.config
        self.threshold = math.radians(threshold_degrees)
        self.lean_from_network = lean_from_network
        self.body = body
        self.last_tilts_degrees = np.empty(0)

    def forward(
        self, proxy: torch.Tensor, crop_keypoints: torch.Tensor | None = None
    ) -> BodyDistribution:
        """The network's output for ``(B, C + 17, S, S)`` proxies, each in its own frame.

        Args:
            proxy: the proxies.
            crop_keypoints: ``(B, 17, 2)`` crop pixels: the keypoints each crop was framed on
                (for synthetic batches, ``TrainingBatch.keypoints2d``); the upright copies are
                framed on them. None: on the keypoints the heatmaps show.
        """
        heatmaps_from = proxy.shape[1] - NUM_KEYPOINTS
        keypoints, present = heatmap_peaks(proxy[:, heatmaps_from:])
        points, observed = keypoints.cpu().double().numpy(), present.cpu().numpy()
        if crop_keypoints is not None and tuple(crop_keypoints.shape) != tuple(keypoints.shape):
            raise ValueError(f"crop_keypoints must be {tuple(keypoints.shape)}, got "
                             f"{tuple(crop_keypoints.shape)}")  # fmt: skip
        framing = None if crop_keypoints is None else crop_keypoints.cpu().double().numpy()
        size = int(proxy.shape[-1])
        views: dict[int, UprightView] = {}
        self.last_tilts_degrees = np.full(proxy.shape[0], np.nan)
        leanless = []
        for index in range(proxy.shape[0]):
            tilt = torso_tilt(points[index], observed[index])
            if tilt is None:
                leanless.append(index)
            elif abs(tilt) > self.threshold:
                views[index] = _view(tilt, points[index], observed[index], framing, index, size)
        if leanless and self.lean_from_network:
            views |= self._views_from_network_lean(
                proxy[leanless], points[leanless], observed[leanless], framing, leanless
            )
        for index, view in views.items():
            self.last_tilts_degrees[index] = math.degrees(view.tilt)
        return self._read(proxy, points, present, views)

    def _views_from_network_lean(
        self,
        proxy: torch.Tensor,
        points: np.ndarray,
        observed: np.ndarray,
        framing: np.ndarray | None,
        indices: list[int],
    ) -> dict[int, UprightView]:
        """Views for examples whose keypoints show no torso (``proxy`` holds just those, in the
        order of ``indices``): each read as it is, at every lean of
        :data:`LEAN_CANDIDATES_DEGREES` and at the lean of its own reading (when beyond the
        threshold); the reading whose
        most likely body fits the shown keypoints best wins, if it fits them
        :data:`TURNED_FIT_MARGIN` closer than the reading as it is."""
        present, size = torch.as_tensor(observed), int(proxy.shape[-1])
        if self.body is None:
            self.body = BodyModel().to(proxy.device)
        as_it_is = self.network(proxy)
        as_it_is_misfits = mode_keypoint_misfits(as_it_is, self.body, size, points, observed)
        best = np.full(len(indices), np.inf)
        chosen: dict[int, UprightView] = {}
        own_leans = [
            lean if lean is not None and abs(lean) > self.threshold else None
            for lean in mode_torso_tilts(as_it_is, self.body, size)
        ]
        candidates = [[math.radians(degrees)] * len(indices) for degrees in LEAN_CANDIDATES_DEGREES]
        candidates.append(own_leans)
        for leans in candidates:
            views = {
                row: _view(lean, points[row], observed[row], framing, indices[row], size)
                for row, lean in enumerate(leans)
                if lean is not None
            }
            if not views:
                continue
            output = self._read(proxy, points, present, views)
            misfits = mode_keypoint_misfits(output, self.body, size, points, observed)
            for row, view in views.items():
                if misfits[row] < best[row]:
                    best[row], chosen[row] = misfits[row], view
        return {
            indices[row]: view
            for row, view in chosen.items()
            if best[row] < (1.0 - TURNED_FIT_MARGIN) * as_it_is_misfits[row]
        }

    def _read(
        self,
        proxy: torch.Tensor,
        points: np.ndarray,
        present: torch.Tensor,
        views: dict[int, UprightView],
    ) -> BodyDistribution:
        """The network's output for ``proxy``, the examples in ``views`` read from their upright
        copies and mapped back to their crops' frames."""
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


def _view(
    tilt: float,
    points: np.ndarray,
    observed: np.ndarray,
    framing: np.ndarray | None,
    index: int,
    size: int,
) -> UprightView:
    """The upright copy undoing ``tilt`` for example ``index`` of a batch of ``size`` crops:
    framed on its crop keypoints (``framing[index]``) when known, else on its observed heatmap
    peaks (``points``, ``observed``: that example's)."""
    if framing is None:
        return UprightView.from_tilt(tilt, points, size, observed)
    return UprightView.from_tilt(tilt, framing[index], size)
