"""Render ``docs/figures/predict_overview.png``: ``hkpd-predict`` on a photo hkpd renders itself.

The photo is the explorer's demo scene (:func:`hkpd.explorer.demo_scene.render_demo_scene`: the
shipped body in a walking pose, rasterised and shaded by hkpd, so it can be committed). The real
pipeline runs on it: BlazePose, crop, proxy, the network given with ``--model``, samples,
uncertainty, overview.

    python docs/figures/scripts/make_predict_overview.py --model runs/hkpd/last.pt
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

from PIL import Image

from hkpd.explorer.demo_scene import render_demo_scene
from hkpd.prediction import cli

FIGURE = Path(__file__).resolve().parents[1] / "predict_overview.png"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default=None, help="checkpoint (default: the shipped model)")
    parser.add_argument("--samples", type=int, default=10)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        photo = Path(folder) / "rendered_person.png"
        Image.fromarray(render_demo_scene().image).save(photo)
        command = [str(photo), "--out", str(Path(folder) / "out"), "--samples", str(args.samples)]
        if args.model:
            command += ["--model", args.model]
        if cli.main([*command, "--format", "npz"]) != 0:
            raise SystemExit("hkpd-predict failed on the rendered photo")
        FIGURE.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(Path(folder) / "out" / photo.stem / "overview.png", FIGURE)
    print(f"wrote {FIGURE}")


if __name__ == "__main__":
    main()
