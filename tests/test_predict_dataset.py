"""hkpd-predict over whole datasets (issue 60): the split among torchrun's processes, the index,
``--resume`` after a kill at any moment, and photos counted as photos with ``--all-people``.

The ranks run as torchrun would start them, with ``WORLD_SIZE``/``RANK``/``LOCAL_RANK`` (and the
run's name) in their environment: in this process one after another (the ranks share nothing
but the output folder, so rank 1 can finish before rank 0 starts), or forked, to be killed.
"""

from __future__ import annotations

import contextlib
import io
import json
import multiprocessing
import os
import random
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from test_predict_cli import TruthDetector, checkpoint, scene  # noqa: F401 (fixtures)
from test_predict_cli_all_people import TwoPeopleDetector

from hkpd.launch import Launch
from hkpd.prediction import cli
from hkpd.prediction.cli import PhotoResult
from hkpd.prediction.dataset_run import (
    INDEX_FILE,
    INDEX_KEYS,
    WORK_FOLDER,
    Shard,
    latest_records,
    photo_labels,
    read_records,
    run_counts,
)
from hkpd.prediction.image_input import ImageInputError


def _launch_environment(rank: int, world_size: int, run: str) -> dict[str, str]:
    """What torchrun puts in the environment of rank ``rank`` (one machine)."""
    return {
        "RANK": str(rank), "LOCAL_RANK": str(rank), "WORLD_SIZE": str(world_size),
        "LOCAL_WORLD_SIZE": str(world_size), "TORCHELASTIC_RUN_ID": run,
        "TORCHELASTIC_RESTART_COUNT": "0", "MASTER_ADDR": "127.0.0.1", "MASTER_PORT": "29500",
    }  # fmt: skip


def _quiet_main(arguments: list[object]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main([str(argument) for argument in arguments])
    return code, out.getvalue(), err.getvalue()


def test_the_split_is_balanced_deterministic_and_covers_every_photo() -> None:
    paths = [Path(f"photos/{name}.jpg") for name in "qwertyuiopasdfghjklzx"]  # 21, unsorted
    shares = [Shard(Launch(rank, rank, 4), 4, "run").own(paths) for rank in range(4)]
    assert sorted(index for share in shares for index in share) == list(range(21))
    assert sorted(len(share) for share in shares) == [5, 5, 5, 6]
    by_name = sorted(range(21), key=lambda i: paths[i].as_posix())
    assert shares[1] == sorted(by_name[1::4])  # every 4th of the sorted paths, from the 2nd
    assert Shard().own(paths) == list(range(21))  # alone: all of them, as given
    assert shares == [Shard(Launch(r, r, 4), 4, "other").own(paths) for r in range(4)]


def test_a_shard_is_read_from_torchruns_environment() -> None:
    alone = Shard.from_environment({})
    assert alone.world_size == 1 and alone.rank == 0 and alone.device("auto") == "auto"
    assert Shard.from_environment({}).run != alone.run  # a new name for every run alone
    first = Shard.from_environment(_launch_environment(1, 2, "job-7"))
    second = Shard.from_environment(_launch_environment(0, 2, "job-7"))
    assert (first.rank, first.world_size, first.local_ranks) == (1, 2, 2)
    assert first.run == second.run != Shard.from_environment(_launch_environment(0, 2, "job-8")).run
    assert first.cpu_threads(2) == 1 and first.cpu_threads(16) == 8 and first.cpu_threads(1) == 1
    assert first.device("cpu") == "cpu"
    with pytest.raises(ValueError, match="lacks LOCAL_RANK"):
        Shard.from_environment({"RANK": "0", "WORLD_SIZE": "2"})


def test_photo_labels_are_relative_to_the_folder_given(tmp_path: Path) -> None:
    inside = tmp_path / "set" / "a" / "b.jpg"
    inside.parent.mkdir(parents=True)
    alone = tmp_path / "c.jpg"
    labels = photo_labels([tmp_path / "set", alone], [inside, alone])
    assert labels == ["a/b.jpg", alone.as_posix()]


def test_the_latest_record_of_a_folder_wins_and_cut_lines_are_left_out(tmp_path: Path) -> None:
    part = tmp_path / "part.jsonl"
    day = "2026-01-01T00:00"
    lines = [{"folder": "a", "status": "error: x", "finished": f"{day}:01.000+00:00"},
             {"folder": "a", "status": "ok", "finished": f"{day}:02.000+00:00"},
             {"folder": "b", "status": "ok", "finished": f"{day}:00.000+00:00"}]  # fmt: skip
    part.write_text("".join(json.dumps(line) + "\n" for line in lines) + '{"folder": "c", "sta')
    records = latest_records(read_records(part))
    assert [(r["folder"], r["status"]) for r in records] == [("a", "ok"), ("b", "ok")]
    counts = run_counts(records, ["a", "b", "c"], all_people=False)
    assert (counts.photos, counts.photos_done, counts.photos_failed) == (3, 2, 1)


@pytest.fixture
def tiny_predictor_factory(scene):  # noqa: F811
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    def factory(model, device):
        network, _ = load_network(model, "cpu")
        return Predictor(network, "cpu", detector=TruthDetector(scene.keypoints2d))

    return factory


def test_two_ranks_write_what_one_process_writes_bit_for_bit(
    tmp_path, scene, checkpoint, tiny_predictor_factory, monkeypatch  # noqa: F811
) -> None:  # fmt: skip
    photos = tmp_path / "photos"
    (photos / "more").mkdir(parents=True)
    for name in ("b_person.png", "more/a_person.png", "c_person.png"):
        Image.fromarray(scene.image).save(photos / name)
    (photos / "damaged.jpg").write_bytes(b"\xff\xd8\xff\xe0 not a whole jpeg" * 20)
    monkeypatch.setattr(cli, "load_predictor", tiny_predictor_factory)
    common = ["--model", checkpoint, "--samples", "2", "--uncertainty-samples", "4",
              "--format", "npz", "--seed", "5"]  # fmt: skip
    alone = _quiet_main([photos, "--out", tmp_path / "alone", *common])
    assert alone[0] == 1 and "3 of 4 photos done, 1 failed" in alone[1]
    lines = {}
    for rank in (1, 0):  # rank 1 first: rank 0 waits for the others, then merges the index
        for key, value in _launch_environment(rank, 2, "test-run").items():
            monkeypatch.setenv(key, value)
        code, lines[rank], _ = _quiet_main([photos, "--out", tmp_path / "ranks", *common])
        assert code == 0  # under torchrun a complete run exits 0 (failures are in the index)
    assert lines[1] == "" and "3 of 4 photos done, 1 failed" in lines[0]
    for name in ("b_person", "a_person", "c_person"):
        one = np.load(tmp_path / "alone" / name / "prediction.npz")
        two = np.load(tmp_path / "ranks" / name / "prediction.npz")
        assert sorted(one.files) == sorted(two.files)
        for key in one.files:  # bit-identical arrays: the seeds depend on neither rank nor order
            assert one[key].tobytes() == two[key].tobytes(), (name, key)
    left = sorted(path.name for path in (tmp_path / "ranks").iterdir())
    assert left == ["a_person", "b_person", "c_person", INDEX_FILE]
    index = read_records(tmp_path / "ranks" / INDEX_FILE)
    assert sorted({record["rank"] for record in index}) == [0, 1]
    assert all(tuple(record) == INDEX_KEYS for record in index)
    by_photo = {record["photo"]: record for record in index}
    assert sorted(by_photo) == ["b_person.png", "c_person.png", "damaged.jpg", "more/a_person.png"]
    assert by_photo["damaged.jpg"]["status"].startswith("error: ")
    reference = {
        record["photo"]: record for record in read_records(tmp_path / "alone" / INDEX_FILE)
    }
    for photo, record in by_photo.items():
        for key in ("folder", "status", "quality", "flags", "sex_probabilities", "files"):
            assert record[key] == reference[photo][key], (photo, key)
    for key in _launch_environment(0, 2, "-"):  # alone again: --resume skips the complete ones
        monkeypatch.delenv(key)
    summaries = {p: p.stat().st_mtime_ns for p in (tmp_path / "ranks").glob("*/summary.json")}
    code, out, _ = _quiet_main([photos, "--out", tmp_path / "ranks", *common, "--resume"])
    assert code == 1 and "3 of 4 photos done, 1 failed, 3 complete before this run;" in out
    assert summaries == {p: p.stat().st_mtime_ns for p in summaries}  # nothing written again
    assert len(read_records(tmp_path / "ranks" / INDEX_FILE)) == 4


def test_all_people_counts_photos_not_people(
    tmp_path, scene, checkpoint, monkeypatch  # noqa: F811
) -> None:  # fmt: skip
    from hkpd.network.checkpoint import load_network
    from hkpd.prediction.predictor import Predictor

    def factory(model, device):
        network, _ = load_network(model, "cpu")
        return Predictor(network, "cpu", detector=TwoPeopleDetector(scene.keypoints2d))

    monkeypatch.setattr(cli, "load_predictor", factory)
    for name in ("one.png", "two.png"):
        Image.fromarray(scene.image).save(tmp_path / name)
    Image.new("RGB", (200, 300), (128, 128, 128)).save(tmp_path / "nobody.png")
    photos = [tmp_path / name for name in ("one.png", "two.png", "nobody.png")]
    common = ["--model", checkpoint, "--samples", "0", "--uncertainty-samples", "4",
              "--format", "npz", "--all-people", "--out", tmp_path / "out"]  # fmt: skip
    code, out, err = _quiet_main([*photos, *common])
    assert code == 1
    assert "2 of 3 photos done, 1 failed (4 of 4 people)" in out.splitlines()[-1]
    assert "3/3" in err and "4/4" not in err  # the bar counts photos too
    index = read_records(tmp_path / "out" / INDEX_FILE)
    assert [(r["folder"], r["person"], r["status"]) for r in index] == [
        ("nobody", None, "no person"), ("one/person_1", 1, "ok"), ("one/person_2", 2, "ok"),
        ("two/person_1", 1, "ok"), ("two/person_2", 2, "ok"),
    ]  # fmt: skip


def test_resume_refuses_overwrite_and_a_plain_rerun_points_to_it(tmp_path, capsys) -> None:
    assert cli.main(["photo.jpg", "--out", str(tmp_path), "--resume", "--overwrite"]) == 2
    assert "--resume keeps the complete results" in capsys.readouterr().err
    (tmp_path / "photo" / "x").mkdir(parents=True)
    assert cli.main(["photo.jpg", "--out", str(tmp_path)]) == 2
    assert "pass --resume to keep them" in capsys.readouterr().err
    assert cli.main(["photo.jpg", "--out", str(tmp_path), "--resume"]) == 2  # not a result
    assert "not complete results" in capsys.readouterr().err


def test_same_person_is_refused_under_torchrun(tmp_path, capsys, monkeypatch) -> None:
    for key, value in _launch_environment(1, 2, "same").items():
        monkeypatch.setenv(key, value)
    assert cli.main(["a.jpg", "b.jpg", "--out", str(tmp_path), "--same-person"]) == 2
    assert "--same-person combines every photo's shape in one process" in capsys.readouterr().err
    monkeypatch.setenv("RANK", "2")
    assert cli.main(["a.jpg", "--out", str(tmp_path)]) == 2
    assert "do not fit together" in capsys.readouterr().err


# --- kill -9 at random moments, then --resume -------------------------------------------


DAMAGED = "photo_05.jpg"
PHOTOS = 12


class NoModel:
    """The predictor double of the kill test (the photo double does the work)."""

    def close(self) -> None:
        pass


def slow_photo_double(predictor, image, folder, **_) -> PhotoResult:
    """Stands in for :func:`hkpd.prediction.cli.predict_photo`: writes a few files slowly into
    ``folder`` (the partial one), summary.json last, so that kills land in the middle of
    writing; the damaged photo fails like an unreadable image."""
    if Path(image).name == DAMAGED:
        raise ImageInputError(f"{image}: cannot read the image (damaged)")
    folder.mkdir(parents=True)
    files = []
    for index in range(3):
        time.sleep(random.uniform(0.005, 0.03))
        (folder / f"part_{index}.txt").write_text(f"{Path(image).name} {index}\n" * 200)
        files.append(f"part_{index}.txt")
    summary = {"image": str(image), "quality": {"score": 0.5, "flags": []},
               "sex_probabilities": {"female": 0.25, "male": 0.75}, "files": files,
               "timings": {"total_s": 0.05}}  # fmt: skip
    (folder / "summary.json").write_text(json.dumps(summary))
    return PhotoResult(image=image, folder=folder, files=files, person_box=(0, 0, 1, 1))


def _rank_process(arguments: list[str], environment: dict[str, str], log: Path) -> None:
    """A forked rank: torchrun's variables, output to ``log``, ``hkpd-predict``'s main."""
    os.environ.update(environment)
    descriptor = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND)
    os.dup2(descriptor, 1)
    os.dup2(descriptor, 2)
    os._exit(cli.main(arguments))


def _start_ranks(arguments, run: str, log: Path) -> list[multiprocessing.Process]:
    context = multiprocessing.get_context("fork")
    ranks = [
        context.Process(target=_rank_process, args=(arguments, _launch_environment(r, 2, run), log))
        for r in range(2)
    ]
    for process in ranks:
        process.start()
    return ranks


def _complete_folders(out: Path) -> dict[str, int]:
    """Complete result folders -> their summary.json's inode (a folder redone gets a new one)."""
    return {
        path.name: (path / "summary.json").stat().st_ino
        for path in out.iterdir()
        if path.is_dir() and (path / "summary.json").is_file() and not path.name.startswith(".")
    }


def test_kill_9_at_random_moments_then_resume_does_every_photo_once(tmp_path, monkeypatch):
    monkeypatch.setattr(cli, "load_predictor", lambda model, device: NoModel())
    monkeypatch.setattr(cli, "predict_photo", slow_photo_double)
    monkeypatch.setattr(Shard, "configure_threads", lambda self, device: None)  # forked torch
    photos = tmp_path / "photos"
    photos.mkdir()
    for index in range(PHOTOS):
        (photos / f"photo_{index:02d}.jpg").write_bytes(b"a photo")
    expected = {f"photo_{index:02d}" for index in range(PHOTOS)} - {Path(DAMAGED).stem}
    chooser = random.Random(60)
    for trial in range(10):
        out = tmp_path / f"out_{trial}"
        log = tmp_path / f"log_{trial}.txt"
        arguments = [str(photos), "--out", str(out)]
        ranks = _start_ranks(arguments, f"killed-{trial}", log)
        time.sleep(chooser.uniform(0.0, 0.6))
        victim = chooser.randrange(2)
        os.kill(ranks[victim].pid, signal.SIGKILL)
        with contextlib.suppress(ProcessLookupError):  # torchrun stops the other rank too
            os.kill(ranks[1 - victim].pid, signal.SIGTERM)
        for process in ranks:
            process.join(timeout=30)
        before = _complete_folders(out) if out.exists() else {}
        resumed = _start_ranks([*arguments, "--resume"], f"resumed-{trial}", log)
        for process in resumed:
            process.join(timeout=60)
        assert [process.exitcode for process in resumed] == [0, 0], log.read_text()
        after = _complete_folders(out)
        assert set(after) == expected, (trial, log.read_text())
        assert all(after[name] == inode for name, inode in before.items())  # not redone
        assert sorted(path.name for path in out.iterdir()) == sorted([*expected, INDEX_FILE])
        assert not (out / WORK_FOLDER).exists()
        index = read_records(out / INDEX_FILE)
        assert len(index) == PHOTOS and len({record["folder"] for record in index}) == PHOTOS
        for record in index:
            if record["photo"] == DAMAGED:
                assert record["status"] == "error: cannot read the image (damaged)"
            else:
                assert record["status"] == "ok" and record["sex_probabilities"]["male"] == 0.75
        for name in expected:
            text = (out / name / "part_2.txt").read_text()
            assert text == f"{name}.jpg 2\n" * 200  # whole, and the photo's own


def test_torchrun_with_two_processes_predicts_a_folder_into_one_index(tmp_path: Path) -> None:
    """The real command line: ``torchrun --standalone --nproc_per_node 2 --no-python
    hkpd-predict``, the shipped model and detector, a photo for each rank and a damaged file."""
    import shutil
    import subprocess
    import sys

    from hkpd.explorer.demo_photo import shipped_photo

    program = Path(sys.executable).parent / "hkpd-predict"
    if not program.is_file():
        pytest.skip("hkpd-predict is not installed beside this Python")
    photos = tmp_path / "photos"
    photos.mkdir()
    for name in ("a.jpg", "b.jpg"):
        shutil.copyfile(shipped_photo(), photos / name)
    (photos / "c_damaged.jpg").write_bytes(b"\xff\xd8\xff\xe0 cut short" * 30)
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone",
               "--nproc_per_node=2", "--no-python", str(program), str(photos), "--out",
               str(tmp_path / "out"), "--samples", "0", "--format", "npz",
               "--uncertainty-samples", "4"]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "2 of 3 photos done, 1 failed" in done.stdout
    assert done.stdout.count("photos done") == 1  # rank 0 says it once, for both
    failed = [line for line in done.stderr.splitlines() if "FAILED" in line]
    assert len(failed) == 1 and "c_damaged.jpg: the image data is corrupt" in failed[0]
    index = read_records(tmp_path / "out" / INDEX_FILE)
    assert [(r["photo"], r["rank"], r["status"] == "ok") for r in index] == [
        ("a.jpg", 0, True), ("b.jpg", 1, True), ("c_damaged.jpg", 0, False)
    ]  # fmt: skip
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["a", "b", INDEX_FILE]
