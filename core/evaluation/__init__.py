"""Evaluation: the metrics (MPJPE variants, PVE-T-SC, 2D errors, min-of-N, sample diversity) and
the `hkpd-eval` command.

Experiments build on :mod:`hkpd.evaluation.test_set` (a checkpoint's network and the fixed
synthetic test set) and read the network through :class:`hkpd.prediction.readings.proxy_reader.
ProxyReader`, as ``hkpd-eval`` does.

Metric functions return per-example values: metres for 3D metrics (times
:data:`MILLIMETRES_PER_METRE` for the paper's tables), pixels for 2D errors.
"""

from hkpd.alignment import (
    least_squares_scale_align,
    procrustes_align,
    rms_scale_align,
    root_align,
)
from hkpd.evaluation.metrics import (
    MILLIMETRES_PER_METRE,
    MIN_OF_N_COUNTS,
    joint_error_2d,
    min_of_n,
    mpjpe,
    mpjpe_procrustes,
    mpjpe_scale_corrected,
    per_joint_spread,
    pve_t_sc,
    pve_t_sc_from_betas,
    sample_diversity,
)
from hkpd.evaluation.prediction_metrics import EvaluationTargets, evaluate_prediction

__all__ = [
    "MILLIMETRES_PER_METRE",
    "MIN_OF_N_COUNTS",
    "EvaluationTargets",
    "evaluate_prediction",
    "joint_error_2d",
    "least_squares_scale_align",
    "min_of_n",
    "mpjpe",
    "mpjpe_procrustes",
    "mpjpe_scale_corrected",
    "per_joint_spread",
    "procrustes_align",
    "pve_t_sc",
    "pve_t_sc_from_betas",
    "rms_scale_align",
    "root_align",
    "sample_diversity",
]
