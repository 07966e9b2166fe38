"""Do several real photos of one person agree on the shape? (docs/shape.md, section 5)

There is no true shape for a photo, but photos of one person must agree with each other, and
two people should come out apart if the shape is read at all. For each person (a group of photo
paths) the shipped predictor reads every photo with keypoint evidence alone and with the person
mask too (``silhouette_evidence``), then combines the photos as ``hkpd-predict --same-person``
does (the product of the shape Gaussians). Printed per posterior:

- per photo: β₀ (height), β₁, β₂ (girth), β₃ means ± stds;
- per person: the combined β₀…β₃ ± std, and the spread of the photos' means about their mean in
  units of each photo's std (RMS over photos and β₀…β₃: about 1 or less when the photos agree
  within their stated uncertainty, above 1 when they contradict each other);
- between the two people: the difference of their combined β₀…β₃ in units of the combined std.

    python docs/experiments/same_person_photos.py --person A1.jpg A2.jpg --person B1.jpg B2.jpg
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from hkpd.prediction import Predictor
from hkpd.prediction.shape_combination import product_of_gaussians

SHOWN = 4
"""β₀…β₃: height, shoulders vs torso depth, girth, shoulders vs hips."""


def read_person(predictor: Predictor, photos: list[Path]) -> tuple[torch.Tensor, torch.Tensor]:
    """``(N, 10)`` shape means and stds of ``photos``."""
    means, stds = [], []
    for photo in photos:
        posterior = predictor.predict(photo)
        means.append(posterior.shape_mean.detach().double().cpu())
        stds.append(posterior.shape_std.detach().double().cpu())
        shown = ", ".join(
            f"{m:+.2f}±{s:.2f}" for m, s in zip(means[-1][:SHOWN], stds[-1][:SHOWN], strict=True)
        )
        print(f"  {photo.name}: β₀…β₃ {shown}  fit terms {posterior.evidence_fit.terms}")
    return torch.stack(means), torch.stack(stds)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--person", nargs="+", type=Path, action="append", required=True)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    for silhouette in (False, True):
        predictor.silhouette_evidence = silhouette
        print(f"\n## {'keypoints + person mask' if silhouette else 'keypoints only'}")
        combined = []
        for index, photos in enumerate(args.person):
            print(f"person {index + 1}:")
            means, stds = read_person(predictor, photos)
            mean, std = product_of_gaussians(means, stds)
            combined.append((mean, std))
            spread = ((means - means.mean(0)) / stds)[:, :SHOWN].pow(2).mean().sqrt()
            pairs = zip(mean[:SHOWN], std[:SHOWN], strict=True)
            shown = ", ".join(f"{m:+.2f}±{s:.2f}" for m, s in pairs)
            print(f"  combined ({len(photos)} photos): β₀…β₃ {shown}")
            print(f"  photos' spread about their mean, in their stds (RMS β₀…β₃): {spread:.2f}")
        if len(combined) == 2:
            (first, first_std), (second, second_std) = combined
            apart = (first - second) / (first_std.pow(2) + second_std.pow(2)).sqrt()
            values = ", ".join(f"{value:+.2f}" for value in apart[:SHOWN])
            print(f"person 1 - person 2, in combined stds (β₀…β₃): {values}")
    predictor.close()


if __name__ == "__main__":
    main()
