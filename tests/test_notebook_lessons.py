"""docs/notebooks/lessons.ipynb, cheaply: it is a valid notebook committed without large
outputs, its code parses, its imports resolve, and every call it makes on the library exists
with the keywords it passes (running it needs the model and ~1 minute; docs/explorer.md's
lessons are what it does)."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import json
from pathlib import Path

from hkpd.explorer.saved_scene import ScenePage
from hkpd.prediction import BodyPosterior, Predictor

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "notebooks" / "lessons.ipynb"
VARIABLE_TYPES = {
    "predictor": Predictor,
    "fits_mask": Predictor,
    "posterior": BodyPosterior,
    "hidden": BodyPosterior,
    "sharp": BodyPosterior,
    "network": BodyPosterior,
    "outline": BodyPosterior,
    "page": ScenePage,
}
"""What the notebook's variables hold (the calls on them are checked against these types)."""


def code_cells() -> list[str]:
    notebook = json.loads(NOTEBOOK.read_text())
    assert notebook["nbformat"] == 4
    cells = [cell for cell in notebook["cells"] if cell["cell_type"] == "code"]
    assert sum(len(json.dumps(cell.get("outputs", []))) for cell in cells) < 100_000
    return ["".join(cell["source"]) for cell in cells]


def _members(cls: type) -> set[str]:
    fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
    return fields | set(dir(cls))


def _check_keywords(function, call: ast.Call, where: str) -> None:
    names = [keyword.arg for keyword in call.keywords if keyword.arg is not None]
    parameters = inspect.signature(function).parameters
    takes_any = any(p.kind is p.VAR_KEYWORD for p in parameters.values())
    unknown = [name for name in names if name not in parameters and not takes_any]
    assert not unknown, f"{where}: {function.__qualname__} takes no {unknown}"


def test_the_lessons_notebook_calls_only_what_exists() -> None:
    sources = code_cells()
    assert len(sources) == 5
    namespace: dict[str, object] = {}
    checked = set()
    for index, source in enumerate(sources):
        tree = ast.parse(source)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import | ast.ImportFrom):
                exec(compile(ast.Module([node], []), f"cell {index}", "exec"), namespace)
        for node in ast.walk(tree):
            where = f"cell {index} line {getattr(node, 'lineno', '?')}"
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
                cls = VARIABLE_TYPES.get(node.value.id)
                if cls is not None:
                    assert node.attr in _members(cls), f"{where}: {cls.__name__}.{node.attr}?"
                    checked.add(f"{cls.__name__}.{node.attr}")
            if not isinstance(node, ast.Call):
                continue
            if isinstance(node.func, ast.Name) and callable(namespace.get(node.func.id)):
                _check_keywords(namespace[node.func.id], node, where)
                checked.add(node.func.id)
            elif isinstance(node.func, ast.Attribute) and isinstance(node.func.value, ast.Name):
                cls = VARIABLE_TYPES.get(node.func.value.id)
                if cls is not None:
                    _check_keywords(getattr(cls, node.func.attr), node, where)
    # The lessons' calls were all seen (the check above did not silently skip them).
    expected = ("show", "part_uncertainty", "Predictor.predict", "BodyPosterior.keypoints",
                "BodyPosterior.with_concentration", "BodyPosterior.vertex_uncertainty")  # fmt: skip
    for name in expected:
        assert name in checked, name
    assert "from_pretrained" in sources[0] and "evidence=False" in sources[3]
    assert "occluders=[shin_box]" in sources[1] and '"left_elbow", 10.0' in sources[2]
