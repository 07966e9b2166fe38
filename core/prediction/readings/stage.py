"""The reading stage: how the network reads a crop (as it is, mirrored, upright, lean search).

One implementation for photos (:class:`hkpd.prediction.Predictor`) and for proxies that are
already made (the synthetic test sets: :class:`hkpd.prediction.readings.proxy_reader.ProxyReader`):

1. **Mirror reading** (:attr:`ReadingConfig.mirror`): every proxy is read as it is and as its
   left-right mirror image, and the reading whose most likely body fits the shown keypoints
   more closely is kept (:class:`hkpd.prediction.readings.mirror.MirrorChoosingReader`).
2. **Upright copy**: an example whose shown torso leans more than
   :attr:`ReadingConfig.upright_start_degrees` from upright
   (:func:`hkpd.prediction.readings.upright_view.torso_tilt`) is also read from a copy turned
   upright (:class:`hkpd.prediction.readings.upright_view.UprightView`), and that reading is
   mapped back to the crop's frame.
3. **Lean search** (:attr:`ReadingConfig.lean_search`): an example whose shown keypoints show
   no torso is read at every lean of :data:`hkpd.prediction.readings.lean.LEAN_CANDIDATES_DEGREES`
   and at the lean of its own reading; the turned reading whose body fits the shown keypoints
   best is its upright copy, if it fits them
   :data:`~hkpd.prediction.readings.lean.TURNED_FIT_MARGIN` closer than the reading as it is
   (:mod:`hkpd.prediction.readings.lean`).

The stage does not know where proxies come from: the caller gives a :class:`TurnedProxy`, the
proxy of an example seen through a view (for photos found again on the turned RGB crop, for
ready-made proxies by warping their image planes). Copies are framed as the crop was, on
:attr:`ReadingInput.framing` when the caller knows what the crop was framed on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.distributions import BodyDistribution
from hkpd.prediction.readings.lean import (
    LEAN_CANDIDATES_DEGREES,
    TURNED_FIT_MARGIN,
    mode_keypoint_misfits,
    mode_torso_tilts,
)
from hkpd.prediction.readings.mirror import MirrorChoosingReader
from hkpd.prediction.readings.upright_view import UprightView, torso_tilt

LEAN_SEARCH_BATCH = 32
"""Turned copies read per network call in the lean search (a photo's 11-12 candidates: one)."""


@dataclass(frozen=True)
class ReadingConfig:
    """How the network reads its input (:mod:`hkpd.prediction.readings`).

    Attributes:
        upright_start_degrees: an example whose shown torso leans more than this from upright
            is (also) read from a copy turned upright.
        mirror: read every proxy as it is and mirrored, keeping the reading whose most likely
            body fits the shown keypoints more closely; False reads each once.
        lean_search: for examples whose shown keypoints show no torso, search the lean to read
            them at (:mod:`hkpd.prediction.readings.lean`); False reads them as they are.
    """

    upright_start_degrees: float = 30.0
    mirror: bool = True
    lean_search: bool = True

    def __post_init__(self) -> None:
        if not 0.0 <= self.upright_start_degrees <= 180.0:
            raise ValueError(
                "ReadingConfig.upright_start_degrees must lie in [0, 180], got "
                f"{self.upright_start_degrees}"
            )

    @property
    def upright_start(self) -> float:
        """:attr:`upright_start_degrees` in radians."""
        return math.radians(self.upright_start_degrees)


class TurnedProxy(Protocol):
    """Makes the proxy of one example seen through a view."""

    def __call__(self, example: int, view: UprightView) -> torch.Tensor:
        """The ``(C + 17, S, S)`` proxy of example ``example`` turned by ``view`` (any device)."""
        ...


@dataclass(frozen=True)
class ReadingInput:
    """B examples as the reading stage takes them.

    Attributes:
        proxy: ``(B, C + 17, S, S)`` proxies, on the network's device.
        keypoints: ``(B, 17, 2)`` float64 crop pixels: the keypoints the proxies show (the
            evidence; where absent, anything finite).
        shown: ``(B, 17)`` bool, which of them are shown.
        turned_proxy: makes an example's upright copy.
        framing: ``(B, 17, 2)`` float64 crop pixels: the keypoints each crop was framed on; the
            upright copies are framed on them, as the crops were. None: on the shown keypoints.
    """

    proxy: torch.Tensor
    keypoints: np.ndarray
    shown: np.ndarray
    turned_proxy: TurnedProxy
    framing: np.ndarray | None = None

    @property
    def count(self) -> int:
        """B."""
        return int(self.proxy.shape[0])

    @property
    def size(self) -> int:
        """S, the crop side in pixels."""
        return int(self.proxy.shape[-1])

    def view(self, example: int, tilt: float) -> UprightView:
        """The upright copy of ``example`` undoing ``tilt`` radians, framed on its
        :attr:`framing` keypoints when known, else on its shown ones."""
        if self.framing is None:
            keypoints, shown = self.keypoints[example], self.shown[example]
            return UprightView.from_tilt(tilt, keypoints, self.size, shown)
        return UprightView.from_tilt(tilt, self.framing[example], self.size)


@dataclass(frozen=True)
class Readings:
    """What the network read for B examples: R readings (R >= B), one per row of its call.

    Attributes:
        distribution: ``(R,)`` the readings, each mapped to its example's crop frame.
        views: ``B`` entries: the upright copy each example was read from (None: as it is).
        row_views: ``R`` entries: the view each reading read (None: the proxy as it is).
        chosen_rows: ``B`` entries: the row of each example's chosen reading (its upright
            copy's when it has one).
        mirrored: ``(R,)`` bool, which readings came from the mirror image.
    """

    distribution: BodyDistribution
    views: tuple[UprightView | None, ...]
    row_views: tuple[UprightView | None, ...]
    chosen_rows: tuple[int, ...]
    mirrored: np.ndarray

    def chosen(self) -> BodyDistribution:
        """``(B,)`` each example's chosen reading."""
        if self.chosen_rows == tuple(range(len(self.row_views))):
            return self.distribution
        return self.distribution.rows(torch.tensor(self.chosen_rows))

    @property
    def tilts_degrees(self) -> np.ndarray:
        """``(B,)`` float64: the lean each example's upright copy undid, degrees (NaN: read as
        it is)."""
        return np.array([math.nan if v is None else math.degrees(v.tilt) for v in self.views])


class ReadingStage:
    """The network and the ways of reading with it (see the module docstring).

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` or a wrapper of one (its
            ``config`` is exposed).
        body: the body model that poses readings to compare them (on the network's device);
            None: the shipped one, loaded when first needed.
        config: the reading settings.

    Attributes:
        network: what reads a batch of proxies: ``network``, wrapped in a
            :class:`MirrorChoosingReader` when ``config.mirror``.
    """

    def __init__(
        self,
        network: torch.nn.Module,
        body: BodyModel | None = None,
        config: ReadingConfig | None = None,
    ) -> None:
        self.config = config or ReadingConfig()
        self.body = body
        self.network = MirrorChoosingReader(network, body) if self.config.mirror else network

    def read(
        self, batch: ReadingInput, *, upright: bool = True, keep_as_it_is: bool = False
    ) -> Readings:
        """The network's readings of ``batch``.

        Args:
            batch: the examples.
            upright: read leaning examples (and, with the lean search, torso-less ones) from
                upright copies; False reads every example as it is.
            keep_as_it_is: also keep the reading as it is of examples read from an upright
                copy (the copies are read in the same call, after the B proxies); False reads
                each example once.
        """
        views = self.upright_views(batch) if upright else [None] * batch.count
        return self.read_views(batch, views, keep_as_it_is)

    def upright_views(self, batch: ReadingInput) -> list[UprightView | None]:
        """Per example, the upright copy to read it from (None: as it is)."""
        views: list[UprightView | None] = [None] * batch.count
        torsoless = []
        for example in range(batch.count):
            tilt = torso_tilt(batch.keypoints[example], batch.shown[example])
            if tilt is None:
                torsoless.append(example)
            elif abs(tilt) > self.config.upright_start:
                views[example] = batch.view(example, tilt)
        if torsoless and self.config.lean_search:
            for example, view in self._searched_views(batch, torsoless).items():
                views[example] = view
        return views

    def read_views(
        self,
        batch: ReadingInput,
        views: list[UprightView | None],
        keep_as_it_is: bool = False,
        mirrored: np.ndarray | None = None,
    ) -> Readings:
        """The readings of ``batch``, example ``i`` from ``views[i]`` (None: as it is), in one
        network call (``keep_as_it_is``: as for :meth:`read`). ``mirrored``: ``(R,)`` bool per
        row of that call, the mirror choice already made (``Readings.mirrored`` of an earlier
        reading with the same views); each row is then read once, that way (None: chosen
        here, when the stage reads mirrored)."""
        turned = [(example, view) for example, view in enumerate(views) if view is not None]
        count = batch.count
        if not turned:
            proxies, row_views, chosen = batch.proxy, list(views), list(range(count))
        elif keep_as_it_is:
            proxies = torch.cat([batch.proxy, self._turned_proxies(batch, turned)])
            row_views = [None] * count + [view for _, view in turned]
            chosen = list(range(count))
            for row, (example, _) in enumerate(turned, start=count):
                chosen[example] = row
        else:
            proxies = batch.proxy.clone()
            for example, view in turned:
                proxies[example] = batch.turned_proxy(example, view).to(proxies.device)
            row_views, chosen = list(views), list(range(count))
        output = _in_crop_frames(self._network_output(proxies, mirrored), row_views)
        mirrored = self._last_mirrored(len(row_views))
        return Readings(output, tuple(views), tuple(row_views), tuple(chosen), mirrored)

    def _network_output(
        self, proxies: torch.Tensor, mirrored: np.ndarray | None
    ) -> BodyDistribution:
        """The network's readings of ``proxies``, mirrored as ``mirrored`` says when given."""
        if mirrored is None or not isinstance(self.network, MirrorChoosingReader):
            return self.network(proxies)
        return self.network.read_as(proxies, mirrored)

    def _turned_proxies(
        self, batch: ReadingInput, turned: list[tuple[int, UprightView]]
    ) -> torch.Tensor:
        """``(T, C + 17, S, S)`` the upright copies of ``(example, view)`` pairs."""
        proxies = [batch.turned_proxy(example, view) for example, view in turned]
        return torch.stack(proxies).to(batch.proxy.device)

    def _last_mirrored(self, count: int) -> np.ndarray:
        """``(count,)`` bool: which readings of the last network call came from the mirror."""
        if isinstance(self.network, MirrorChoosingReader):
            return np.asarray(self.network.last_mirrored, dtype=bool).copy()
        return np.zeros(count, dtype=bool)

    def _body(self, device: torch.device) -> BodyModel:
        if self.body is None:
            self.body = BodyModel().to(device)
        return self.body

    def _searched_views(self, batch: ReadingInput, examples: list[int]) -> dict[int, UprightView]:
        """The lean search for ``examples`` (their shown keypoints show no torso): each read as
        it is, at every lean of :data:`LEAN_CANDIDATES_DEGREES` and at the lean of its own
        reading (when beyond the upright start); the view whose reading's most likely body
        fits the shown keypoints best, where it fits them :data:`TURNED_FIT_MARGIN` closer
        than the reading as it is."""
        body, size = self._body(batch.proxy.device), batch.size
        as_it_is = self.network(batch.proxy[examples])
        keypoints, shown = batch.keypoints[examples], batch.shown[examples]
        baseline = mode_keypoint_misfits(as_it_is, body, size, keypoints, shown)
        candidates: list[tuple[int, UprightView]] = []
        for example, own_lean in zip(examples, mode_torso_tilts(as_it_is, body, size), strict=True):
            leans = [math.radians(degrees) for degrees in LEAN_CANDIDATES_DEGREES]
            if own_lean is not None and abs(own_lean) > self.config.upright_start:
                leans.append(own_lean)
            candidates += [(example, batch.view(example, lean)) for lean in leans]
        misfits = np.concatenate(
            [
                self._candidate_misfits(batch, candidates[start : start + LEAN_SEARCH_BATCH])
                for start in range(0, len(candidates), LEAN_SEARCH_BATCH)
            ]
        )
        chosen = {}
        for index, example in enumerate(examples):
            rows = [row for row, (owner, _) in enumerate(candidates) if owner == example]
            best = rows[int(np.argmin(misfits[rows]))]  # the first of equal fits
            if misfits[best] < (1.0 - TURNED_FIT_MARGIN) * baseline[index]:
                chosen[example] = candidates[best][1]
        return chosen

    def _candidate_misfits(
        self, batch: ReadingInput, candidates: list[tuple[int, UprightView]]
    ) -> np.ndarray:
        """``(N,)`` how far the reading of each ``(example, view)`` copy, mapped back, projects
        from the example's shown keypoints (crop pixels)."""
        output = self.network(self._turned_proxies(batch, candidates))
        output = _in_crop_frames(output, [view for _, view in candidates])
        owners = [example for example, _ in candidates]
        body = self._body(batch.proxy.device)
        keypoints, shown = batch.keypoints[owners], batch.shown[owners]
        return mode_keypoint_misfits(output, body, batch.size, keypoints, shown)


def _in_crop_frames(output: BodyDistribution, views: list[UprightView | None]) -> BodyDistribution:
    """``output`` with the global rotation and camera of each row read through a view mapped
    back to its crop's frame (on the CPU; relative rotations and shape do not depend on the
    view)."""
    if all(view is None for view in views):
        return output
    orient, camera = output.global_orient.clone(), output.camera.clone()
    for row, view in enumerate(views):
        if view is not None:
            row_orient, row_camera = view.to_crop_frame(orient[row].cpu(), camera[row].cpu())
            orient[row], camera[row] = row_orient.to(orient.device), row_camera.to(camera.device)
    return replace(output, global_orient=orient, camera=camera)
