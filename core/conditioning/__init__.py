"""Conditioning the network's body distribution on the photo's 2D keypoints.

The network's distribution is a *prior*; the detected keypoints are *evidence*. This package
fits the body to the evidence with the prior as regulariser (a batched Levenberg-Marquardt
solve, :mod:`hkpd.conditioning.keypoint_fit`) and turns the fit's Laplace approximation back
into the same families (per-joint matrix-Fisher, diagonal Gaussian shape,
:mod:`hkpd.conditioning.laplace`), so the rejection sampler and everything after it work
unchanged. The maths is in ``docs/evidence.md``.

It sits between the body model and prediction: it takes plain tensors (no network, no photo).
"""

from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.keypoint_evidence import KeypointEvidence
from hkpd.conditioning.keypoint_fit import (
    KeypointFit,
    condition_on_keypoints,
    fit_keypoints,
)
from hkpd.conditioning.laplace import marginal_precisions, matrix_fisher_from_precision

__all__ = [
    "EvidenceConfig",
    "KeypointEvidence",
    "KeypointFit",
    "condition_on_keypoints",
    "fit_keypoints",
    "marginal_precisions",
    "matrix_fisher_from_precision",
]
