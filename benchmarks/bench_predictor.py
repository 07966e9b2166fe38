"""Latency of the whole predictor with the model loaded: ``predict`` (detection + proxy +
network, and with 2D evidence the keypoint fit), then mode + 100 samples + per-vertex
uncertainty; network-only and evidence posteriors side by side.

Usage: python benchmarks/bench_predictor.py [--model CKPT] [--photos DIR] [--repeats 5]
       [--threads 2] [--no-mirror-reading] [--silhouette-evidence] [--facings 2]
       [--sex female|male]

``--silhouette-evidence`` builds the predictor with ``silhouette_evidence=True``: the
evidence rows then fit the keypoints *and* BlazePose's person mask (issue 41's speed target).
``--facings 1`` fits each start only as the network read it, not also half-turned
(``EvidenceConfig.facings``; issue 42). By default the evidence posterior fits both sexes'
shape priors (issue 49: two fits); ``--sex`` states one (one fit), for the comparison.
``--no-landmark-evidence`` leaves out BlazePose's hand and foot landmarks (issue 52).
``--no-face`` leaves out the face's word on the sex (issue 57: the face is read by default);
``--no-second-reader`` leaves out MoveNet (issue 59). Each repeat reads the photo afresh (the
predictor's photo readings, kept for occluder edits, are forgotten first).

Without ``--photos`` it uses the explorer's built-in demo photo (rendered by hkpd itself).
Prints a markdown table; results are recorded in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from dataclasses import replace
from pathlib import Path

import torch

from hkpd.prediction import Predictor
from hkpd.prediction.readings import ReadingConfig


def demo_photo():
    from hkpd.explorer.demo_scene import render_demo_scene

    return render_demo_scene().image


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--model", help="checkpoint (default: the shipped model)")
    parser.add_argument("--photos", type=Path, help="folder of photos")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument(
        "--no-mirror-reading", action="store_true", help="read each crop once, not also mirrored"
    )
    parser.add_argument(
        "--silhouette-evidence",
        action="store_true",
        help="the evidence posterior also fits the detector's person mask",
    )
    parser.add_argument(
        "--facings",
        type=int,
        choices=(1, 2),
        help="fit each start as read (1) or also half-turned (2); default: the model's setting",
    )
    parser.add_argument(
        "--sex", choices=("female", "male"), help="state the sex: one fit instead of two"
    )
    parser.add_argument(
        "--no-landmark-evidence",
        action="store_true",
        help="fit without BlazePose's hand and foot landmarks (issue 52's comparison)",
    )
    parser.add_argument("--no-face", action="store_true", help="do not read the face")
    parser.add_argument(
        "--no-second-reader", action="store_true", help="do not read the person with MoveNet"
    )
    args = parser.parse_args()
    options = {"read_face": False} if args.no_face else {}
    if args.no_second_reader:
        options["second_reader"] = False
    torch.set_num_threads(args.threads)
    reading = ReadingConfig(mirror=not args.no_mirror_reading)
    predictor = Predictor.from_pretrained(
        args.model,
        device="cpu",
        reading_config=reading,
        silhouette_evidence=args.silhouette_evidence,
    )
    predictor.landmark_evidence = not args.no_landmark_evidence
    if args.facings is not None:
        predictor.evidence_config = replace(predictor.evidence_config, facings=args.facings)
    if args.photos:
        photos = sorted(p for p in args.photos.iterdir() if p.suffix.lower() in (".jpg", ".png"))
    else:
        photos = [demo_photo()]
    predictor.predict(photos[0])  # warm up the detector graph and the network
    rows = []
    for evidence in (False, True):
        predict_times, sample_times, fit_times, totals = [], [], [], []
        for photo in photos:
            for _ in range(args.repeats):
                predictor._photo_readings.clear()  # a photo read afresh, not an occluder edit
                start = time.perf_counter()
                sex = args.sex if evidence else None
                posterior = predictor.predict(photo, evidence=evidence, sex=sex, **options)
                middle = time.perf_counter()
                posterior.mode()
                posterior.vertex_uncertainty(100)
                end = time.perf_counter()
                predict_times.append(middle - start)
                sample_times.append(end - middle)
                totals.append(end - start)
                if posterior.evidence_fit is not None:
                    fit_times.append(posterior.evidence_fit.seconds)
        name = "network only"
        if evidence:
            name = "with 2D + mask evidence" if args.silhouette_evidence else "with 2D evidence"
        rows.append((f"predict ({name})", predict_times, ""))
        if fit_times:
            fit_name = "keypoint + silhouette fit" if args.silhouette_evidence else "keypoint fit"
            fit_target = "" if args.silhouette_evidence else "<= 200"
            sexes = "one sex" if args.sex or not predictor.body.has_sex_priors else "per sex"
            rows.append((f"  of which the {fit_name} ({sexes})", fit_times, fit_target))
        rows.append((f"mode + 100 samples + vertex uncertainty ({name})", sample_times, ""))
        rows.append((f"photo -> posterior + uncertainty ({name})", totals,
                     "<= 450" if evidence else ""))  # fmt: skip
    load = os.getloadavg()[0]
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, load {load:.1f}, torch "
          f"{torch.__version__}, threads {args.threads}, network input "
          f"{predictor.crop_size} px, mirror reading {predictor.reading.config.mirror}, "
          f"silhouette evidence {predictor.silhouette_evidence}, "
          f"landmark evidence {predictor.landmark_evidence}, "
          f"facings {predictor.evidence_config.facings}, "
          f"sexes fitted {1 if args.sex or not predictor.body.has_sex_priors else 2}, "
          f"face read {not args.no_face}, second reader {not args.no_second_reader}, "
          f"{len(photos)} photo(s) x {args.repeats}")  # fmt: skip
    print()
    print("| step | median ms | best ms | target |")
    print("|---|---|---|---|")
    for label, times, target in rows:
        print(f"| {label} | {statistics.median(times) * 1e3:.0f} | {min(times) * 1e3:.0f} "
              f"| {target} |")  # fmt: skip


if __name__ == "__main__":
    main()
