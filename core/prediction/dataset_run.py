"""``hkpd-predict`` over a whole dataset: the photos split among torchrun's processes, a run
that ``--resume`` finishes after any crash, and one index of every photo's result.

``torchrun --standalone --nproc_per_node N --no-python hkpd-predict PHOTOS... --out OUT``
starts N copies of ``hkpd-predict``; each reads its place from torchrun's variables
(:func:`hkpd.launch.detect_launch`) and takes every N-th photo of the sorted paths
(:meth:`Shard.own`), so the split is the same in every process and balanced by count. No
process group is made: the processes share nothing but the folder ``OUT``, and each writes
only its own files there. Alone (no torchrun) a process is rank 0 of 1 and takes every photo.

``OUT`` during a run::

    OUT/<name>/                  a photo's results: visible only once complete (written into
                                 OUT/.<name>.partial, then renamed)
    OUT/.hkpd-predict/part-<run>-<rank>.jsonl   each rank's index records, one line per photo
                                 (per person with --all-people), appended as they finish
    OUT/.hkpd-predict/done-<run>-<rank>         a rank finished its photos (its counts, JSON)
    OUT/index.jsonl              the index: the part files merged by rank 0 once every rank is
                                 done (and the parts of killed runs, on ``--resume``)

After a finished run ``OUT`` holds only result folders and ``index.jsonl``. ``--resume`` skips
every folder that is complete (it has its ``summary.json``: folders appear whole), removes what
a killed run left half-written, and tries the rest again, failures included.

Rank 0 draws the one progress bar (photos finished by all ranks, read from the part files) and
prints the final line. Under torchrun every process exits 0 once the run is complete, failed
photos included (they are in the index): a non-zero status would make torchrun stop the other
processes and report the whole launch as failed. A process that dies makes torchrun stop the
others (rank 0 waits for the done markers until then); ``--resume`` finishes the run.

An index record (:data:`INDEX_KEYS`): ``photo`` (the path relative to the folder given on the
command line, or as given for a file), ``folder`` (under ``OUT``), ``person`` (1, 2 ... with
``--all-people``, else None), ``status`` (``ok``, ``no person`` or ``error: ...``),
``quality`` and ``flags`` (summary.json's quality score and flags), ``sex_probabilities``,
``seconds`` (the photo's time), ``files``, ``rank`` and ``finished`` (UTC, ISO 8601).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import sys
import time
import uuid
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

import torch
from tqdm import tqdm

from hkpd.interrupts import deferred_interrupts, raise_if_interrupted
from hkpd.launch import Launch, detect_launch, local_world_size

INDEX_FILE = "index.jsonl"
WORK_FOLDER = ".hkpd-predict"
"""The run's working files under ``OUT`` (part files, done markers); removed after the merge."""
PARTIAL_SUFFIX = ".partial"
"""A folder being written is ``.<name>.partial`` beside ``<name>``."""
REPLACED_SUFFIX = ".replaced"
"""With ``--overwrite`` the old folder is ``.<name>.replaced`` until the new one is in place."""
COMPLETE_MARK = "summary.json"
"""The file that every complete result folder holds (written last, then the folder appears)."""
INDEX_KEYS = (
    "photo", "folder", "person", "status", "quality", "flags", "sex_probabilities", "seconds",
    "files", "rank", "finished",
)  # fmt: skip
POLL_S = 0.5
"""How often rank 0 looks at the other ranks' part files while it waits for them, seconds."""
RUN_VARIABLES = ("TORCHELASTIC_RUN_ID", "TORCHELASTIC_RESTART_COUNT", "MASTER_ADDR", "MASTER_PORT")
"""torchrun's variables that name one launch (the same in all its processes, also on several
machines): :attr:`Shard.run` is made from them."""


@dataclass(frozen=True)
class Shard:
    """This process's share of a run: which photos, how many threads, which device.

    Attributes:
        launch: rank, local rank and world size (:class:`hkpd.launch.Launch`).
        local_ranks: processes of the launch on this machine (``LOCAL_WORLD_SIZE``).
        run: a name of this launch shared by its processes (a new random one alone), which
            tells this run's part files from a killed run's.
    """

    launch: Launch = field(default_factory=Launch)
    local_ranks: int = 1
    run: str = field(default_factory=lambda: uuid.uuid4().hex[:12])

    @classmethod
    def from_environment(cls, environment: Mapping[str, str] | None = None) -> Shard:
        """The shard torchrun's variables describe (rank 0 of 1 without them).

        Raises:
            ValueError: torchrun's variables are incomplete or do not fit together.
        """
        environment = os.environ if environment is None else environment
        launch = detect_launch(environment)
        if not launch.distributed:
            return cls(launch)
        named = "|".join(environment.get(name, "") for name in RUN_VARIABLES)
        run = hashlib.sha1(named.encode()).hexdigest()[:12]
        return cls(launch, local_world_size(environment), run)

    @property
    def rank(self) -> int:
        return self.launch.rank

    @property
    def world_size(self) -> int:
        return self.launch.world_size

    def own(self, paths: Sequence[Path]) -> list[int]:
        """Indices into ``paths`` of this rank's photos: every ``world_size``-th of the paths
        sorted as text, from the ``rank``-th (the ranks' counts differ by one at most), in the
        order given (alone: all of them, as given)."""
        order = sorted(range(len(paths)), key=lambda index: paths[index].as_posix())
        return sorted(order[self.rank :: self.world_size])

    def cpu_threads(self, cores: int) -> int:
        """Torch threads of this process: the machine's ``cores`` shared by its local ranks."""
        return max(1, cores // self.local_ranks)

    def device(self, requested: str) -> str:
        """The device this rank predicts on: for ``auto`` with a GPU, or ``cuda``, the GPU
        ``cuda:LOCAL_RANK`` (modulo the GPUs torch sees, so ranks may share one); else as
        ``requested``. Alone, ``requested`` as it is."""
        if not self.launch.distributed or requested not in ("auto", "cuda"):
            return requested
        count = torch.cuda.device_count()
        if count == 0:
            return "cpu" if requested == "auto" else requested
        return f"cuda:{self.launch.local_rank % count}"

    def configure_threads(self, device: str) -> None:
        """Under torchrun on the CPU: give torch this rank's share of the cores."""
        if self.launch.distributed and not device.startswith("cuda"):
            torch.set_num_threads(self.cpu_threads(len(os.sched_getaffinity(0))))


def add_dataset_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--resume`` and ``-v/--verbose`` (whole datasets, docs/prediction.md)."""
    group = parser.add_argument_group('whole datasets (docs/prediction.md, "Whole datasets")')
    group.add_argument(
        "--resume",
        action="store_true",
        help="finish an earlier run into --out: skip every photo whose results are complete, "
        "remove what a killed run left half-written, predict the rest (failures again) and "
        f"merge everything into --out/{INDEX_FILE}",
    )
    group.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="under torchrun, every process prints a line per photo (by default only the "
        "first one prints: one progress bar for all, and the failures)",
    )


def photo_labels(inputs: Sequence[str | os.PathLike[str]], images: Sequence[Path]) -> list[str]:
    """Each image's ``photo`` in the index: its path relative to the folder given on the
    command line that it was found in (POSIX separators), or the path as given for a file."""
    folders = [Path(item) for item in inputs if Path(item).is_dir()]
    labels = []
    for image in images:
        label = image.as_posix()
        for folder in folders:
            if image.is_relative_to(folder) and image != folder:
                label = image.relative_to(folder).as_posix()
                break
        labels.append(label)
    return labels


def now_text() -> str:
    """The present moment as the index writes it (UTC, ISO 8601 with milliseconds)."""
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def is_complete(folder: Path) -> bool:
    """Whether ``folder`` holds a finished photo's results (folders appear only when whole)."""
    return (folder / COMPLETE_MARK).is_file()


def result_record(folder: Path, name: str, photo: str, person: int | None, rank: int) -> dict:
    """The index record of the complete result folder ``folder`` (``name`` under ``OUT``),
    read from its ``summary.json``."""
    summary = json.loads((folder / COMPLETE_MARK).read_text())
    quality = summary.get("quality") or {}
    return {
        "photo": photo, "folder": name, "person": person, "status": "ok",
        "quality": quality.get("score"), "flags": list(quality.get("flags") or []),
        "sex_probabilities": summary.get("sex_probabilities"),
        "seconds": (summary.get("timings") or {}).get("total_s"),
        "files": len(summary.get("files") or []), "rank": rank, "finished": now_text(),
    }  # fmt: skip


def failure_record(
    name: str, photo: str, person: int | None, status: str, seconds: float, rank: int
) -> dict:
    """The index record of a photo (or person) that failed: ``status`` is ``no person`` or
    ``error: <what went wrong>``."""
    return {
        "photo": photo, "folder": name, "person": person, "status": status, "quality": None,
        "flags": [], "sex_probabilities": None, "seconds": round(seconds, 4), "files": 0,
        "rank": rank, "finished": now_text(),
    }  # fmt: skip


def read_records(path: Path) -> list[dict]:
    """The records of a JSON-lines file; a line cut short by a killed process, or anything
    else that is not a record, is left out."""
    records = []
    try:
        text = path.read_text()
    except (FileNotFoundError, UnicodeDecodeError):
        return records
    for line in text.splitlines():
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(record, dict) and isinstance(record.get("folder"), str):
            records.append(record)
    return records


def latest_records(records: Iterable[dict]) -> list[dict]:
    """One record per folder, the last finished (a later one in ``records`` wins a tie),
    sorted by folder."""
    latest: dict[str, dict] = {}
    for record in records:
        kept = latest.get(record["folder"])
        if kept is None or str(record.get("finished", "")) >= str(kept.get("finished", "")):
            latest[record["folder"]] = record
    return [latest[name] for name in sorted(latest)]


def merge_index(out: Path, skip_run: str | None = None) -> list[dict]:
    """Merge the part files under ``out`` (all, or all but run ``skip_run``'s, which are
    still being written) into ``out/index.jsonl``, written beside and renamed into place; the
    merged parts and done markers are removed, the work folder too once empty. Returns the
    index's records."""
    work = out / WORK_FOLDER
    index = out / INDEX_FILE
    parts = sorted(work.glob("part-*.jsonl"), key=lambda path: path.stat().st_mtime)
    parts = [path for path in parts if skip_run is None or f"-{skip_run}-" not in path.name]
    records = latest_records(
        [*read_records(index), *(record for part in parts for record in read_records(part))]
    )
    if records:
        written = out / f".{INDEX_FILE}.writing"
        with written.open("w") as stream:
            stream.writelines(json.dumps(record) + "\n" for record in records)
            stream.flush()
            os.fsync(stream.fileno())
        with deferred_interrupts():
            written.replace(index)
    for path in [*parts, *work.glob("done-*")]:
        if skip_run is None or f"-{skip_run}-" not in path.name:
            path.unlink(missing_ok=True)
    if work.is_dir() and not any(work.iterdir()):
        work.rmdir()
    return records


def remove_leftovers(out: Path, names: Iterable[str]) -> int:
    """Remove what killed runs left of the folders ``names`` under ``out``: half-written
    ``.<name>.partial`` folders (also of ``--all-people``'s person folders inside) and old
    folders an ``--overwrite`` was replacing; returns how many were removed."""
    removed = 0
    for name in names:
        folder = out / name
        leftovers = [folder.with_name(f".{folder.name}{PARTIAL_SUFFIX}"),
                     folder.with_name(f".{folder.name}{REPLACED_SUFFIX}")]  # fmt: skip
        if folder.is_dir() and not is_complete(folder):
            leftovers += [*folder.glob(f".*{PARTIAL_SUFFIX}"), *folder.glob(f".*{REPLACED_SUFFIX}")]
        for path in leftovers:
            if path.exists():
                shutil.rmtree(path, ignore_errors=True)
                removed += 1
    return removed


@dataclass
class RunCounts:
    """What a run did, over all its ranks (rank 0 counts after the merge).

    Attributes:
        photos, photos_done, photos_failed: photos of the run; those with every result ok;
            those with a failed one (or no record, which a finished run does not leave).
        people, people_done: with ``--all-people``, the people found and predicted; else None.
        skipped: results that were complete already (``--resume``).
        files: files in the run's result folders.
    """

    photos: int = 0
    photos_done: int = 0
    photos_failed: int = 0
    people: int | None = None
    people_done: int | None = None
    skipped: int = 0
    files: int = 0

    def describe(self) -> str:
        """E.g. ``2 of 2 photos done, 0 failed (8 of 8 people)``."""
        line = f"{self.photos_done} of {self.photos} photos done, {self.photos_failed} failed"
        if self.people is not None:
            line += f" ({self.people_done} of {self.people} people)"
        if self.skipped:
            line += f", {self.skipped} complete before this run"
        return line


def run_counts(
    records: Sequence[dict], names: Sequence[str], all_people: bool, skipped: int = 0
) -> RunCounts:
    """:class:`RunCounts` of the photos ``names`` (their folders under ``OUT``) from the index
    ``records`` (records of other folders, from earlier runs into ``OUT``, are not counted)."""
    by_photo: dict[str, list[dict]] = {name: [] for name in names}
    for record in records:
        top = record["folder"].split("/")[0] if all_people else record["folder"]
        if top in by_photo:
            by_photo[top].append(record)
    counts = RunCounts(photos=len(by_photo), skipped=skipped)
    for photo_records in by_photo.values():
        ok = [record for record in photo_records if record.get("status") == "ok"]
        if photo_records and len(ok) == len(photo_records):
            counts.photos_done += 1
        else:
            counts.photos_failed += 1
        counts.files += sum(int(record.get("files") or 0) for record in ok)
    if all_people:
        people = [r for rs in by_photo.values() for r in rs if r.get("person") is not None]
        counts.people = len(people)
        counts.people_done = sum(record.get("status") == "ok" for record in people)
    return counts


class DatasetRun:
    """One rank's part in a run writing into ``out``: what is complete, its part file, and on
    rank 0 the wait for the other ranks and the merge into the index.

    Args:
        out: the output folder.
        shard: this process's share (:meth:`Shard.from_environment`).
        names: every photo's folder name under ``out``, all ranks' (:func:`output_names`).
        labels: every photo's ``photo`` in the index, in the order of ``names``.
        resume: skip complete folders, remove leftovers (``--resume``).
    """

    def __init__(
        self, out: Path, shard: Shard, names: Sequence[str], labels: Sequence[str], resume: bool
    ) -> None:
        self.out, self.shard, self.resume = out, shard, resume
        self.names = list(names)
        self.labels = dict(zip(names, labels, strict=True))
        self.skipped = 0
        self.photos_finished = 0
        """This process's photos finished so far (every person of them)."""
        self._part: IO[str] | None = None
        self.work = out / WORK_FOLDER

    @property
    def part_path(self) -> Path:
        return self.work / f"part-{self.shard.run}-{self.shard.rank}.jsonl"

    def begin(self, own_names: Sequence[str]) -> None:
        """On ``--resume``: remove the leftovers of this rank's folders; rank 0 also merges
        the part files of killed runs into the index."""
        if not self.resume:
            return
        remove_leftovers(self.out, own_names)
        if self.shard.rank != 0:
            return
        (self.out / f".{INDEX_FILE}.writing").unlink(missing_ok=True)  # a merge that was killed
        if self.work.is_dir():
            merge_index(self.out, skip_run=self.shard.run)

    def complete(self, name: str) -> bool:
        """Whether ``--resume`` skips the folder ``name``: it is complete. Records it."""
        folder = self.out / name
        if not (self.resume and is_complete(folder)):
            return False
        self.skipped += 1
        self._write(result_record(folder, name, self._photo(name), _person(name), self.shard.rank))
        return True

    def record(self, name: str, error: str | None, no_person: bool, seconds: float) -> dict:
        """Append the record of the folder ``name`` just written (``error`` None) or of a
        failure to this rank's part file (flushed and synced: a kill loses nothing written)."""
        rank = self.shard.rank
        if error is None:
            record = result_record(self.out / name, name, self._photo(name), _person(name), rank)
        else:
            status = "no person" if no_person else f"error: {error}"
            record = failure_record(name, self._photo(name), _person(name), status, seconds, rank)
        self._write(record)
        return record

    def finish(self, progress: RunProgress | None, all_people: bool) -> RunCounts | None:
        """This rank is done: close its part file and say so; rank 0 waits for the others
        (updating ``progress``), merges the index and returns the run's counts (None on the
        other ranks)."""
        self._close()
        self.work.mkdir(parents=True, exist_ok=True)
        marker = self.work / f"done-{self.shard.run}-{self.shard.rank}"
        marker.write_text(json.dumps({"skipped": self.skipped}))
        if self.shard.rank != 0:
            return None
        markers = [self.work / f"done-{self.shard.run}-{r}" for r in range(self.shard.world_size)]
        while not all(path.exists() for path in markers):
            raise_if_interrupted()
            if progress is not None:
                progress.refresh()
            time.sleep(POLL_S)
        if progress is not None:
            progress.refresh()
        skipped = sum(json.loads(path.read_text()).get("skipped", 0) for path in markers)
        with deferred_interrupts():
            records = merge_index(self.out)
        return run_counts(records, self.names, all_people, skipped)

    def interrupted(self) -> None:
        """After a Ctrl-C: close the part file; alone, also merge it into the index (under
        torchrun the other ranks may still write: ``--resume`` merges)."""
        self._close()
        if self.shard.world_size == 1 and self.work.is_dir():
            with deferred_interrupts():
                merge_index(self.out)

    def _photo(self, name: str) -> str:
        return self.labels.get(name.split("/")[0], name)

    def _write(self, record: dict) -> None:
        if self._part is None:
            self.work.mkdir(parents=True, exist_ok=True)
            self._part = self.part_path.open("a")
        self._part.write(json.dumps(record) + "\n")
        self._part.flush()
        os.fsync(self._part.fileno())

    def _close(self) -> None:
        if self._part is not None:
            self._part.close()
            self._part = None


def _person(name: str) -> int | None:
    """The person number of an ``--all-people`` folder ``PHOTO/person_K``; None otherwise."""
    parent, _, last = name.rpartition("/")
    if parent and last.startswith("person_") and last[len("person_") :].isdigit():
        return int(last[len("person_") :])
    return None


class RunProgress:
    """The run's progress bar: alone, over this process's photos; under torchrun, on rank 0
    only, over every rank's photos (counted from the part files), with the failures of the
    other ranks said above it; per-photo lines from every rank only with ``verbose``.

    Args:
        run: the run (its shard and work folder).
        own_photos: photos this process predicts.
        program: the bar's label.
        verbose: under torchrun, every rank prints its per-photo lines.
    """

    def __init__(self, run: DatasetRun, own_photos: int, program: str, verbose: bool) -> None:
        self.run, self.verbose, self.program = run, verbose, program
        self.alone = run.shard.world_size == 1
        self._offsets: dict[Path, int] = {}
        self._photos_seen: set[str] = set()
        self.bar: Any = None
        if self.alone or run.shard.rank == 0:
            total = own_photos if self.alone else len(run.names)
            self.bar = tqdm(total=total, desc=program, unit="photo", file=sys.stderr)

    def photo_done(self) -> None:
        """One of this process's photos (all its people) is finished."""
        self.run.photos_finished += 1
        if self.alone:
            self.bar.update(1)
        else:
            self.refresh()

    def say(self, line: str, failed: bool) -> None:
        """A per-photo line (``failed``: to stderr): printed alone, by rank 0 for its own
        failures, and by every rank with ``verbose`` (with its rank in front)."""
        stream = sys.stderr if failed else sys.stdout
        if self.alone:
            tqdm.write(line, file=stream)
        elif self.verbose:
            tqdm.write(f"[rank {self.run.shard.rank}] {line}", file=stream)
        elif failed and self.run.shard.rank == 0:
            tqdm.write(line, file=stream)

    def refresh(self) -> None:
        """Rank 0 under torchrun: count the photos finished by all ranks from the new lines of
        this run's part files; say the other ranks' failures (without ``verbose``)."""
        if self.bar is None or self.alone:
            return
        for part in self.run.work.glob(f"part-{self.run.shard.run}-*.jsonl"):
            for record in self._new_records(part):
                self._photos_seen.add(record["folder"].split("/")[0])
                status = str(record.get("status", "ok"))
                if status != "ok" and record.get("rank") != 0 and not self.verbose:
                    said = status.removeprefix("error: ") if status != "no person" else status
                    tqdm.write(f"{self.program}: FAILED {record.get('photo')}: {said}",
                               file=sys.stderr)  # fmt: skip
        self.bar.n = len(self._photos_seen)
        self.bar.refresh()

    def _new_records(self, part: Path) -> list[dict]:
        """The whole lines added to ``part`` since the last look."""
        offset = self._offsets.get(part, 0)
        with part.open("rb") as stream:
            stream.seek(offset)
            data = stream.read()
        end = data.rfind(b"\n") + 1
        self._offsets[part] = offset + end
        records = []
        for line in data[:end].splitlines():
            try:
                records.append(json.loads(line))
            except json.JSONDecodeError:
                continue
        return [record for record in records if isinstance(record, dict) and "folder" in record]

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
