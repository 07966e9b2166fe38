"""Files of a shape combined from several photos of one person (``hkpd-predict --same-person``).

Into one folder :func:`write_combined_shape` writes:

- ``tpose.<fmt>``: the T-pose mesh of the combined mean shape, per mesh format asked for (Y-up
  display frame, pelvis at the origin, like the other mesh files);
- ``tpose_uncertainty.<fmt>``: the same mesh coloured by per-vertex *shape* uncertainty on the
  fixed colour scale of :mod:`hkpd.prediction.exports.uncertainty_colours`;
- ``shape.npz`` (with ``npz`` among the formats): ``betas_mean (K,)``, ``betas_std (K,)``,
  ``photo_betas_mean (N, K)``, ``photo_betas_std (N, K)``, ``baseline_betas_mean (K,)``,
  ``tpose_vertices (V, 3)`` (camera-aligned body frame), ``uncertainty (V,)`` metres,
  ``faces (F, 3)``;
- ``shape.json``: the same numbers (without the meshes), the photos, the method and the files.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from hkpd.prediction.exports.uncertainty_colours import UncertaintyColourScale
from hkpd.prediction.exports.writers import (
    ARRAY_FORMAT,
    DISPLAY_FRAME_NOTE,
    MESH_FORMATS,
    write_distribution_npz,
    write_json,
    write_mesh,
)
from hkpd.prediction.shape_combination import CombinedShape

METHOD_NOTE = (
    "product: precision-weighted product of the photos' diagonal shape Gaussians "
    "(1/std^2 = sum 1/std_i^2, mean = std^2 sum mean_i/std_i^2); the baseline averages the means"
)


def write_combined_shape(
    folder: Path,
    combined: CombinedShape,
    baseline: CombinedShape,
    images: Sequence[Path],
    photo_means: torch.Tensor,
    photo_stds: torch.Tensor,
    formats: Sequence[str],
    scale: UncertaintyColourScale,
) -> list[str]:
    """Write the combined shape's files into ``folder`` (created) and return their names.

    Args:
        folder: where to write.
        combined: the probabilistic combination (:func:`combine_shapes` with ``"product"``).
        baseline: the mean of the means (``"mean"``), stored for comparison.
        images: the N photos combined, in order.
        photo_means, photo_stds: ``(N, K)`` their shape Gaussians.
        formats: output formats (mesh formats and/or ``npz``).
        scale: colour scale of the uncertainty mesh.
    """
    folder.mkdir(parents=True, exist_ok=True)
    uncertainty = combined.vertex_uncertainty.detach().cpu().double().numpy()
    colours = scale.colours_uint8(uncertainty)
    written: list[Path] = []
    for fmt in formats:
        if fmt in MESH_FORMATS:
            vertices = combined.tpose_vertices
            written.append(write_mesh(folder / f"tpose.{fmt}", vertices, combined.faces))
            written.append(
                write_mesh(folder / f"tpose_uncertainty.{fmt}", vertices, combined.faces, colours)
            )
    if ARRAY_FORMAT in formats:
        arrays = {
            "betas_mean": combined.betas_mean,
            "betas_std": combined.betas_std,
            "photo_betas_mean": photo_means,
            "photo_betas_std": photo_stds,
            "baseline_betas_mean": baseline.betas_mean,
            "tpose_vertices": combined.tpose_vertices,
            "uncertainty": combined.vertex_uncertainty,
            "faces": combined.faces.to(torch.int32),
        }
        written.append(write_distribution_npz(folder / "shape.npz", arrays))
    summary_path = folder / "shape.json"
    files = [path.name for path in written] + [summary_path.name]
    summary = {
        "photos": [str(image) for image in images],
        "count": combined.count,
        "method": METHOD_NOTE,
        "betas_mean": combined.betas_mean,
        "betas_std": combined.betas_std,
        "mean_std": combined.mean_std,
        "photo_betas_mean": photo_means,
        "photo_betas_std": photo_stds,
        "photo_mean_std": [float(row.mean()) for row in photo_stds],
        "baseline_betas_mean": baseline.betas_mean,
        "uncertainty": {
            "what": "shape only: mean distance of T-pose meshes sampled from the combined "
            "Gaussian from their mean, metres",
            "mean_m": float(np.mean(uncertainty)),
            "max_m": float(np.max(uncertainty)),
            "samples": combined.uncertainty_samples,
            "colour_scale": scale.describe(),
        },
        "frames": DISPLAY_FRAME_NOTE + "; the T-pose body faces the viewer",
        "formats": list(formats),
        "files": files,
    }
    write_json(summary_path, summary)
    return files
