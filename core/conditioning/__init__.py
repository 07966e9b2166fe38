"""Conditioning the network's body distribution on the photo's evidence (2D keypoints, a mask).

The network's distribution is a *prior*; the detected keypoints are *evidence*. This package
fits the body to the evidence with the prior as regulariser (a batched Levenberg-Marquardt
solve, :mod:`hkpd.conditioning.keypoint_fit`) and turns the fit's Laplace approximation back
into the same families (per-joint matrix-Fisher, diagonal Gaussian shape,
:mod:`hkpd.conditioning.laplace`), so the rejection sampler and everything after it work
unchanged. The evidence is a list of :class:`EvidenceTerm` (the keypoints' :class:`KeypointTerm`,
the person's mask's :class:`SilhouetteTerm`), so a new kind of evidence plugs in without
touching the solver or the Laplace step. The maths is in ``docs/evidence.md``.

It sits between the body model and prediction: it takes plain tensors (no network, no photo).
"""

from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.evidence_term import EvidenceTerm, PosedBodies
from hkpd.conditioning.facing import faces_camera, half_turned
from hkpd.conditioning.keypoint_evidence import KeypointEvidence
from hkpd.conditioning.keypoint_fit import (
    KeypointFit,
    condition_on_keypoints,
    fit_evidence,
)
from hkpd.conditioning.keypoint_term import KeypointTerm
from hkpd.conditioning.laplace import marginal_precisions, matrix_fisher_from_precision
from hkpd.conditioning.shape_prior import (
    ShapeGaussian,
    conditioned_on_measurements,
    rebased_on_population,
)
from hkpd.conditioning.silhouette_term import (
    SilhouetteConfig,
    SilhouetteEvidence,
    SilhouetteTerm,
)
from hkpd.conditioning.surface_points import SurfaceSamples
from hkpd.stated_body import StatedBody

__all__ = [
    "EvidenceConfig",
    "EvidenceTerm",
    "KeypointEvidence",
    "KeypointFit",
    "KeypointTerm",
    "PosedBodies",
    "ShapeGaussian",
    "SilhouetteConfig",
    "SilhouetteEvidence",
    "SilhouetteTerm",
    "StatedBody",
    "SurfaceSamples",
    "condition_on_keypoints",
    "conditioned_on_measurements",
    "faces_camera",
    "fit_evidence",
    "half_turned",
    "marginal_precisions",
    "matrix_fisher_from_precision",
    "rebased_on_population",
]
