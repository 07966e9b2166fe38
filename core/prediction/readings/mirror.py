"""Reading a proxy and its mirror image, and keeping the reading that fits the keypoints better.

A person's left-right mirror image is just as plausible a photo of a person, and the network,
trained on mirrored poses, reads both about equally well on average (the shipped run 17: 4.83 px
against 4.83 px on the upright synthetic split). But not equally well *per photo*: read both
ways, the reading whose most likely body projects closer to the keypoints the heatmaps show
(:func:`hkpd.prediction.readings.lean.mode_keypoint_misfits`; no ground truth involved) is the
better one more often than not. Keeping it took run 17 from 4.83 to 4.76 px upright and from
7.61 to 7.44 px on the any-orientation split read upright
(``docs/runs/orientation_finetune_17/mirror_and_perspective_readings.md``).

The mirror image of a proxy is its columns reversed (pixel ``u`` goes to ``S - 1 - u``: with
pixel centres at integers that is exactly NDC ``x -> -x``) with the heatmaps of left and right
keypoints, eyes and ears included, swapped (:data:`hkpd.coco_keypoints.COCO17_MIRROR_ORDER`).
Its reading maps back by the reflection ``M = diag(-1, 1, 1)`` of the camera's x axis, which is
also the body's sagittal plane: the relative rotations of left and right joints trade places
and are conjugated by ``M`` (:func:`hkpd.mirror_symmetry.reflect_rotations`), the global
rotation is conjugated by ``M`` (``M R M`` of a rotation that maps body to camera axes), and the
camera's x shift changes sign. Shape does not change.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.coco_keypoints import COCO17_MIRROR_ORDER
from hkpd.distributions import BodyDistribution
from hkpd.mirror_symmetry import BODY_MIRROR_PERMUTATION, reflect_rotations
from hkpd.prediction.readings.lean import mode_keypoint_misfits
from hkpd.proxy import NUM_KEYPOINTS
from hkpd.proxy.heatmaps import heatmap_peaks


def mirror_proxy(proxy: torch.Tensor) -> torch.Tensor:
    """The left-right mirror image of ``(B, C + 17, S, S)`` proxies: every plane's columns
    reversed, the heatmaps of left and right keypoints swapped."""
    if proxy.ndim != 4 or proxy.shape[1] < NUM_KEYPOINTS:
        raise ValueError(f"expected (B, C + {NUM_KEYPOINTS}, S, S) proxies, got "
                         f"{tuple(proxy.shape)}")  # fmt: skip
    planes = proxy.shape[1] - NUM_KEYPOINTS
    heatmaps = proxy[:, planes:][:, list(COCO17_MIRROR_ORDER)]
    return torch.cat([proxy[:, :planes], heatmaps], 1).flip(-1)


def unmirror_output(output: BodyDistribution) -> BodyDistribution:
    """A reading of mirrored proxies mapped back to the proxies' own frame (its own inverse)."""
    permutation = torch.tensor(BODY_MIRROR_PERMUTATION, device=output.F.device)
    sign = torch.tensor([1.0, -1.0, 1.0], dtype=output.camera.dtype, device=output.camera.device)
    return replace(
        output,
        F=reflect_rotations(output.F[:, permutation]),
        global_orient=reflect_rotations(output.global_orient),
        camera=output.camera * sign,
    )


class MirrorChoosingReader(torch.nn.Module):
    """``network``, reading every proxy as it is and mirrored, keeping per example the reading
    whose most likely body fits the keypoints its heatmaps show more closely.

    Both readings run as one batch of ``2 B``. An example whose heatmaps show no keypoint keeps
    the reading as it is.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` or a wrapper of one (its
            ``config`` is exposed).
        body: the body model that poses the readings (on the network's device); None: the
            shipped one, loaded when first needed.

    Attributes:
        last_mirrored: ``(B,)`` bool of the last call: which examples kept the mirrored
            reading.
        last_other: the last call's readings that were not kept (each example's other one,
            mapped to its proxy's frame); None before the first call.
    """

    def __init__(self, network: torch.nn.Module, body: BodyModel | None = None) -> None:
        super().__init__()
        self.network = network
        self.config = network.config
        self.body = body
        self.last_mirrored = np.zeros(0, dtype=bool)
        self.last_other: BodyDistribution | None = None

    def read_as(self, proxy: torch.Tensor, mirrored: np.ndarray) -> BodyDistribution:
        """The readings of ``(B, C + 17, S, S)`` proxies, each read mirrored where
        ``mirrored (B,)`` says so (a choice made before, e.g. on the photo without occluders:
        :class:`hkpd.prediction.photo_reading.PhotoReading`) and as it is elsewhere, in one
        network call of ``B``; each in its proxy's frame. Sets :attr:`last_mirrored`;
        :attr:`last_other` becomes None (the other readings are not made)."""
        take = torch.as_tensor(np.asarray(mirrored, dtype=bool), device=proxy.device)
        if take.shape != (proxy.shape[0],):
            raise ValueError(f"mirrored must have one flag per proxy, got {tuple(take.shape)}")
        flipped = torch.where(take[:, None, None, None], mirror_proxy(proxy), proxy)
        output = self.network(flipped)
        self.last_mirrored = take.cpu().numpy().copy()
        self.last_other = None
        return unmirror_output(output).where(take, output)

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        """The chosen readings of ``(B, C + 17, S, S)`` proxies, each in its proxy's frame."""
        count, size = int(proxy.shape[0]), int(proxy.shape[-1])
        both = self.network(torch.cat([proxy, mirror_proxy(proxy)]))
        as_it_is = both.rows(slice(0, count))
        mirrored = unmirror_output(both.rows(slice(count, 2 * count)))
        if self.body is None:
            self.body = BodyModel().to(proxy.device)
        peaks, present = heatmap_peaks(proxy[:, -NUM_KEYPOINTS:])
        points, shown = peaks.cpu().double().numpy(), present.cpu().numpy()
        misfits = [
            mode_keypoint_misfits(reading, self.body, size, points, shown)
            for reading in (as_it_is, mirrored)
        ]
        self.last_mirrored = misfits[1] < misfits[0]
        take = torch.as_tensor(self.last_mirrored, device=proxy.device)
        self.last_other = mirrored.where(~take, as_it_is)
        return mirrored.where(take, as_it_is)
