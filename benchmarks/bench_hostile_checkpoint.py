"""Time and memory to refuse hostile checkpoints (issue 44: < 1 s, < 100 MB).

Each case is the shipped weights with one change and a valid checksum (a hostile config, or
weights like a diverged run's); each is loaded with ``load_network`` in a fresh process, which
reports the wall time to the refusal and how much its peak resident memory grew (the peak
``VmHWM`` over the attempt, reset just before it, less the resident memory before it)::

    python benchmarks/bench_hostile_checkpoint.py
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import torch

from hkpd.network.checkpoint import model_checksum
from hkpd.prediction.predictor import shipped_model_path

CASES: dict[str, dict] = {
    "backbone_base_width=8192": {"backbone_base_width": 8192},
    "backbone_blocks=[2000000]": {"backbone_blocks": [2000000]},
    "image_size=60000": {"image_size": 60000},
    "backbone_base_width=64 (fits the limits, not the tensors)": {"backbone_base_width": 64},
}

CHILD = """
import json, re, sys, time
from pathlib import Path
from hkpd.network.checkpoint import CheckpointError, load_network

def kilobytes(field):
    return int(re.search(field + r":\\s+(\\d+)", Path("/proc/self/status").read_text())[1])

Path("/proc/self/clear_refs").write_text("5")  # the peak (VmHWM) restarts from the current RSS
before = kilobytes("VmRSS")
start = time.perf_counter()
try:
    load_network(sys.argv[1])
    outcome = "LOADED"
except CheckpointError as error:
    outcome = str(error)
seconds = time.perf_counter() - start
after = kilobytes("VmHWM")
print(json.dumps({"seconds": seconds, "grew_mb": (after - before) / 1024, "outcome": outcome}))
"""


def _hostile_files(folder: Path) -> dict[str, Path]:
    files = {}
    for index, (name, entries) in enumerate(CASES.items()):
        payload = torch.load(shipped_model_path(), weights_only=True)
        payload["network_config"].update(entries)
        files[name] = folder / f"config_{index}.pt"
        torch.save(payload, files[name])
    for name, value in (("weights x 1e4", 1e4), ("one weight NaN", float("nan"))):
        payload = torch.load(shipped_model_path(), weights_only=True)
        state = payload["model"]
        if value == 1e4:
            payload["model"] = {
                k: v * value if v.is_floating_point() else v for k, v in state.items()
            }
        else:
            state["head.first_layer.weight"] = state["head.first_layer.weight"].clone()
            state["head.first_layer.weight"].view(-1)[0] = value
        payload["checksum"] = model_checksum(payload["model"])
        files[name] = folder / f"weights_{len(files)}.pt"
        torch.save(payload, files[name])
    return files


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    with tempfile.TemporaryDirectory() as folder:
        for name, path in _hostile_files(Path(folder)).items():
            result = subprocess.run(
                [sys.executable, "-c", CHILD, str(path)],
                capture_output=True, text=True, check=True,
            )  # fmt: skip
            report = json.loads(result.stdout)
            print(
                f"{name:58s} {report['seconds'] * 1000:6.0f} ms  +{report['grew_mb']:5.1f} MB  "
                f"{report['outcome'][len(str(path)) + 1 :][:70]}"
            )


if __name__ == "__main__":
    main()
