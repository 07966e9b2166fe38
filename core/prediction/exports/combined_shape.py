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
- ``shape.json``: the same numbers (without the meshes), the photos, the method and the files;
  with a :class:`CombinedBody`, also the combined ``"sex_probabilities"`` and ``"drawn_sex"``,
  the combined shape's ``"measurements"`` (``{name: {"mean", "std"}}``), each photo's
  ``"photo_sex_probabilities"`` and what was ``"stated"``. With sex as a latent the shape is
  combined per sex (:mod:`hkpd.prediction.sex_combination`) and ``shape.npz`` also holds the
  per-sex arrays of :func:`hkpd.prediction.exports.body_summary.sex_arrays` and the
  measurements.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from hkpd.prediction.exports.body_summary import (
    measurement_arrays,
    measurement_summary,
    sex_arrays,
    stated_summary,
)
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

if TYPE_CHECKING:
    from hkpd.conditioning import StatedBody

METHOD_NOTE = (
    "product: precision-weighted product of the photos' diagonal shape Gaussians "
    "(1/std^2 = sum 1/std_i^2, mean = std^2 sum mean_i/std_i^2); the baseline averages the means"
)

SEX_METHOD_NOTE = (
    "per sex: product of the photos' full-covariance shape Gaussians, the sexes' log-odds added, "
    "a stated measurement counted once (hkpd.prediction.sex_combination); betas_mean/betas_std "
    "are the more probable sex's; the baseline averages the photos' means"
)


@dataclass(frozen=True)
class CombinedBody:
    """What ``shape.json`` says about the combined body besides its shape coefficients.

    Attributes:
        measurements: ``{name: (mean, std)}`` of the combined shape (metres, kilograms), or
            None.
        photo_sex_probabilities: per combined photo, ``{"female": p, "male": 1 - p}`` or None.
        stated: what every photo was given, or None.
    """

    measurements: Mapping[str, tuple[float, float]] | None = None
    photo_sex_probabilities: Sequence[Mapping[str, float] | None] = ()
    stated: StatedBody | None = None

    def summary(self, combined: CombinedShape) -> dict[str, object]:
        """The ``shape.json`` keys: ``"sex_probabilities"`` (the combined ones, or None),
        ``"drawn_sex"``, ``"measurements"``, ``"photo_sex_probabilities"`` and ``"stated"``."""
        sexes = combined.sexes
        return {
            "sex_probabilities": None if sexes is None else dict(sexes.probabilities),
            "drawn_sex": None if sexes is None else sexes.most_probable,
            "measurements": None
            if self.measurements is None
            else measurement_summary(self.measurements),
            "photo_sex_probabilities": [
                None if item is None else dict(item) for item in self.photo_sex_probabilities
            ],
            "stated": stated_summary(self.stated),
        }


def write_combined_shape(
    folder: Path,
    combined: CombinedShape,
    baseline: CombinedShape,
    images: Sequence[Path],
    photo_means: torch.Tensor,
    photo_stds: torch.Tensor,
    formats: Sequence[str],
    scale: UncertaintyColourScale,
    body: CombinedBody | None = None,
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
        body: the combined body's measurements, the photos' sexes and what was stated (None:
            not written).
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
        } | sex_arrays(combined.sexes, int(combined.betas_mean.shape[-1]))
        if body is not None and body.measurements is not None:
            arrays |= measurement_arrays(body.measurements)
        written.append(write_distribution_npz(folder / "shape.npz", arrays))
    summary_path = folder / "shape.json"
    files = [path.name for path in written] + [summary_path.name]
    summary = {
        "photos": [str(image) for image in images],
        "count": combined.count,
        "method": METHOD_NOTE if combined.sexes is None else SEX_METHOD_NOTE,
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
    if body is not None:
        summary |= body.summary(combined)
    write_json(summary_path, summary)
    return files
