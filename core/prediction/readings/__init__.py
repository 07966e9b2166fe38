"""How the network reads a crop: as it is, mirrored, from an upright copy, at the lean that fits.

- :mod:`~hkpd.prediction.readings.stage`: :class:`ReadingStage` composes the readings below for
  photos (:class:`hkpd.prediction.Predictor`) and ready-made proxies alike; :class:`ReadingConfig`
  switches them.
- :mod:`~hkpd.prediction.readings.mirror`: the left-right mirror reading, kept when its body fits
  the shown keypoints better.
- :mod:`~hkpd.prediction.readings.upright_view`: the upright copy of a leaning person's crop and
  the exact map of its reading back to the crop.
- :mod:`~hkpd.prediction.readings.lean`: the lean to read a view at when it shows no torso.
- :mod:`~hkpd.prediction.readings.proxy_reader`: the stage as a network-like module over proxies
  (what ``hkpd-eval`` and the experiments read synthetic test sets with).

A new reading is added as a step of :class:`ReadingStage` with its switch in
:class:`ReadingConfig` (``docs/architecture.md``).
"""

from hkpd.prediction.readings.stage import (
    LEAN_SEARCH_BATCH,
    ReadingConfig,
    ReadingInput,
    Readings,
    ReadingStage,
    TurnedProxy,
)

__all__ = [
    "LEAN_SEARCH_BATCH",
    "ReadingConfig",
    "ReadingInput",
    "ReadingStage",
    "Readings",
    "TurnedProxy",
]
