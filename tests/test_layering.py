"""Imports only go down the data flow (docs/architecture.md): no package reaches up."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

LAYERS: dict[str, int] = {
    # shared conventions and arithmetic
    "kinematic_tree": 0, "camera_conventions": 0, "coco_keypoints": 0, "devices": 0,
    "cpu_allocator": 0, "alignment": 0, "uncertainty": 0, "mirror_symmetry": 0,
    "distributions": 1,
    "body": 2,
    "poses": 3, "rendering": 3, "proxy": 3,
    "synthesis": 4,
    "network": 5,
    "conditioning": 6,
    "prediction": 7,
    "evaluation": 8,
    "training": 9,
    "explorer": 10,
    "assets": 0,
}  # fmt: skip
"""Layer of each top-level module or package of ``hkpd``: a module may import only from its own
layer or below (the training side sits above the model code, and the explorer above both;
the explorer must not import training or evaluation either)."""

FORBIDDEN = {"explorer": {"training", "evaluation"}}


def _modules() -> list[tuple[str, Path]]:
    found = []
    for folder, package in ((ROOT / "core", None), (ROOT / "explorer", "explorer")):
        for path in sorted(folder.rglob("*.py")):
            relative = path.relative_to(folder)
            top = package or (relative.parts[0].removesuffix(".py"))
            if top == "__init__":
                continue  # the root package's lazy public names
            found.append((top, path))
    return found


def _imported(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hkpd."):
            names.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("hkpd."):
                    names.add(alias.name.split(".")[1])
    return names


def test_no_module_imports_from_a_later_layer() -> None:
    problems = []
    for top, path in _modules():
        assert top in LAYERS, f"{path}: add its package {top!r} to LAYERS"
        for name in _imported(path):
            assert name in LAYERS, f"{path} imports unknown hkpd.{name}"
            if LAYERS[name] > LAYERS[top] or name in FORBIDDEN.get(top, set()):
                problems.append(f"{path.relative_to(ROOT)} imports hkpd.{name}")
    assert not problems, "\n".join(problems)
