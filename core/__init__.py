"""hkpd: probabilistic 3D human shape and pose from one photo.

The packages follow the data flow photo -> proxy -> network -> distribution -> samples ->
meshes -> view:

- :mod:`hkpd.prediction`: photo -> :class:`Predictor` -> :class:`BodyPosterior` (also
  ``hkpd-predict``).
- :mod:`hkpd.proxy`: the edge-and-heatmap proxy representation.
- :mod:`hkpd.network`: the distribution-prediction network.
- :mod:`hkpd.distributions`: matrix-Fisher distributions over joint rotations (exact normaliser,
  differentiable rejection sampler), the kinematic-tree distribution and the shape Gaussian.
- :mod:`hkpd.body`: the SMPL-format body model; :mod:`hkpd.uncertainty`: per-vertex spread.
- Training side: :mod:`hkpd.poses`, :mod:`hkpd.rendering`, :mod:`hkpd.synthesis`,
  :mod:`hkpd.training`, :mod:`hkpd.evaluation`. The browser app is :mod:`hkpd.explorer`.
"""

__version__ = "0.1.0"

__all__ = ["BodyModel", "BodyPosterior", "Predictor", "__version__"]


def __getattr__(name: str):
    """``hkpd.Predictor``, ``hkpd.BodyPosterior`` and ``hkpd.BodyModel``, imported on first use
    (the predictor pulls in torch, OpenCV and LiteRT, which ``import hkpd`` alone should not)."""
    if name in ("Predictor", "BodyPosterior"):
        from hkpd import prediction

        return getattr(prediction, name)
    if name == "BodyModel":
        from hkpd.body import BodyModel

        return BodyModel
    raise AttributeError(f"module 'hkpd' has no attribute {name!r}")
