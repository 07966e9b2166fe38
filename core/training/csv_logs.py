"""The run folder's CSV logs: rows appended as training goes, checked and cut on resume."""

from __future__ import annotations

import csv
from pathlib import Path

from hkpd.training.schedule import LOSS_TERMS


def append_row(path: Path, row: dict[str, float]) -> None:
    """Append ``row``; a row with columns the file lacks (a run resumed by a newer version that
    logs more metrics) rewrites the file with the extra columns, left empty in older rows."""
    columns = list(row)
    if path.exists():
        with path.open(newline="") as handle:
            header = next(csv.reader(handle), [])
        if header and not set(columns) <= set(header):
            with path.open(newline="") as handle:
                rows = list(csv.DictReader(handle))
            header += [column for column in columns if column not in header]
            with path.open("w", newline="") as handle:
                writer = csv.DictWriter(handle, fieldnames=header)
                writer.writeheader()
                writer.writerows(rows)
        columns = header or columns
    new = not path.exists() or path.stat().st_size == 0
    with path.open("a", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        if new:
            writer.writeheader()
        writer.writerow(row)


def check_log(path: Path) -> None:
    """Raise a ValueError when a log to resume has rows but no ``step`` column."""
    if not path.exists():
        return
    with path.open(newline="") as handle:
        header = next(csv.reader(handle), [])
        has_rows = next(csv.reader(handle), None) is not None
    if has_rows and "step" not in header:
        raise ValueError(
            f"--resume: {path} has no 'step' column, so it was not written by hkpd-train; "
            "move it away to continue"
        )


def truncate_log(path: Path, last_step: int) -> None:
    """Drop rows after ``last_step`` (a resumed run rewrites them)."""
    if not path.exists():
        return
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        return
    kept = [row for row in rows if float(row["step"]) <= last_step]
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(kept)


LOG_TERMS = (*LOSS_TERMS, "total")


def complete_row(row: dict[str, float]) -> dict[str, float]:
    """Every loss column in a fixed order (inactive terms empty), so CSV columns never shift."""
    fixed = {key: row[key] for key in ("step", "seconds", "samples_per_second", "learning_rate")}
    return fixed | {name: row.get(name, "") for name in LOG_TERMS}
