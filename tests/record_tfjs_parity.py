"""Record the TF.js parity fixtures of hkpd's shipped graph models (tests/data/tfjs_parity/).

Runs each model with ``@tensorflow/tfjs`` (pinned in tests/tfjs_parity/package.json) on its
pure-JavaScript CPU backend under node, on a small crop of assets/photos/warrior_lunge.jpg,
and stores the image and TF.js's outputs. It also runs hkpd's runtime on the same inputs and
prints the largest differences (float32, and float64 to see which side's rounding they are).
CI reads the fixtures only; recording needs node and, once,
``npm ci --prefix tests/tfjs_parity`` (node_modules is git-ignored).

    python tests/record_tfjs_parity.py                      # the shipped models
    python tests/record_tfjs_parity.py --model-dir DIR --models centernet --compare-only

Outputs of more than :data:`FULL_LIMIT` elements are stored as a sample: :data:`SAMPLED`
random positions (fixed seed) plus the :data:`TOP` largest values, with the whole output's
mean and mean absolute value (both within the tolerance whenever every element is).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from tfjs_parity_inputs import REPEAT, model_inputs  # noqa: E402

from hkpd.model_runtime import GraphModel  # noqa: E402

NODE_FOLDER = ROOT / "tests" / "tfjs_parity"
FIXTURES = ROOT / "tests" / "data" / "tfjs_parity"
PHOTO = ROOT / "assets" / "photos" / "warrior_lunge.jpg"
SHIPPED = ("faceres", "nanodet", "movenet-thunder")
FULL_LIMIT = 20_000
SAMPLED = 2048
TOP = 256

CROPS = {
    "faceres": ((484, 136, 588, 240), 224),
    "nanodet": ((180, 0, 900, 720), 416),
    "movenet-thunder": ((180, 0, 900, 720), 256),
    "centernet": ((180, 0, 900, 720), 512),
}
"""Each model's crop of the photo (left, top, right, bottom) and its input side."""


def parity_image(name: str) -> np.ndarray:
    """The stored image of ``name``'s fixture: its crop, resized (bilinear) to the input side
    divided by ``REPEAT[name]``; ``(s, s, 3)`` uint8."""
    box, side = CROPS[name]
    small = side // REPEAT[name]
    with Image.open(PHOTO) as photo:
        crop = photo.convert("RGB").crop(box).resize((small, small), Image.Resampling.BILINEAR)
    return np.asarray(crop, dtype=np.uint8)


def generic_inputs(model: GraphModel) -> dict[str, np.ndarray]:
    """Inputs for a model without a fixture (``--compare-only``): the photo's square crop
    resized to each NHWC image input (RGB 0..255, int32 where the input is), a free batch 1
    and free sides 256."""
    inputs = {}
    for name, spec in model.inputs.items():
        shape = [
            size if size != -1 else 1 if axis == 0 else 256
            for axis, size in enumerate(spec.shape or ())
        ]
        if len(shape) != 4 or shape[3] != 3:
            raise SystemExit(f"{model.path}: no generic input for {name} {shape}")
        with Image.open(PHOTO) as photo:
            square = photo.convert("RGB").crop(CROPS["nanodet"][0])
            pixels = np.asarray(square.resize((shape[2], shape[1]), Image.Resampling.BILINEAR))
        array = np.broadcast_to(pixels, shape)
        inputs[name] = np.ascontiguousarray(
            array.astype(np.int32 if spec.dtype == "DT_INT32" else np.float32)
        )
    return inputs


def run_tfjs(jobs: dict[str, dict[str, np.ndarray]], model_dir: Path, outputs: dict) -> dict:
    """TF.js's outputs: ``{model: {output name: array}}``."""
    if not (NODE_FOLDER / "node_modules" / "@tensorflow" / "tfjs").is_dir():
        raise SystemExit(f"run `npm ci --prefix {NODE_FOLDER}` first (needs node and npm)")
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        job = {"models": []}
        for name, inputs in jobs.items():
            specs = {}
            for index, (input_name, array) in enumerate(inputs.items()):
                file = work / f"{name}-input{index}.bin"
                file.write_bytes(
                    np.ascontiguousarray(array).astype(array.dtype.newbyteorder("<")).tobytes()
                )
                dtype = "int32" if array.dtype == np.int32 else "float32"
                specs[input_name] = {"file": str(file), "dtype": dtype, "shape": list(array.shape)}
            job["models"].append({
                "json": str(model_dir / f"{name}.json"), "inputs": specs,
                "outputs": outputs[name], "out_dir": str(work / name),
            })  # fmt: skip
        (work / "job.json").write_text(json.dumps(job))
        done = subprocess.run(
            ["node", "record.cjs", str(work / "job.json")],
            cwd=NODE_FOLDER, capture_output=True, text=True, check=False,
        )  # fmt: skip
        if done.returncode:
            raise SystemExit(f"node failed:\n{done.stderr}")
        print("TF.js:", done.stdout.strip().splitlines()[-1])
        return {name: _read_outputs(work / name) for name in jobs}


def _read_outputs(folder: Path) -> dict[str, np.ndarray]:
    listing = json.loads((folder / "outputs.json").read_text())
    result = {}
    for index, entry in enumerate(listing):
        dtype = "<i4" if entry["dtype"] == "int32" else "<f4"
        values = np.frombuffer((folder / f"{index}.bin").read_bytes(), dtype=dtype)
        result[entry["name"]] = values.reshape(entry["shape"])
    return result


def fixture_arrays(image: np.ndarray, outputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The npz's arrays: the image, the output names, and per output i its shape, mean, mean
    absolute value, values and (for sampled outputs) their flat indices."""
    arrays = {"image": image, "output_names": np.array(list(outputs))}
    generator = np.random.default_rng(57)
    for index, (name, value) in enumerate(outputs.items()):
        flat = value.reshape(-1)
        arrays[f"out{index}_shape"] = np.array(value.shape, dtype=np.int64)
        arrays[f"out{index}_mean"] = np.array(flat.astype(np.float64).mean())
        arrays[f"out{index}_mean_abs"] = np.array(np.abs(flat.astype(np.float64)).mean())
        if flat.size > FULL_LIMIT:
            picked = generator.choice(flat.size, SAMPLED, replace=False)
            largest = np.argsort(flat, kind="stable")[-TOP:]
            positions = np.unique(np.concatenate([picked, largest])).astype(np.int32)
            arrays[f"out{index}_indices"] = positions
            flat = flat[positions]
        arrays[f"out{index}_values"] = flat
        print(f"  {name}: {list(value.shape)} {value.dtype}, stored {flat.size} values")
    return arrays


def compare(name: str, model_dir: Path, inputs: dict, expected: dict[str, np.ndarray]) -> None:
    """Print hkpd's largest differences from TF.js per output, in float32 and float64."""
    model = GraphModel.load(model_dir / f"{name}.json")
    for dtype in (torch.float32, torch.float64):
        ours = model.to(dtype=dtype).run(inputs, list(expected))
        for output, value in expected.items():
            difference = np.abs(ours[output].double().numpy() - value.astype(np.float64))
            print(
                f"  {name} {output} ({str(dtype)[6:]}): max |hkpd - tfjs| {difference.max():.3g}"
                f" (largest |value| {np.abs(value).max():.3g})"
            )


def main(argv: list[str] | None = None) -> None:
    """Record (or, with --compare-only, just compare) the chosen models."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model-dir", type=Path, default=ROOT / "assets" / "human_models")
    parser.add_argument(
        "--models", nargs="+", default=list(SHIPPED), help=f"default {SHIPPED}; others than "
        f"{sorted(CROPS)} only with --compare-only (generic inputs)"
    )  # fmt: skip
    parser.add_argument("--compare-only", action="store_true", help="write no fixture")
    arguments = parser.parse_args(argv)
    torch.set_num_threads(1)
    unknown = sorted(set(arguments.models) - set(CROPS))
    if unknown and not arguments.compare_only:
        parser.error(f"{unknown} have no fixture recipe: use --compare-only")
    models = {n: GraphModel.load(arguments.model_dir / f"{n}.json") for n in arguments.models}
    images = {name: parity_image(name) for name in arguments.models if name in CROPS}
    inputs = {
        name: model_inputs(name, images[name]) if name in CROPS else generic_inputs(model)
        for name, model in models.items()
    }
    output_names = {name: model.output_names for name, model in models.items()}
    expected = run_tfjs(inputs, arguments.model_dir, output_names)
    for name in arguments.models:
        compare(name, arguments.model_dir, inputs[name], expected[name])
        if not arguments.compare_only:
            FIXTURES.mkdir(parents=True, exist_ok=True)
            target = FIXTURES / f"{name}.npz"
            np.savez_compressed(target, **fixture_arrays(images[name], expected[name]))
            print(f"wrote {target.relative_to(ROOT)} ({target.stat().st_size:,} bytes)")


if __name__ == "__main__":
    main()
