"""Guards on packaging and CI wiring that a fresh clone depends on."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_source_package_is_listed_in_pyproject() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    package_dirs = config["package-dir"]
    found = set()
    for package, folder in package_dirs.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            relative = init.parent.relative_to(ROOT / folder)
            found.add(".".join((package, *relative.parts)) if relative.parts else package)
    assert found <= listed, f"packages missing from pyproject.toml: {sorted(found - listed)}"


def test_ci_runs_the_readme_test_command() -> None:
    readme = (ROOT / "README.md").read_text()
    match = re.search(r"<!-- test-command -->\s*```(?:bash|sh)?\n(.+?)\n```", readme, re.S)
    assert match, "README.md must show the test command after a <!-- test-command --> marker"
    command = match.group(1).strip()
    assert command in (ROOT / ".ci" / "run").read_text()


def test_the_readme_api_section_documents_what_researchers_asked_for() -> None:
    """Issue 58: what ``log_prob`` takes, ``part_uncertainty``, ``quality.low`` and
    ``person_box`` are in the README's API section (which stays short: ≤ 150 lines in all)."""
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 150
    api = readme[readme.index("## Python API") : readme.index("## Evaluate")]
    assert "log_prob(samples.body_pose, samples.betas)" in api
    assert ".body_pose (N, 23, 3, 3)" in api and ".betas (N, 10)" in api
    for name in ("part_uncertainty", "quality.low", ".person_box (x0, y0, x1, y1)"):
        assert name in api, name


def test_the_readme_quotes_no_sex_probability_of_the_shipped_photo() -> None:
    """Issue 58: the README's "female 56 %" went stale as the sex evidence changed; the Body
    section shows the current number, the README says where to look."""
    readme = (ROOT / "README.md").read_text()
    assert not re.search(r"\b(?:fe)?male \d+ ?%", readme)
