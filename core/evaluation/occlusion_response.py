"""Does hiding a limb make the model less sure about that limb, and only that limb?

For synthetic test images (held-out poses, no augmentation) one limb's pixels are covered by
a black box (its bounding box in the rendered part map, plus a margin), exactly as the
explorer's occluders and ``Predictor.predict(occluders=...)`` do: the box is painted before
Canny, and keypoints under it are dropped from the heatmaps. The network predicts both
versions; each limb's mean per-vertex uncertainty (100 samples) is compared:

- *occluded-limb ratio* = uncertainty of the hidden limb with the box / without it;
- *other limbs' change* = ``|ratio - 1|`` for the three limbs that were not covered.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.distributions import BodyDistribution
from hkpd.kinematic_tree import LIMB_SEGMENT_PARTS, SMPL_JOINT_NAMES
from hkpd.prediction.occluders import Occluders, apply_occluders
from hkpd.proxy import build_proxy_batch
from hkpd.synthesis.generator import RenderedBatch, SyntheticDataGenerator, batch_seed
from hkpd.uncertainty import vertex_uncertainty

OCCLUDED_LIMBS = ("left_forearm", "right_forearm", "left_lower_leg", "right_lower_leg")
"""The limbs that get covered (keys of :data:`hkpd.kinematic_tree.LIMB_SEGMENT_PARTS`)."""

LIMB_PARTS: dict[str, tuple[str, ...]] = {limb: LIMB_SEGMENT_PARTS[limb] for limb in OCCLUDED_LIMBS}
"""The covered limbs as SMPL part groups."""

MIN_LIMB_PIXELS = 40
BOX_MARGIN_PX_AT_256 = 6


@dataclass
class OcclusionCase:
    """One image with one limb covered."""

    limb: str
    ratio: float
    other_changes: list[float]


LIMB_PART_INDICES: dict[str, torch.Tensor] = {
    limb: torch.tensor([SMPL_JOINT_NAMES.index(part) for part in parts])
    for limb, parts in LIMB_PARTS.items()
}
"""The parts of each limb as SMPL joint-group indices."""


def limb_vertex_masks(body: BodyModel) -> dict[str, torch.Tensor]:
    """``{limb: (V,) bool}``, the body's vertices labelled with one of the limb's parts."""
    return {
        limb: torch.isin(body.part_labels, parts.to(body.part_labels.device))
        for limb, parts in LIMB_PART_INDICES.items()
    }


def cover_limb(
    rendered: RenderedBatch, item: int, limb: str
) -> tuple[np.ndarray, torch.Tensor] | None:
    """One rendered image with ``limb`` covered by its bounding box (plus a margin) in black.

    Args:
        rendered: a synthetic batch (its part map says where the limb is).
        item: which image of the batch.
        limb: a key of :data:`LIMB_PARTS`.

    Returns:
        ``(image, present)``: the ``(S, S, 3)`` uint8 covered image and the ``(17,)`` bool input
        keypoints that stay present (those under the box are dropped); None when the limb shows
        fewer than ``MIN_LIMB_PIXELS`` pixels.
    """
    size = rendered.images.shape[1]
    margin = max(1, round(BOX_MARGIN_PX_AT_256 * size / 256))
    pixels = torch.isin(rendered.part_map[item].cpu(), LIMB_PART_INDICES[limb]).nonzero()
    if len(pixels) < MIN_LIMB_PIXELS:
        return None
    (y0, x0), (y1, x1) = pixels.amin(0).tolist(), pixels.amax(0).tolist()
    x0, y0 = max(0, x0 - margin), max(0, y0 - margin)
    x1, y1 = min(size, x1 + margin + 1), min(size, y1 + margin + 1)
    box = Occluders([(x0, y0, x1, y1)])
    under = box.covers(rendered.input_keypoints[item].cpu().numpy())
    present = rendered.input_present[item].cpu() & ~torch.from_numpy(under)
    return apply_occluders(rendered.images[item], box), present


def sampled_vertex_uncertainty(
    output: BodyDistribution, poses: torch.Tensor, betas: torch.Tensor, body: BodyModel
) -> torch.Tensor:
    """``(B, V)`` per-vertex uncertainty (metres) of S bodies per image, each posed with the
    image's predicted global rotation.

    Args:
        output: the network's prediction for B images.
        poses: ``(S, B, 23, 3, 3)`` relative joint rotations.
        betas: ``(S, B, K)`` shape coefficients.
    """
    count = poses.shape[0]
    result = []
    for item in range(output.batch_size):
        orient = output.global_orient[item].expand(count, 3, 3)
        vertices = body(betas[:, item], poses[:, item], orient).vertices
        result.append(vertex_uncertainty(vertices))
    return torch.stack(result)


Conditioner = Callable[[BodyDistribution, torch.Tensor, torch.Tensor], BodyDistribution]
"""Maps the network's output, the ``(B, 17, 2)`` input keypoints and their ``(B, 17)`` presence
to another posterior (e.g. the keypoint-evidence one)."""


def _per_vertex_uncertainty(
    network, proxy, body, samples: int, seed: int, condition=None, keypoints=None, present=None
) -> torch.Tensor:
    """``(B, V)`` uncertainty of each image's predicted posterior (conditioned by ``condition``
    on the present keypoints, when given), metres."""
    output = network(proxy)
    if condition is not None:
        output = condition(output, keypoints, present)
    generator = torch.Generator(device=proxy.device).manual_seed(seed)
    poses = output.pose_distribution().sample(samples, generator=generator)  # (S, B, 23, 3, 3)
    betas = output.sample_betas(samples, generator)
    return sampled_vertex_uncertainty(output, poses, betas, body)


@torch.no_grad()
def occlusion_response(
    network: torch.nn.Module,
    generator: SyntheticDataGenerator,
    cases: int = 100,
    samples: int = 100,
    seed: int = 77,
    batch_size: int = 10,
    condition: Conditioner | None = None,
) -> list[OcclusionCase]:
    """Cover one limb per image (cycling through the four limbs) and measure the response.

    Args:
        network: the trained network (eval mode).
        generator: a synthetic data generator with augmentation switched off, on held-out poses.
        cases: images with a visible limb to evaluate (images where the chosen limb shows fewer
            than ``MIN_LIMB_PIXELS`` pixels are skipped and replaced).
        condition: optional map to another posterior given the present input keypoints (the
            covered limb's keypoints are absent in the covered view).

    Returns:
        One :class:`OcclusionCase` per evaluated image.
    """
    body = generator.body
    masks = limb_vertex_masks(body)
    limbs = list(LIMB_PARTS)
    results: list[OcclusionCase] = []
    batch_index = 0
    while len(results) < cases:
        rendered = generator.generate(batch_size, batch_seed(seed, batch_index))
        batch_index += 1
        covered_images, covered_present, chosen = [], [], []
        for item in range(batch_size):
            limb = limbs[(len(results) + len(chosen)) % len(limbs)]
            hidden = cover_limb(rendered, item, limb)
            if hidden is None:
                continue
            covered_images.append(hidden[0])
            covered_present.append(hidden[1])
            chosen.append((item, limb))
        if not chosen:
            continue
        items = [item for item, _ in chosen]
        device = rendered.batch.proxy.device
        clean = rendered.batch.proxy[items]
        covered = build_proxy_batch(
            np.stack(covered_images),
            rendered.input_keypoints[items].cpu(),
            torch.stack(covered_present),
            device,
        )
        keypoints = rendered.input_keypoints[items]
        present = rendered.input_present[items]
        before = _per_vertex_uncertainty(
            network, clean, body, samples, seed, condition, keypoints, present
        )
        after = _per_vertex_uncertainty(
            network, covered, body, samples, seed, condition, keypoints,
            torch.stack(covered_present).to(present.device),
        )  # fmt: skip
        for row, (_, limb) in enumerate(chosen):
            ratios = {
                name: float(after[row, mask].mean() / before[row, mask].mean().clamp_min(1e-9))
                for name, mask in masks.items()
            }
            others = [abs(value - 1) for name, value in ratios.items() if name != limb]
            results.append(OcclusionCase(limb, ratios[limb], others))
            if len(results) == cases:
                break
    return results


def summarise(results: list[OcclusionCase]) -> dict[str, float]:
    """Median and quartiles of the occluded-limb ratio (all cases, then forearms and lower legs
    apart: NaN for a kind with no case); median change of the other limbs."""
    ratios = np.array([case.ratio for case in results])
    others = np.array([change for case in results for change in case.other_changes])
    forearms = [case.ratio for case in results if case.limb.endswith("forearm")]
    lower_legs = [case.ratio for case in results if case.limb.endswith("lower_leg")]
    return {
        "cases": float(len(results)),
        "occluded_ratio_median": float(np.median(ratios)),
        "occluded_ratio_q25": float(np.quantile(ratios, 0.25)),
        "occluded_ratio_q75": float(np.quantile(ratios, 0.75)),
        "occluded_ratio_median_forearms": float(np.median(forearms)) if forearms else math.nan,
        "occluded_ratio_median_lower_legs": float(np.median(lower_legs))
        if lower_legs
        else math.nan,
        "fraction_ratio_at_least_1.5": float((ratios >= 1.5).mean()),
        "other_limbs_change_median": float(np.median(others)),
        "fraction_other_limbs_within_20pct": float((others <= 0.2).mean()),
    }
