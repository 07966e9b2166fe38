"""hkpd-train under torchrun: two gloo processes on the CPU train as one with the doubled batch,
write one run folder, and resume exactly."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from ddp_gradient_worker import MODES, gradients, joined, rank_batch, tiny_network

from hkpd.network.checkpoint import load_network, read_checkpoint
from hkpd.training.config import TrainConfig
from hkpd.training.distributed import Launch, detect_launch, rank_seed
from hkpd.training.loop import build_training
from hkpd.training.stop_signals import StopSignals

TESTS = Path(__file__).parent
TINY_FLAGS = [
    "--device=cpu", "--batch-size=4", "--image-size=64", "--backbone-base-width=8",
    "--samples-loss-from=0", "--joints3d-loss-from=3", "--learning-rate=1e-3",
    "--num-samples=2", "--log-every=1", "--val-every=0", "--val-size=2",
    "--checkpoint-every=100", "--quiet",
]  # fmt: skip
"""Every loss on within four steps, the samples loss (each rank's own random draws) from the
first, so a rank whose random state were not restored would change the result."""
LOSS_COLUMNS = ("shape_nll", "pose_nll", "global_rotation", "joints2d_mode", "joints2d_samples",
                "joints3d_mode", "total")  # fmt: skip


def torchrun(*arguments: str, processes: int = 2) -> subprocess.CompletedProcess:
    """``torchrun --standalone`` (a free port of its own) with ``arguments``."""
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone",
               f"--nproc-per-node={processes}", *arguments]  # fmt: skip
    environment = {**os.environ, "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        command, capture_output=True, text=True, timeout=240, env=environment, check=False
    )


def train_in_two(out: Path, steps: int, resume: bool = False) -> subprocess.CompletedProcess:
    flags = [*TINY_FLAGS, f"--out={out}", f"--steps={steps}", *(["--resume"] if resume else [])]
    done = torchrun("-m", "hkpd.training.cli", *flags)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    return done


def rows(path: Path) -> list[dict[str, str]]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


def losses(path: Path) -> list[tuple[str, ...]]:
    return [tuple(row[name] for name in ("step", *LOSS_COLUMNS)) for row in rows(path)]


def test_averaged_gradients_equal_one_process_with_the_doubled_batch(tmp_path) -> None:
    """DDP's gradient over two ranks of 4 examples = one process's over those 8 examples (batch
    normalisation on running statistics); with batch statistics, each rank normalises its own
    batch, and the gradient is the average of the two single-batch gradients."""
    saved = tmp_path / "gradients.pt"
    done = torchrun(str(TESTS / "ddp_gradient_worker.py"), str(saved))
    assert done.returncode == 0, done.stderr[-4000:]
    found = torch.load(saved, weights_only=True)
    batches = [rank_batch(0), rank_batch(1)]
    network = tiny_network()
    doubled = gradients(network, network, joined(batches), "eval")
    alone = {mode: [gradients(network, network, b, mode) for b in batches] for mode in MODES}
    averaged = [(a + b) / 2 for a, b in zip(*alone["train"], strict=True)]
    assert len(found["eval"]) == len(doubled) == len(list(network.parameters()))
    # batch statistics amplify float32 summation-order noise (thread counts differ between the
    # workers and this process: 1.3e-4 of the largest gradient seen in CI, 1.1e-3 on another
    # 2-core VM), so "train" gets 3e-3; rank 0's own gradient is > 1e-2 away (below), so both
    # bounds still tell the two apart
    tolerance = {"eval": 1e-4, "train": 3e-3}
    for expected, mode in ((doubled, "eval"), (averaged, "train")):
        for got, want in zip(found[mode], expected, strict=True):
            scale = float(want.abs().max()) + 1e-12
            assert float((got - want).abs().max()) <= tolerance[mode] * scale, mode
    # not rank 0's own gradient: the other rank's batch counts
    worst = max(
        float((got - own).abs().max() / (own.abs().max() + 1e-12))
        for got, own in zip(found["eval"], alone["eval"][0], strict=True)
    )
    assert worst > 1e-2


def test_two_processes_write_one_run_and_resume_exactly(tmp_path) -> None:
    """torchrun ... --steps 4 writes one run folder; 2 + 2 resumed steps equal 4 uninterrupted
    ones (weights, optimiser, every logged loss), each rank's random draws included."""
    whole, pieces = tmp_path / "whole", tmp_path / "pieces"
    done = train_in_two(whole, 4)
    assert done.stdout.count("finished: 4 steps, 32 samples") == 1  # rank 0 alone prints
    assert "global batch 8" in done.stdout and "error" not in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["whole"]
    assert {p.name for p in whole.iterdir()} == {
        "config.json", "curves.png", "last.pt", "train.csv", "val.csv"
    }  # fmt: skip
    assert [int(r["step"]) for r in rows(whole / "train.csv")] == [1, 2, 3, 4]
    assert float(rows(whole / "train.csv")[-1]["joints3d_mode"]) > 0  # every loss was on
    assert json.loads((whole / "config.json").read_text())["world_size"] == 2
    network, payload = load_network(whole / "last.pt")
    assert payload["step"] == 4 and payload["samples_seen"] == 32
    assert len(payload["rng_per_rank"]) == 2
    assert network(torch.zeros(1, 18, 64, 64)).F.shape == (1, 23, 3, 3)

    train_in_two(pieces, 2)
    train_in_two(pieces, 4, resume=True)
    assert losses(pieces / "train.csv") == losses(whole / "train.csv")
    resumed, whole_run = read_checkpoint(pieces / "last.pt"), read_checkpoint(whole / "last.pt")
    assert resumed["checksum"] == whole_run["checksum"] and resumed["samples_seen"] == 32
    for saved, uninterrupted in zip(
        resumed["optimizer"]["state"].values(), whole_run["optimizer"]["state"].values(),
        strict=True,
    ):  # fmt: skip
        assert torch.equal(saved["exp_avg_sq"], uninterrupted["exp_avg_sq"])
    assert [int(r["step"]) for r in rows(pieces / "val.csv")] == [2, 4]
    config = TrainConfig.load(pieces / "config.json")
    with pytest.raises(ValueError, match="trained with 2 process"):
        build_training(replace(config, steps=6), resume=True, launch=Launch())


def test_a_launch_is_read_from_torchruns_environment() -> None:
    assert detect_launch({}) == Launch()
    launch = detect_launch({"WORLD_SIZE": "4", "RANK": "3", "LOCAL_RANK": "1"})
    assert launch == Launch(rank=3, local_rank=1, world_size=4) and not launch.is_main
    with pytest.raises(ValueError, match="lacks LOCAL_RANK"):
        detect_launch({"WORLD_SIZE": "2", "RANK": "0"})
    with pytest.raises(ValueError, match="do not fit"):
        detect_launch({"WORLD_SIZE": "2", "RANK": "2", "LOCAL_RANK": "0"})
    assert rank_seed(5, 0) == 5 and rank_seed(5, 1) != rank_seed(5, 0)


def test_ctrl_c_asks_the_loop_to_stop_after_its_step() -> None:
    """The first SIGINT or SIGTERM only sets the request (every rank finishes its step, then
    they stop together); alone, a second Ctrl-C stops at once; the old handlers come back."""
    before = signal.getsignal(signal.SIGINT)
    with StopSignals() as signals:
        os.kill(os.getpid(), signal.SIGTERM)
        os.kill(os.getpid(), signal.SIGINT)
        assert signals.requested
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is before
    with StopSignals(force_on_second_interrupt=False) as signals:  # under torchrun
        for _ in range(3):
            os.kill(os.getpid(), signal.SIGINT)
        assert signals.requested
