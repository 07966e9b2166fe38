"""What the install promises (docs/install.md): CPU torch from PyTorch's CPU index as an extra
index in both README commands, no mediapipe or jax, one OpenCV, and the shipped BlazePose models
as their NOTICE describes them."""

from __future__ import annotations

import hashlib
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).parents[1]
CPU_TORCH = "torch==2.13.0 --extra-index-url https://download.pytorch.org/whl/cpu"


def test_both_readme_commands_take_cpu_torch_and_skip_an_unreachable_index_fast() -> None:
    readme = (ROOT / "README.md").read_text()
    commands = [line for line in readme.splitlines() if line.startswith("python3 -m venv .venv")]
    assert len(commands) == 2  # the main job and the tests
    for command in commands:
        assert CPU_TORCH in command
        assert "--retries 1" in command
        # torch is installed before hkpd, so hkpd's `torch>=2.1` is already satisfied.
        assert command.index(CPU_TORCH) < command.index("install --no-compile -e ")


def test_dependencies_have_no_mediapipe_no_jax_and_one_opencv() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = [re.split(r"[<>=!~ \[;]", d, maxsplit=1)[0].lower() for d in project["dependencies"]]
    assert not {"mediapipe", "jax", "jaxlib"} & set(names)
    assert [n for n in names if n.startswith("opencv")] == ["opencv-python-headless"]
    assert "ai-edge-litert" in names
    assert "numpy" in names and not any(d.startswith("numpy<") for d in project["dependencies"])


def test_shipped_blazepose_models_match_their_notice() -> None:
    folder = ROOT / "assets" / "blazepose"
    notice = (folder / "NOTICE.md").read_text()
    for name in ("pose_detection.tflite", "pose_landmark_full.tflite"):
        data = (folder / name).read_bytes()
        assert len(data) < 25 * 2**20
        assert f"{hashlib.sha256(data).hexdigest()}  {name}" in notice
