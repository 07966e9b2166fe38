"""hkpd.explorer: the viser web app behind ``hkpd-explore`` (see docs/explorer.md).

It lives in the top-level ``explorer/`` folder and installs as ``hkpd.explorer``.

To drive it from Python with any predictor::

    from hkpd.explorer import ExplorerApp, PredictionResult

    class MyProvider:
        def predict(self, image, occluders) -> PredictionResult: ...

    app = ExplorerApp(MyProvider(), image, port=8080)   # image: (H, W, 3) uint8 RGB
    print(app.url)

Modules: ``state`` (app state), ``worker`` (coalescing background worker), ``provider``
(the predictor protocol and the adapter to :class:`hkpd.prediction.Predictor`),
``posterior_view`` (samples, heatmap, joint axes), ``scene`` and ``panels`` (viser scene and
GUI), ``app`` (wiring), ``photo_geometry``, ``colour_map``, ``upload``, ``export``,
``demo_scene`` and ``cli``. Names below are imported lazily so that ``import hkpd.explorer``
does not start viser.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "ExplorerApp": "hkpd.explorer.app",
    "ExplorerState": "hkpd.explorer.state",
    "Occluder": "hkpd.explorer.state",
    "CoalescingWorker": "hkpd.explorer.worker",
    "PosteriorProvider": "hkpd.explorer.provider",
    "PredictionResult": "hkpd.explorer.provider",
    "PredictorProvider": "hkpd.explorer.provider",
    "PosteriorView": "hkpd.explorer.posterior_view",
    "compute_view": "hkpd.explorer.posterior_view",
    "render_demo_scene": "hkpd.explorer.demo_scene",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'hkpd.explorer' has no attribute {name!r}")
