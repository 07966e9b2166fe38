"""hkpd.explorer: the viser web app behind ``hkpd-explore`` (see docs/explorer.md).

It lives in the top-level ``explorer/`` folder and installs as ``hkpd.explorer``.

To drive it from Python with any predictor::

    from hkpd.explorer import ExplorerApp, PredictionResult

    class MyProvider:
        def predict(self, image, occluders, evidence=True, bbox=None) -> PredictionResult:
            ...  # image (H, W, 3) uint8 RGB; occluders and bbox: (x0, y0, x1, y1) photo pixels

    app = ExplorerApp(MyProvider(), image, port=8080)   # image: (H, W, 3) uint8 RGB
    print(app.url)

In a notebook, ``show(posterior)`` returns the explorer's scene of a prediction as an object
Jupyter displays inline (``hkpd.explorer.show(predictor.predict(photo))``; ``.save(path)``
writes the page).

(``evidence``: condition on the photo's 2D keypoints, else the network alone; ``bbox``: look
for the person only inside this box, None: anywhere; see :class:`PosteriorProvider`.)

Modules: ``state`` (app state), ``worker`` (coalescing background worker), ``provider``
(the predictor protocol and the adapter to :class:`hkpd.prediction.Predictor`),
``posterior_view`` (samples, heatmap, joint axes), ``scene`` (the viser scene), ``panels``
(the GUI: one builder per section, arranged in tabs by ``panels.build_panels``), ``app``
(wiring), ``photo_geometry``, ``colour_map`` (the colourings and their colour bars),
``change_baseline`` (the change colouring's baseline per photo and person), ``upload``,
``export``, ``demo_photo`` (the shipped photo), ``demo_scene`` (the synthetic scene),
``html_page`` (a scene as one self-contained HTML page), ``saved_scene`` (pages without a live
explorer: ``hkpd-explore --export-html`` and :func:`show`) and ``cli``. Names below are imported
lazily so that ``import hkpd.explorer`` does not start viser.
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
    "show": "hkpd.explorer.saved_scene",
    "ScenePage": "hkpd.explorer.saved_scene",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'hkpd.explorer' has no attribute {name!r}")
