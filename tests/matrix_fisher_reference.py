"""Independent high-precision references for the matrix-Fisher normaliser (tests only).

These use mpmath at 30 significant digits with adaptive tanh-sinh quadrature, on a *different*
one-dimensional representation from the library's (Lee 2018's Bessel-product integral with the
roles of the singular values permuted), plus closed forms for special cases.
"""

from __future__ import annotations

import json
from pathlib import Path

import mpmath as mp


def _breakpoints(scale: mp.mpf) -> list[mp.mpf]:
    """Points on [-1, 1] that bracket boundary layers of width 1/scale at both ends."""
    points = {mp.mpf(-1), mp.mpf(0), mp.mpf(1)}
    width = 1 / scale
    while width < 1:
        points.add(-1 + width)
        points.add(1 - width)
        width *= 10
    return sorted(points)


def reference_log_c(s1: float, s2: float, s3: float, digits: int = 30) -> mp.mpf:
    """log c(diag(s1, s2, s3)) with the Haar probability measure.

    c = 1/2 int_{-1}^{1} I0((s2 - s3)(1 - u)/2) I0((s2 + s3)(1 + u)/2) exp(s1 u) du.
    """
    with mp.workdps(digits):
        a, b, c = mp.mpf(s1), mp.mpf(s2), mp.mpf(s3)

        def integrand(u: mp.mpf) -> mp.mpf:
            return (
                mp.besseli(0, (b - c) * (1 - u) / 2)
                * mp.besseli(0, (b + c) * (1 + u) / 2)
                * mp.exp(a * (u - 1))
            )

        scale = max(abs(a), abs(b), abs(c), mp.mpf(1))
        return a + mp.log(mp.quad(integrand, _breakpoints(scale)) / 2)


def reference_expected_diagonal(s1: float, s2: float, s3: float, digits: int = 30) -> list[float]:
    """d log c / d s_i by central differences of :func:`reference_log_c` at high precision."""
    with mp.workdps(digits):
        values = [mp.mpf(s1), mp.mpf(s2), mp.mpf(s3)]
        step = mp.mpf(10) ** -8 * max(1, max(abs(v) for v in values))
        result = []
        for i in range(3):
            plus = list(values)
            minus = list(values)
            plus[i] += step
            minus[i] -= step
            difference = reference_log_c(*plus, digits=digits) - reference_log_c(
                *minus, digits=digits
            )
            result.append(float(difference / (2 * step)))
        return result


def isotropic_log_c(s: float) -> mp.mpf:
    """log c(s I) = s + log(I0(2s) - I1(2s)) (Haar angle density (1 - cos t)/pi)."""
    with mp.workdps(30):
        x = mp.mpf(s)
        return x + mp.log(mp.besseli(0, 2 * x) - mp.besseli(1, 2 * x))


def rank_one_log_c(s: float) -> mp.mpf:
    """log c(diag(s, 0, 0)) = log(sinh(s) / s), since R_11 is uniform on [-1, 1] under Haar."""
    with mp.workdps(30):
        x = mp.mpf(s)
        return mp.log(mp.sinh(x) / x) if x != 0 else mp.mpf(0)


GRID_REFERENCE = Path(__file__).parent / "data" / "normalizer_reference.json"
"""The references on test_normalizer.py's points, written by running this module."""


def write_grid_reference(
    grid: list[tuple[float, float, float]],
    gradient_points: list[tuple[float, float, float]],
    path: Path,
) -> None:
    """Store ``reference_log_c`` at every point of ``grid`` (30 significant digits, as text)
    and ``reference_expected_diagonal`` at every point of ``gradient_points``.

    Computing them takes ~1.5 minutes of mpmath quadrature; the tests read the file and
    recompute a few of its points to show that it still is what these functions give.
    """  # fmt: skip
    rows = [[*point, mp.nstr(reference_log_c(*point), 30)] for point in grid]
    diagonals = [[*point, *reference_expected_diagonal(*point)] for point in gradient_points]
    lines = ",\n".join(f"  {json.dumps(row)}" for row in rows)
    gradient_lines = ",\n".join(f"  {json.dumps(row)}" for row in diagonals)
    path.write_text(
        f'{{"digits": 30, "log_c": [\n{lines}\n], "expected_diagonal": [\n{gradient_lines}\n]}}\n'
    )


def read_grid_reference(path: Path = GRID_REFERENCE) -> dict[tuple[float, float, float], mp.mpf]:
    """The stored grid: ``{(s1, s2, s3): log c}``."""
    with mp.workdps(30):
        rows = json.loads(path.read_text())["log_c"]
        return {(s1, s2, s3): mp.mpf(value) for s1, s2, s3, value in rows}


def read_gradient_reference(
    path: Path = GRID_REFERENCE,
) -> dict[tuple[float, float, float], list[float]]:
    """The stored ``d log c / d s_i``: ``{(s1, s2, s3): [three floats]}``."""
    rows = json.loads(path.read_text())["expected_diagonal"]
    return {tuple(row[:3]): list(row[3:]) for row in rows}


if __name__ == "__main__":  # python tests/matrix_fisher_reference.py: rewrite the stored grid
    from test_normalizer import GRADIENT_POINTS, GRID

    write_grid_reference(GRID, GRADIENT_POINTS, GRID_REFERENCE)
    print(f"wrote {GRID_REFERENCE} ({len(GRID)} + {len(GRADIENT_POINTS)} points)")
