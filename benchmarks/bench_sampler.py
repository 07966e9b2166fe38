"""Benchmark the matrix-Fisher rejection sampler and log-normaliser on this machine's CPU.

Prints markdown tables (paste them into docs/benchmarks.md):

1. rotation samples per second for B images x 23 joints x K samples, float32, for several
   concentration scales; "steady" samples from an already-built distribution (its SVD and
   proposal parameters cached), "end to end" builds the distribution from F each call;
2. log-normaliser evaluations per second at B x 23 (float32 in, float64 quadrature inside);
3. accuracy of log c against the mpmath reference (when mpmath is installed).

Usage: python benchmarks/bench_sampler.py [--batch 8] [--samples 100] [--threads 2]
"""

from __future__ import annotations

import argparse
import platform

import torch
from timing import median_and_best

from hkpd.distributions import KinematicMatrixFisher, MatrixFisher
from hkpd.kinematic_tree import BODY_PARENTS


def sampler_table(batch: int, samples: int, repeats: int) -> list[str]:
    rows = [
        "| concentration scale of F | steady samples/s, median (best) "
        "| end-to-end samples/s, median (best) | mean acceptance | min expected acceptance |",
        "|---|---|---|---|---|",
    ]
    per_call = batch * len(BODY_PARENTS) * samples
    generator = torch.Generator().manual_seed(0)
    for scale in (0.0, 1.0, 10.0, 100.0, 1000.0):
        F = scale * torch.randn(batch, len(BODY_PARENTS), 3, 3, generator=generator)
        built = KinematicMatrixFisher(F, BODY_PARENTS)
        steady = median_and_best(lambda built=built: built.sample(samples), repeats, warmups=2)
        end_to_end = median_and_best(
            lambda F=F: KinematicMatrixFisher(F, BODY_PARENTS).sample(samples), repeats, warmups=2
        )
        acceptance = float(built.last_acceptance_rate.mean())
        expected = float(built.joints.expected_acceptance_rate.min())
        steady_text = f"{per_call / steady[0] / 1e6:.2f} M ({per_call / steady[1] / 1e6:.2f} M)"
        e2e_text = (
            f"{per_call / end_to_end[0] / 1e6:.2f} M ({per_call / end_to_end[1] / 1e6:.2f} M)"
        )
        rows.append(
            f"| {scale:g} | {steady_text} | {e2e_text} | {acceptance:.3f} | {expected:.3f} |"
        )
    # For comparison: the same work as one small sampling call per distribution.
    F = 10.0 * torch.randn(batch * len(BODY_PARENTS), 3, 3, generator=generator)
    loop = median_and_best(
        lambda: [MatrixFisher(f).sample((samples,)) for f in F], max(3, repeats // 20), warmups=2
    )
    rows.append(
        f"| 10, naive loop: one call per distribution | - | {per_call / loop[0] / 1e6:.2f} M "
        f"({per_call / loop[1] / 1e6:.2f} M) | - | - |"
    )
    return rows


def normalizer_table(batch: int, repeats: int) -> list[str]:
    rows = [
        "| input | evaluations/s, median (best) | median time per call |",
        "|---|---|---|",
    ]
    generator = torch.Generator().manual_seed(1)
    for dtype in (torch.float32, torch.float64):
        F = 50.0 * torch.randn(batch, len(BODY_PARENTS), 3, 3, generator=generator, dtype=dtype)
        seconds, best = median_and_best(
            lambda F=F: MatrixFisher(F).log_normalizer, repeats, warmups=2
        )
        count = batch * len(BODY_PARENTS)
        rows.append(
            f"| F {str(dtype).replace('torch.', '')}, with SVD | {count / seconds / 1e3:.0f} k "
            f"({count / best / 1e3:.0f} k) | {seconds * 1e3:.2f} ms |"
        )
    return rows


def accuracy_table() -> list[str]:
    try:
        import mpmath as mp
    except ImportError:
        return ["(mpmath not installed: accuracy table skipped)"]
    from hkpd.distributions import matrix_fisher_log_normalizer

    def reference(s: tuple[float, float, float]) -> mp.mpf:
        with mp.workdps(30):
            a, b, c = (mp.mpf(v) for v in s)
            points = {mp.mpf(-1), mp.mpf(0), mp.mpf(1)}
            width = 1 / max(abs(a), abs(b), abs(c), mp.mpf(1))
            while width < 1:
                points |= {-1 + width, 1 - width}
                width *= 10

            def integrand(u: mp.mpf) -> mp.mpf:
                return (
                    mp.besseli(0, (b - c) * (1 - u) / 2)
                    * mp.besseli(0, (b + c) * (1 + u) / 2)
                    * mp.exp(a * (u - 1))
                )

            return a + mp.log(mp.quad(integrand, sorted(points)) / 2)

    rows = ["| magnitude of S | worst relative error of log c (float64) |", "|---|---|"]
    patterns = [(1, 1, 1), (1, 1, -1), (1, 0, 0), (1, 0.5, -0.25), (1, 1 - 1e-6, 1 - 2e-6)]
    for magnitude in (1e-4, 1e-2, 1.0, 100.0, 1e4, 1e5):
        grid = [tuple(magnitude * p for p in pattern) for pattern in patterns]
        values = matrix_fisher_log_normalizer(torch.tensor(grid, dtype=torch.float64))
        worst = max(
            float(abs((mp.mpf(float(v)) - reference(s)) / reference(s)))
            for v, s in zip(values, grid, strict=True)
        )
        rows.append(f"| {magnitude:g} | {worst:.1e} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=8, help="images per call (B)")
    parser.add_argument("--samples", type=int, default=100, help="samples per distribution (K)")
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--repeats", type=int, default=100, help="timed calls per row")
    parser.add_argument("--skip-accuracy", action="store_true", help="skip the mpmath table")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(
        f"Machine: {platform.processor() or platform.machine()}, {args.threads} torch threads, "
        f"torch {torch.__version__}, Python {platform.python_version()}\n"
    )
    print(f"Rotation sampling, B={args.batch} x 23 joints x K={args.samples}, float32, CPU:\n")
    print("\n".join(sampler_table(args.batch, args.samples, args.repeats)))
    print(f"\nlog c(F) at B={args.batch} x 23:\n")
    print("\n".join(normalizer_table(args.batch, args.repeats)))
    if not args.skip_accuracy:
        print("\nAccuracy against mpmath (30 digits):\n")
        print("\n".join(accuracy_table()))


if __name__ == "__main__":
    main()
