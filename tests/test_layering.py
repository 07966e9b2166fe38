"""The shape of the code (docs/architecture.md): who may import whom, where imports sit, and how
long a function may grow."""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROOT_PACKAGE = "hkpd"
"""``core/__init__.py``, the root package (its lazy public names), under its own name."""

ALLOWED_IMPORTS: dict[str, frozenset[str]] = {
    name: frozenset(allowed)
    for name, allowed in {
        # shared conventions and arithmetic
        "alignment": (),
        "assets": (),
        "camera_conventions": (),
        "coco_keypoints": (),
        "cpu_allocator": (),
        "devices": (),
        "interrupts": (),
        "kinematic_tree": (),
        "launch": (),
        "model_runtime": ("assets",),
        "uncertainty": (),
        "mirror_symmetry": ("kinematic_tree",),
        "stated_body": (),
        "body_flags": ("stated_body",),
        # the model
        "distributions": ("kinematic_tree",),
        "body": ("assets", "coco_keypoints", "kinematic_tree", "stated_body"),
        "proxy": (),
        "rendering": ("camera_conventions",),
        "network": ("camera_conventions", "distributions", "kinematic_tree", "proxy"),
        "conditioning": (
            "body", "camera_conventions", "coco_keypoints", "distributions", "stated_body",
        ),
        "prediction": (
            "assets", "body", "body_flags", "camera_conventions", "coco_keypoints",
            "conditioning", "devices", "model_runtime", "stated_body",
            "distributions", "interrupts", "kinematic_tree", "launch", "mirror_symmetry", "network",
            "proxy", "rendering", "uncertainty",
        ),
        # the training side
        "poses": ("body", "kinematic_tree", "mirror_symmetry"),
        "synthesis": (
            "body", "camera_conventions", "coco_keypoints", "cpu_allocator", "kinematic_tree",
            "poses", "proxy", "rendering",
        ),
        "evaluation": (
            "alignment", "body", "camera_conventions", "coco_keypoints", "conditioning",
            "devices", "distributions", "interrupts", "kinematic_tree", "network", "poses",
            "prediction", "proxy", "synthesis", "uncertainty",
        ),
        "training": (
            "alignment", "body", "camera_conventions", "cpu_allocator", "devices",
            "distributions", "evaluation", "interrupts", "kinematic_tree", "launch", "network",
            "poses", "proxy", "synthesis",
        ),
        # the browser app: the model and the prediction, never the training side
        "explorer": (
            "assets", "body", "body_flags", "camera_conventions", "coco_keypoints",
            "distributions", "stated_body",
            "interrupts", "kinematic_tree", "prediction", "rendering", "uncertainty",
        ),
        ROOT_PACKAGE: ("body", "prediction"),
    }.items()
}  # fmt: skip
"""The ``hkpd`` packages (and top-level modules) each one may import, besides itself: the table
of docs/architecture.md, as measured from the code. An import outside it is a new dependency
to decide on (and to add to both places), not something to slip in."""

ENTRY_MODULES: dict[str, str] = {
    "core/__init__.py": "the root package's lazy `hkpd.Predictor` / `hkpd.BodyModel`: "
    "`import hkpd` alone must not load torch, OpenCV and LiteRT",
    "core/evaluation/evidence_tuning.py": "the `hkpd-tune-evidence` entry point: the predictor, "
    "the detector and the data generator load after the arguments are read (fast --help)",
}
"""Modules besides ``*/cli.py`` whose functions may import other ``hkpd`` packages, and why."""

MAX_FUNCTION_LINES = 80
TABLE_HEADING = "## Who may import whom"


def _source_files() -> Iterator[tuple[str, Path]]:
    """``(package, path)`` of every module of ``core/`` (hkpd) and ``explorer/`` (hkpd.explorer)."""
    for folder, package in ((ROOT / "core", None), (ROOT / "explorer", "explorer")):
        for path in sorted(folder.rglob("*.py")):
            top = package or path.relative_to(folder).parts[0].removesuffix(".py")
            yield (ROOT_PACKAGE if top == "__init__" else top), path


def _imports(path: Path) -> Iterator[tuple[ast.stmt, str, bool]]:
    """``(statement, imported hkpd package, inside a function)`` for every ``hkpd`` import of
    ``path``; ``from hkpd import x`` counts as importing ``x`` when ``x`` is a package."""
    tree = ast.parse(path.read_text())

    def visit(node: ast.AST, in_function: bool) -> Iterator[tuple[ast.stmt, str, bool]]:
        for child in ast.iter_child_nodes(node):
            inside = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if isinstance(child, ast.ImportFrom):
                assert child.level == 0, f"{path}:{child.lineno}: write the import absolute"
                if child.module == ROOT_PACKAGE:
                    for alias in child.names:
                        known = alias.name in ALLOWED_IMPORTS
                        yield child, alias.name if known else ROOT_PACKAGE, inside
                elif child.module and child.module.startswith(f"{ROOT_PACKAGE}."):
                    yield child, child.module.split(".")[1], inside
            elif isinstance(child, ast.Import):
                for alias in child.names:
                    if alias.name == ROOT_PACKAGE or alias.name.startswith(f"{ROOT_PACKAGE}."):
                        parts = alias.name.split(".")
                        yield child, parts[1] if len(parts) > 1 else ROOT_PACKAGE, inside
            yield from visit(child, inside)

    yield from visit(tree, False)


def _where(path: Path, node: ast.AST) -> str:
    return f"{path.relative_to(ROOT)}:{node.lineno}"


def test_every_import_is_an_allowed_edge() -> None:
    problems = []
    for package, path in _source_files():
        assert package in ALLOWED_IMPORTS, f"{path}: declare package {package!r} in ALLOWED_IMPORTS"
        for node, imported, _ in _imports(path):
            if imported != package and imported not in ALLOWED_IMPORTS[package]:
                problems.append(f"{_where(path, node)}: {package} imports hkpd.{imported}")
    assert not problems, "imports outside docs/architecture.md's graph:\n" + "\n".join(problems)


def test_every_allowed_edge_is_used() -> None:
    """The graph is drawn from the code: an edge nothing uses any more leaves the table."""
    used: dict[str, set[str]] = {package: set() for package in ALLOWED_IMPORTS}
    for package, path in _source_files():
        used[package] |= {imported for _, imported, _ in _imports(path)} - {package}
    unused = {p: sorted(ALLOWED_IMPORTS[p] - used[p]) for p in ALLOWED_IMPORTS}
    unused = {package: names for package, names in unused.items() if names}
    assert not unused, f"remove from the table (and the docs): {unused}"


def test_the_graph_has_no_cycle() -> None:
    done: set[str] = set()

    def visit(package: str, path: tuple[str, ...]) -> None:
        assert package not in path, f"import cycle: {' -> '.join((*path, package))}"
        if package not in done:
            for imported in ALLOWED_IMPORTS[package]:
                visit(imported, (*path, package))
            done.add(package)

    for package in ALLOWED_IMPORTS:
        assert ALLOWED_IMPORTS[package] <= ALLOWED_IMPORTS.keys(), package
        visit(package, ())


def test_the_architecture_table_lists_the_same_graph() -> None:
    """docs/architecture.md's table under "Who may import whom" names exactly the packages
    declared here (first column the package, last column what it may import)."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    section = text.split(f"\n{TABLE_HEADING}\n", 1)[1].split("\n## ", 1)[0]
    documented: dict[str, frozenset[str]] = {}
    for line in section.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.startswith("|") and re.fullmatch(r"`[\w.]+`", cells[0]):
            documented[cells[0].strip("`")] = frozenset(re.findall(r"`(\w+)`", cells[-1]))
    differing = {
        name: (sorted(documented.get(name, ())), sorted(ALLOWED_IMPORTS.get(name, ())))
        for name in documented.keys() | ALLOWED_IMPORTS.keys()
        if documented.get(name) != ALLOWED_IMPORTS.get(name)
    }
    assert not differing, f"docs/architecture.md vs ALLOWED_IMPORTS (docs, test): {differing}"


def test_function_level_imports_between_packages_only_in_entry_modules() -> None:
    problems = []
    for package, path in _source_files():
        relative = path.relative_to(ROOT).as_posix()
        if path.name == "cli.py" or relative in ENTRY_MODULES:
            continue
        for node, imported, in_function in _imports(path):
            if in_function and imported != package:
                problems.append(f"{_where(path, node)}: hkpd.{imported} imported in a function")
    assert not problems, (
        "move these imports to the top of the module (type-only ones under TYPE_CHECKING):\n"
        + "\n".join(problems)
    )


def test_entry_modules_exist() -> None:
    for relative in ENTRY_MODULES:
        assert (ROOT / relative).is_file(), f"ENTRY_MODULES names a missing {relative}"


def test_no_function_is_longer_than_the_limit() -> None:
    long = []
    for _, path in _source_files():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{_where(path, node)} {node.name}: {lines} lines")
    assert not long, f"split into named steps (at most {MAX_FUNCTION_LINES} lines):\n" + "\n".join(
        long
    )
