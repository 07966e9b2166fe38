"""Render ``docs/figures/multi_view_shape.png`` and print its table: shape from 1-5 synthetic
photos of one person (PVE-T-SC of the single image, the mean of means and the probabilistic
combination; the combined shape std and T-pose vertex uncertainty) for a checkpoint.

    python docs/figures/scripts/make_multi_view_shape_figure.py --poses poses.npz --bodies 100

The numbers are those of ``hkpd-eval CHECKPOINT --poses poses.npz --no-synthetic
--multi-view-shape 100`` (same functions, seed and test poses); the figure also shows the five
renders of the first body.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.evaluation.multi_view_shape import (
    MULTI_VIEW_SEED,
    MultiViewPredictions,
    labelled,
    multi_view_shape_table,
    predict_multi_view_shapes,
)
from hkpd.evaluation.report import markdown_table
from hkpd.network.checkpoint import load_network
from hkpd.poses import pose_source
from hkpd.prediction.predictor import shipped_model_path
from hkpd.synthesis.generator import (
    SyntheticDataConfig,
    SyntheticDataGenerator,
    batch_seed,
)

FIGURE = Path(__file__).resolve().parents[1] / "multi_view_shape.png"
VIEWS = 5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, default=None, help="default: the shipped model")
    parser.add_argument("--poses", type=Path, help="pose bank (its test split); else procedural")
    parser.add_argument("--bodies", type=int, default=100)
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    parser.add_argument("--out", type=Path, default=FIGURE)
    parser.add_argument(
        "--predictions",
        type=Path,
        help="an .npz of the predicted shape Gaussians: read when it exists (no rendering), "
        "else written after predicting",
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    model = args.model or shipped_model_path()
    network, _ = load_network(model, "cpu")
    config = SyntheticDataConfig(image_size=int(network.config.image_size))
    body = BodyModel()
    generator = SyntheticDataGenerator(pose_source(args.poses, "test"), config, body=body)
    with torch.no_grad():
        if args.predictions is not None and args.predictions.is_file():
            arrays = np.load(args.predictions)
            predictions = MultiViewPredictions(
                *(torch.from_numpy(arrays[k]) for k in ("true_betas", "means", "stds"))
            )
        else:
            predictions = predict_multi_view_shapes(network.eval(), generator, args.bodies, VIEWS)
            if args.predictions is not None:
                arrays = {"true_betas": predictions.true_betas, "means": predictions.means,
                          "stds": predictions.stds}  # fmt: skip
                np.savez(args.predictions, **{k: v.numpy() for k, v in arrays.items()})
        rows = multi_view_shape_table(predictions, body)
    print(f"{model}: {args.bodies} bodies x {VIEWS} views, seed {MULTI_VIEW_SEED}\n")
    print(markdown_table(labelled(rows), None))
    errors = predictions.means - predictions.true_betas  # (views, bodies, K)
    shared = float(errors.mean(0).pow(2).sum() / errors.pow(2).sum(-1).mean(0).sum())
    print(f"\nshare of the beta error common to all {VIEWS} views of a body: {shared:.2f} "
          f"(independent errors: {1 / VIEWS:.2f}, one shared error: 1)")  # fmt: skip
    renders = _first_body_views(generator, predictions.true_betas, args.bodies)
    _draw(rows, renders, args.out, args.bodies)
    print(f"\nwrote {args.out}")


def _first_body_views(
    generator: SyntheticDataGenerator, betas: torch.Tensor, bodies: int
) -> list[np.ndarray]:
    """The five renders of the first body exactly as the evaluation made them (``(S, S, 3)``
    uint8 each): batch ``v * chunks`` of the evaluation's stream holds view ``v`` of bodies
    0-49 (``betas``: all bodies' ``(bodies, K)``)."""
    chunks = (bodies + 49) // 50
    first = betas[:50]
    return [
        generator.generate(len(first), batch_seed(MULTI_VIEW_SEED, view * chunks), first).images[0]
        for view in range(VIEWS)
    ]


def _draw(
    rows: dict[str, dict[str, float]], renders: list[np.ndarray], out: Path, bodies: int
) -> None:
    counts = np.arange(1, len(rows) + 1)

    def column(name: str) -> np.ndarray:
        return np.array([row[name] for row in rows.values()])

    figure = plt.figure(figsize=(11, 6.4))
    grid = figure.add_gridspec(2, VIEWS, height_ratios=[1.0, 2.2], hspace=0.3, wspace=0.6)
    for view, image in enumerate(renders):
        axis = figure.add_subplot(grid[0, view])
        axis.imshow(image)
        axis.set_axis_off()
        axis.set_title(f"view {view + 1}", fontsize=9)
    left = figure.add_subplot(grid[1, :3])
    left.plot(counts, column("pve_t_sc_average_body"), ":", color="grey",
              label="average body (all betas 0)")  # fmt: skip
    left.plot(counts, column("pve_t_sc_single"), "k--", label="single image")
    left.plot(counts, column("pve_t_sc_mean"), "o-", label="mean of means")
    left.plot(counts, column("pve_t_sc_product"), "s-", label="probabilistic (product)")
    left.set_xlabel("photos of the person")
    left.set_ylabel("PVE-T-SC (mm)")
    left.set_xticks(counts)
    left.grid(alpha=0.3)
    left.legend()
    left.set_title(f"shape error, {bodies} synthetic bodies (y axis zoomed)")
    right = figure.add_subplot(grid[1, 3:])
    right.plot(counts, column("shape_std_product"), "s-", color="C1", label="combined std")
    right.plot(counts, column("shape_std_product")[0] / np.sqrt(counts), ":", color="k",
               label="one photo / sqrt(n)")  # fmt: skip
    right.plot(counts, column("shape_std_mean"), "o-", color="C0", label="mean of means (RMS)")
    right.set_xlabel("photos of the person")
    right.set_ylabel("mean shape std (coefficients)")
    right.set_xticks(counts)
    right.grid(alpha=0.3)
    twin = right.twinx()
    twin.plot(counts, column("shape_uncertainty_product_mm"), "^-", color="C2",
              label="T-pose vertex uncertainty (mm)")  # fmt: skip
    twin.set_ylabel("T-pose vertex uncertainty (mm)", color="C2")
    twin.set_ylim(bottom=0)
    right.set_ylim(bottom=0)
    handles = right.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
    labels = right.get_legend_handles_labels()[1] + twin.get_legend_handles_labels()[1]
    right.legend(handles, labels, fontsize=8)
    right.set_title("probabilistic combination: how sure")
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=110, bbox_inches="tight")


if __name__ == "__main__":
    main()
