"""Accuracy of log c(F) and its gradient against independent high-precision references."""

from __future__ import annotations

import itertools

import mpmath as mp
import pytest
import torch
from matrix_fisher_reference import (
    isotropic_log_c,
    rank_one_log_c,
    read_gradient_reference,
    read_grid_reference,
    reference_expected_diagonal,
    reference_log_c,
)

from hkpd.distributions import (
    MatrixFisher,
    log_normalizer_and_expectation,
    matrix_fisher_log_normalizer,
)

MAGNITUDES = [1e-6, 1e-3, 9e-3, 0.011, 0.3, 1.0, 4.0, 30.0, 100.0, 1e3, 1e4, 1e5]
# Proper singular value patterns (s1 >= s2 >= |s3|), scaled by the magnitude.
PATTERNS = [
    (1.0, 1.0, 1.0),
    (1.0, 1.0, -1.0),
    (1.0, 0.0, 0.0),
    (1.0, 1.0, 0.0),
    (1.0, 0.5, -0.25),
    (1.0, 0.7, 0.2),
    (1.0, 1.0 - 1e-6, 1.0 - 2e-6),
    (1.0, 1.0 - 1e-9, -(1.0 - 1e-9)),
    (1.0, 0.3, -0.3),
]
GRID = [tuple(m * p for p in pattern) for m, pattern in itertools.product(MAGNITUDES, PATTERNS)]
GRADIENT_POINTS = [
    (0.02, 0.01, -0.005),
    (0.8, 0.3, 0.1),
    (3.0, 3.0, -3.0),
    (25.0, 10.0, -2.0),
    (150.0, 150.0, 149.999),
    (1e3, 20.0, 5.0),
    (1e4, 1e4, -1e4),
    (1e4, 5e3, 1e3),
    (1e4, 0.0, 0.0),
]


def relative_error(value: float, reference: mp.mpf) -> float:
    if reference == 0:
        return abs(value)
    return float(abs((mp.mpf(value) - reference) / reference))


def test_log_normalizer_matches_reference_over_grid() -> None:
    # The mpmath reference over the grid is stored (a minute of quadrature; see the next test).
    stored = read_grid_reference()
    assert list(stored) == GRID, "the grid changed: run python tests/matrix_fisher_reference.py"
    S = torch.tensor(GRID, dtype=torch.float64)
    log_c = matrix_fisher_log_normalizer(S)
    errors = [relative_error(float(v), stored[s]) for v, s in zip(log_c, GRID, strict=True)]
    worst = max(range(len(GRID)), key=errors.__getitem__)
    assert errors[worst] <= 1e-6, f"relative error {errors[worst]:.2e} at S={GRID[worst]}"


@pytest.mark.parametrize("index", [22, 61, 98])  # magnitudes 9e-3, 4 and 1e4
def test_the_stored_grid_reference_is_the_reference(index: int) -> None:
    point = GRID[index]
    with mp.workdps(30):
        assert abs(read_grid_reference()[point] / reference_log_c(*point) - 1) < 1e-20


def test_zero_concentration_is_uniform() -> None:
    log_c = matrix_fisher_log_normalizer(torch.zeros(3, dtype=torch.float64))
    assert float(log_c) == 0.0


@pytest.mark.parametrize("s", [1e-4, 0.05, 1.0, 10.0, 300.0, 1e4, 1e5])
def test_isotropic_closed_form(s: float) -> None:
    value = float(matrix_fisher_log_normalizer(torch.full((3,), s, dtype=torch.float64)))
    assert relative_error(value, isotropic_log_c(s)) <= 1e-6


@pytest.mark.parametrize("s", [1e-3, 0.5, 7.0, 200.0, 5e4])
def test_rank_one_closed_form(s: float) -> None:
    value = float(matrix_fisher_log_normalizer(torch.tensor([s, 0.0, 0.0], dtype=torch.float64)))
    assert relative_error(value, rank_one_log_c(s)) <= 1e-6


@pytest.mark.parametrize("S", GRADIENT_POINTS)
def test_gradient_matches_reference(S: tuple[float, float, float]) -> None:
    _, expected = log_normalizer_and_expectation(torch.tensor(S, dtype=torch.float64))
    reference = read_gradient_reference()[S]  # stored: see the next test
    assert torch.allclose(expected, torch.tensor(reference, dtype=torch.float64), atol=1e-8, rtol=0)


@pytest.mark.parametrize("index", [3, 8])  # (25, 10, -2) and (1e4, 0, 0)
def test_the_stored_gradient_reference_is_the_reference(index: int) -> None:
    point = GRADIENT_POINTS[index]
    stored = read_gradient_reference()[point]
    assert (
        max(abs(a - b) for a, b in zip(stored, reference_expected_diagonal(*point), strict=True))
        < 1e-14
    )


def test_gradient_with_respect_to_F_passes_gradcheck() -> None:
    torch.manual_seed(0)
    for scale in (0.5, 3.0, 40.0):
        F = (scale * torch.randn(4, 3, 3, dtype=torch.float64)).requires_grad_()
        assert torch.autograd.gradcheck(lambda f: MatrixFisher(f).log_normalizer, (F,))


def test_log_prob_passes_gradcheck() -> None:
    torch.manual_seed(1)
    F = (2.0 * torch.randn(3, 3, 3, dtype=torch.float64)).requires_grad_()
    R = MatrixFisher(torch.randn(3, 3, 3, dtype=torch.float64)).sample()
    assert torch.autograd.gradcheck(lambda f: MatrixFisher(f).log_prob(R), (F,))


def test_float32_is_finite_and_close_to_float64() -> None:
    torch.manual_seed(2)
    F64 = (
        torch.randn(64, 3, 3, dtype=torch.float64)
        * torch.logspace(-3, 5, 64, dtype=torch.float64)[:, None, None]
    )
    log_c64 = MatrixFisher(F64).log_normalizer
    F32 = F64.float().requires_grad_()
    log_c32 = MatrixFisher(F32).log_normalizer
    log_c32.sum().backward()
    assert torch.isfinite(log_c32).all() and torch.isfinite(F32.grad).all()
    assert torch.allclose(log_c32.double(), log_c64, rtol=1e-5, atol=1e-6)


def test_expected_diagonal_limits() -> None:
    _, at_zero = log_normalizer_and_expectation(torch.zeros(3, dtype=torch.float64))
    assert torch.allclose(at_zero, torch.zeros(3, dtype=torch.float64), atol=1e-12)
    _, concentrated = log_normalizer_and_expectation(torch.full((3,), 1e5, dtype=torch.float64))
    # E[Q_ii] -> 1 - 1/(2 s) for large isotropic s: the mean approaches the mode.
    assert torch.allclose(
        concentrated, torch.full((3,), 1 - 1 / 2e5, dtype=torch.float64), atol=1e-8
    )


@pytest.mark.parametrize("s", [2e5, 1e6, 1e7, 1e8, 1e12])
def test_isotropic_closed_form_holds_at_very_high_concentration(s: float) -> None:
    """The hands reach ~1e8: log c must stay exact there (the quadrature alone lost 1.8e-3
    nats at 1e7 and 6e-2 at 1e12)."""
    value = matrix_fisher_log_normalizer(torch.full((3,), s, dtype=torch.float64))
    exact = isotropic_log_c(s)
    assert abs(float(mp.mpf(float(value)) - exact)) < 1e-5 * max(1.0, s * 1e-10)
    _, expected = log_normalizer_and_expectation(torch.full((3,), s, dtype=torch.float64))
    torch.testing.assert_close(expected, torch.full((3,), 1 - 1 / (2 * s), dtype=torch.float64))
