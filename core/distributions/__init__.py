"""Probability distributions over body pose (rotations) and shape.

- :class:`MatrixFisher`: matrix-Fisher distribution on SO(3), with an exact normaliser and the
  paper's differentiable rejection sampler (Algorithm 1).
- :class:`KinematicMatrixFisher`: per-joint matrix-Fisher distributions over a kinematic tree.
- :func:`body_shape_distribution`: diagonal Gaussian over shape coefficients.
- :class:`BodyDistribution`: the record of a whole body distribution (pose F, shape Gaussian,
  global rotation, camera) that the network predicts, the fit refines and a posterior wraps.
"""

from hkpd.distributions.bingham_sampler import kent_optimal_b, sample_bingham
from hkpd.distributions.body_distribution import BodyDistribution
from hkpd.distributions.body_shape import body_shape_distribution
from hkpd.distributions.kinematic_matrix_fisher import KinematicMatrixFisher
from hkpd.distributions.matrix_fisher import MatrixFisher
from hkpd.distributions.normalizer import (
    log_normalizer_and_expectation,
    matrix_fisher_log_normalizer,
)
from hkpd.distributions.proper_svd import proper_svd
from hkpd.kinematic_tree import compose_global_rotations  # re-exported: it used to live here

__all__ = [
    "BodyDistribution",
    "KinematicMatrixFisher",
    "MatrixFisher",
    "body_shape_distribution",
    "compose_global_rotations",
    "kent_optimal_b",
    "log_normalizer_and_expectation",
    "matrix_fisher_log_normalizer",
    "proper_svd",
    "sample_bingham",
]
