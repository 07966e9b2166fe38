"""Every relative link in README.md and docs/**/*.md points at a file that exists, and every
``#anchor`` into a markdown file names one of its headings (GitHub's heading slugs)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^```.*?^```", re.S | re.M)
HEADING = re.compile(r"^#{1,6}\s+(.+?)\s*#*\s*$", re.M)


def markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def github_slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"`|\*\*|\*|\[|\]\([^)]*\)", "", heading).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors_of(path: Path) -> set[str]:
    text = FENCE.sub("", path.read_text())
    anchors: set[str] = set()
    for heading in HEADING.findall(text):
        slug = github_slug(heading)
        number = 0
        candidate = slug
        while candidate in anchors:  # repeated headings get -1, -2, ...
            number += 1
            candidate = f"{slug}-{number}"
        anchors.add(candidate)
    return anchors


def relative_links(path: Path) -> list[str]:
    text = FENCE.sub("", path.read_text())
    return [
        target
        for target in LINK.findall(text)
        if not re.match(r"[a-z][a-z0-9+.-]*:", target)  # http:, https:, mailto:
    ]


def test_the_link_pattern_finds_links_and_skips_urls() -> None:
    assert LINK.findall("see [a](docs/a.md#x) and ![b](figures/b.png)") == [
        "docs/a.md#x",
        "figures/b.png",
    ]
    assert github_slug("Several photos of one person: one combined shape") == (
        "several-photos-of-one-person-one-combined-shape"
    )


def test_every_relative_link_resolves() -> None:
    broken = []
    checked = 0
    for source in markdown_files():
        for target in relative_links(source):
            file_part, _, anchor = target.partition("#")
            destination = (source.parent / file_part).resolve() if file_part else source
            checked += 1
            if not destination.exists():
                broken.append(f"{source.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and destination.suffix == ".md" and anchor not in anchors_of(destination):
                broken.append(f"{source.relative_to(ROOT)}: {target} (no such heading)")
    assert checked > 50, "the link pattern found almost no links"
    assert not broken, "broken links:\n" + "\n".join(broken)
