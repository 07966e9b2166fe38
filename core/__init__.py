"""hkpd: probabilistic 3D human shape and pose from one photo.

The packages follow the data flow photo -> 2D keypoints and crop -> proxy -> network ->
distribution (the prior) -> conditioned on the photo's keypoints (the posterior) -> samples ->
meshes -> view:

- :mod:`hkpd.prediction`: photo -> BlazePose keypoints, crop -> network (read as it is,
  mirrored, upright) -> conditioning -> :class:`BodyPosterior`, through :class:`Predictor`
  (also ``hkpd-predict``).
- :mod:`hkpd.proxy`: the edge-and-heatmap proxy representation.
- :mod:`hkpd.network`: the distribution-prediction network.
- :mod:`hkpd.conditioning`: the network's distribution conditioned on the confident 2D
  keypoints (a robust fit, then a Laplace step back to the same families).
- :mod:`hkpd.distributions`: matrix-Fisher distributions over joint rotations (exact normaliser,
  differentiable rejection sampler), the kinematic-tree distribution, the shape Gaussian and
  :class:`~hkpd.distributions.BodyDistribution`, the record that carries them.
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
