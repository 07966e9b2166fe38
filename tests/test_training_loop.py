"""hkpd-train end to end: a tiny CPU run learns, logs, checkpoints and resumes."""

from __future__ import annotations

import csv
from itertools import pairwise
from pathlib import Path

import pytest
import torch

from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import CheckpointError, load_network, read_checkpoint
from hkpd.training.cli import build_parser
from hkpd.training.cli import main as train_main
from hkpd.training.config import TrainConfig, learning_rate_at
from hkpd.training.csv_logs import append_row
from hkpd.training.loop import build_schedule, build_training, train
from hkpd.training.schedule import LossWeights

TINY = {
    "batch_size": 8,
    "image_size": 64,
    "backbone_base_width": 16,
    "samples_loss_from": -1,
    "joints3d_loss_from": -1,
    "learning_rate": 1e-3,
    "num_samples": 2,
    "log_every": 5,
    "val_every": 0,
    "val_size": 8,
    "checkpoint_every": 20,
}


def rows(path: Path) -> list[dict[str, str]]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[TrainConfig, object]:
    config = TrainConfig(out=tmp_path_factory.mktemp("run"), steps=40, **TINY)
    return config, train(config, show_progress=False)


def test_tiny_run_lowers_the_loss(run) -> None:
    config, result = run
    assert result.steps == 40 and result.samples_seen == 320
    log = rows(config.out / "train.csv")
    assert [int(r["step"]) for r in log] == list(range(5, 41, 5))
    first, last = log[0], log[-3:]
    for term in ("joints2d_mode", "pose_nll"):
        assert sum(float(r[term]) for r in last) / 3 < float(first[term]), term
    assert (config.out / "curves.png").stat().st_size > 10_000
    assert "mpjpe_sc" in rows(config.out / "val.csv")[-1]


def test_checkpoint_loads_and_resume_continues(run) -> None:
    config, result = run
    network, payload = load_network(result.checkpoint)
    assert isinstance(network, DistributionNetwork) and payload["step"] == 40
    assert network(torch.zeros(1, 18, 64, 64)).F.shape == (1, 23, 3, 3)
    resumed = train(TrainConfig(**{**vars(config), "steps": 50}), resume=True, show_progress=False)
    assert resumed.steps == 50 and resumed.samples_seen == 400
    steps = [int(r["step"]) for r in rows(config.out / "train.csv")]
    assert steps == list(range(5, 51, 5))  # no duplicated or missing rows


def test_bad_checkpoint_and_missing_paths(tmp_path, capsys) -> None:
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="not a readable checkpoint"):
        read_checkpoint(junk)
    code = train_main(["--out", str(tmp_path / "r"), "--poses", str(tmp_path / "none.npz")])
    assert code == 2
    assert "hkpd-poses build" in capsys.readouterr().err


def test_schedule_stages_follow_the_config() -> None:
    schedule = build_schedule(TrainConfig(samples_loss_from=10, joints3d_loss_from=20))
    assert (
        schedule.weights_at(0).joints2d_samples == 0 and schedule.weights_at(0).joints3d_mode == 0
    )
    assert (
        schedule.weights_at(10).joints2d_samples > 0 and schedule.weights_at(10).joints3d_mode == 0
    )
    assert schedule.weights_at(25).joints3d_mode > 0
    heavier = build_schedule(TrainConfig(samples_loss_from=5, samples_loss_weight=4000.0))
    assert heavier.weights_at(10).joints2d_samples == 4000.0
    assert heavier.weights_at(10).joints2d_mode == LossWeights().joints2d_mode
    mode_heavier = build_schedule(TrainConfig(mode_loss_weight=8000.0))
    assert mode_heavier.weights_at(0).joints2d_mode == 8000.0
    assert mode_heavier.weights_at(10**6).joints2d_samples == LossWeights().joints2d_samples
    never = build_schedule(TrainConfig(samples_loss_from=-1, joints3d_loss_from=-1))
    assert never.weights_at(10**6).joints2d_samples == 0


def test_init_weights_start_a_new_run_from_given_weights(run, tmp_path) -> None:
    config, result = run
    fresh = TrainConfig(**{**vars(config), "out": tmp_path / "fine", "steps": 5,
                           "init_weights": result.checkpoint})  # fmt: skip
    tuned = train(fresh, show_progress=False)
    assert tuned.steps == 5
    before, _ = load_network(result.checkpoint)
    after, _ = load_network(tuned.checkpoint)
    # five small Adam steps from the given weights stay close to them
    pairs = zip(before.parameters(), after.parameters(), strict=True)
    drift = max(float((a - b).abs().max().detach()) for a, b in pairs)
    assert 0 < float(drift) < 0.05
    with_gain = {"concentration_gain": True, "limb_occlusion_probability": 0.5}
    gained = TrainConfig(**{**vars(fresh), "out": tmp_path / "gain", "steps": 2, **with_gain})
    network, _ = load_network(train(gained, show_progress=False).checkpoint)
    assert network.config.concentration_gain
    assert any("log_gain" in name for name, _ in network.named_parameters())
    wrong = TrainConfig(**{**vars(fresh), "out": tmp_path / "x", "backbone_base_width": 8})
    with pytest.raises(ValueError, match="architecture"):
        train(wrong, show_progress=False)


def test_worker_processes_feed_the_same_training(tmp_path) -> None:
    """data_workers > 0 (packed batches from worker processes) trains on the same stream."""
    settings = {**TINY, "steps": 3, "log_every": 1}
    in_thread = train(TrainConfig(out=tmp_path / "thread", **settings), show_progress=False)
    in_workers = train(
        TrainConfig(out=tmp_path / "workers", data_workers=2, **settings), show_progress=False
    )
    assert in_workers.steps == in_thread.steps == 3
    losses = [
        [float(row["total"]) for row in rows(tmp_path / name / "train.csv")]
        for name in ("thread", "workers")
    ]
    assert losses[0] == pytest.approx(losses[1], rel=1e-4)


def test_csv_log_gains_columns_a_newer_version_adds(tmp_path) -> None:
    log = tmp_path / "val.csv"
    append_row(log, {"step": 1, "mpjpe": 70.0})
    append_row(log, {"step": 2, "mpjpe": 69.0, "pose_coverage_50": 0.4})
    append_row(log, {"step": 3, "mpjpe": 68.0, "pose_coverage_50": 0.45})
    with log.open() as handle:
        rows = list(csv.DictReader(handle))
    assert [row["step"] for row in rows] == ["1", "2", "3"]
    assert rows[0]["pose_coverage_50"] == "" and rows[2]["pose_coverage_50"] == "0.45"
    assert rows[1]["mpjpe"] == "69.0"


def test_learning_rate_is_constant_or_decays_along_a_half_cosine(run, tmp_path) -> None:
    config, _ = run
    assert {float(r["learning_rate"]) for r in rows(config.out / "train.csv")} == {1e-3}
    decaying = TrainConfig(steps=101, learning_rate=1e-3, final_learning_rate=1e-5)
    rates = [learning_rate_at(step, decaying) for step in range(101)]
    assert rates[0] == pytest.approx(1e-3) and rates[-1] == pytest.approx(1e-5)
    assert rates[50] == pytest.approx((1e-3 + 1e-5) / 2)
    assert all(later < earlier for earlier, later in pairwise(rates))
    assert learning_rate_at(500, decaying) == pytest.approx(1e-5)  # a run extended past its end
    parsed = build_parser().parse_args(["--final-learning-rate", "3e-5"])
    assert parsed.final_learning_rate == 3e-5
    with pytest.raises(ValueError, match="final-learning-rate"):
        train(TrainConfig(out=tmp_path, final_learning_rate=0.0, **TINY), show_progress=False)


def test_every_flag_has_its_documented_description_and_default() -> None:
    import dataclasses

    from hkpd.training.config import field_descriptions

    descriptions = field_descriptions()
    assert set(descriptions) == {f.name for f in dataclasses.fields(TrainConfig)}
    assert descriptions["steps"] == "optimiser steps in total."
    # reST roles are reduced to plain names and continuation lines joined.
    assert (
        "hkpd.synthesis.augmentations.limb_occlusion_boxes"
        in descriptions["limb_occlusion_probability"]
    )
    assert ":func:" not in descriptions["limb_occlusion_probability"]
    assert "\n" not in descriptions["init_weights"]
    actions = {action.dest: action for action in build_parser()._actions}
    help_text = actions["learning_rate"].help
    assert help_text.startswith("Adam learning rate") and help_text.endswith("(default: 0.0001)")
    build_parser().format_help()  # every help string survives argparse's % formatting


def test_max_minutes_stops_with_a_checkpoint_that_resume_continues(tmp_path, capsys) -> None:
    config = TrainConfig(out=tmp_path / "timed", steps=1000, max_minutes=1e-6, **TINY)
    result = train(config, show_progress=False)
    assert result.out_of_time and not result.interrupted
    assert 1 <= result.steps < 1000  # stopped by the clock, not the step count
    _, payload = load_network(result.checkpoint)
    assert payload["step"] == result.steps
    resumed = train(
        TrainConfig(**{**vars(config), "steps": result.steps + 3, "max_minutes": None}),
        resume=True,
        show_progress=False,
    )
    assert resumed.steps == result.steps + 3 and not resumed.out_of_time
    out = str(tmp_path / "cli")
    flags = ["--out", out, "--steps", "50", "--max-minutes", "1e-6", "--quiet"]
    flags += [f"--{k.replace('_', '-')}={v}" for k, v in TINY.items()]
    assert train_main(flags) == 0
    assert "stopped at --max-minutes 1e-06" in capsys.readouterr().out
    assert train_main(["--out", out, "--max-minutes", "0"]) == 2
    assert "--max-minutes must be a finite number > 0" in capsys.readouterr().err


def test_shape_from_nll_only_also_detaches_the_pose_streams_shape_input(tmp_path) -> None:
    plain = build_training(TrainConfig(out=tmp_path / "a", **TINY))
    assert not plain.network.head.detach_shape_input
    alone = build_training(TrainConfig(out=tmp_path / "b", shape_from_nll_only=True, **TINY))
    assert alone.network.head.detach_shape_input
