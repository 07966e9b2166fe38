"""Evaluation: the metrics (MPJPE variants, PVE-T-SC, 2D errors, min-of-N, sample diversity) and
the `hkpd-eval` command."""
