"""The baseline of the "change" colouring: per photo and person, the posterior without occluders.

The change colouring divides each vertex's uncertainty by its uncertainty in the *baseline*:
the same photo, the same person box, evidence setting and stated body, no occluders, default
concentrations. The first prediction of every photo has no occluders, so the app records it
here (:meth:`BaselineCache.record`) and the baseline costs nothing; only when the person box or
the evidence switch changes while occluders are on does the app predict the baseline once
(:meth:`BaselineCache.posterior` with a ``predict`` callable). The baseline's uncertainty is
kept per ``(num_samples, seed)``, so dragging a concentration slider samples only the current
posterior.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hkpd.explorer.body_settings import NOTHING_STATED, BodyStatement
from hkpd.explorer.posterior_view import baseline_uncertainty
from hkpd.prediction.posterior import BodyPosterior

MAX_KEPT = 4
"""Baselines kept at most (a photo with and without evidence, two people); oldest dropped."""


@dataclass(frozen=True)
class BaselineKey:
    """Which prediction a baseline belongs to.

    Attributes:
        image_token: the app's counter of loaded photos.
        person_box: the box the person was looked for in (None: anywhere).
        evidence: conditioned on the 2D keypoints or the network alone.
        silhouette: the person mask was fitted too.
        stated: what was stated about the body (sex, measurements): a posterior predicted
            with other stated values is another person's body, never this key's.
        turned: the turned-around reading (*Turn around*).
    """

    image_token: int
    person_box: tuple[float, float, float, float] | None
    evidence: bool
    silhouette: bool = False
    stated: BodyStatement = NOTHING_STATED
    turned: bool = False


class BaselineCache:
    """Thread-safe store of baseline posteriors and their per-vertex uncertainties."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._posteriors: dict[BaselineKey, BodyPosterior] = {}
        self._uncertainty: dict[tuple[BaselineKey, int, int], np.ndarray] = {}

    def record(self, key: BaselineKey, posterior: BodyPosterior) -> None:
        """Keep ``posterior`` (predicted without occluders) as the baseline of ``key``."""
        with self._lock:
            if self._posteriors.get(key) is posterior:
                return
            self._posteriors.pop(key, None)
            self._posteriors[key] = posterior
            self._uncertainty = {k: v for k, v in self._uncertainty.items() if k[0] != key}
            while len(self._posteriors) > MAX_KEPT:
                oldest = next(iter(self._posteriors))
                del self._posteriors[oldest]
                self._uncertainty = {k: v for k, v in self._uncertainty.items() if k[0] != oldest}

    def posterior(
        self, key: BaselineKey, predict: Callable[[], BodyPosterior] | None = None
    ) -> BodyPosterior | None:
        """The baseline of ``key``; predicted with ``predict`` (and kept) when missing, None
        when missing and no ``predict`` is given."""
        with self._lock:
            found = self._posteriors.get(key)
        if found is not None or predict is None:
            return found
        posterior = predict()
        self.record(key, posterior)
        return posterior

    def uncertainty(self, key: BaselineKey, num_samples: int, seed: int) -> np.ndarray | None:
        """``(V,)`` metres: the baseline's per-vertex uncertainty over ``num_samples`` samples
        drawn with ``seed`` (computed once per key, count and seed); None without a baseline."""
        with self._lock:
            posterior = self._posteriors.get(key)
            found = self._uncertainty.get((key, num_samples, seed))
        if posterior is None or found is not None:
            return found
        values = baseline_uncertainty(posterior, num_samples, seed)
        with self._lock:
            if self._posteriors.get(key) is posterior:
                self._uncertainty[(key, num_samples, seed)] = values
        return values
