"""Bad input to hkpd-train, hkpd-eval and hkpd-poses: one line, a non-zero exit, no traceback;
exact resume; checkpoints that notice damage and never leave half-written files."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from hkpd.evaluation.cli import main as eval_main
from hkpd.network import DistributionNetwork
from hkpd.network import checkpoint as checkpoints
from hkpd.network.checkpoint import CheckpointError, read_checkpoint, save_checkpoint
from hkpd.network.config import NetworkConfig
from hkpd.poses.cli import main as poses_main
from hkpd.training.cli import main as train_main
from hkpd.training.config import TrainConfig
from hkpd.training.loop import train

TINY = {
    "batch_size": 4, "image_size": 32, "backbone_base_width": 4, "samples_loss_from": 0,
    "joints3d_loss_from": -1, "learning_rate": 1e-3, "num_samples": 2, "log_every": 1,
    "val_every": 0, "val_size": 2, "checkpoint_every": 100,
}  # fmt: skip


def _flags(**values) -> list[str]:
    return [f"--{key.replace('_', '-')}={value}" for key, value in {**TINY, **values}.items()]


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory) -> Path:
    config = NetworkConfig(backbone_base_width=4, image_size=32)
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("model") / "tiny.pt"
    return save_checkpoint(path, DistributionNetwork(config), config.to_dict(), 0, {}, 0)


@pytest.fixture(scope="module")
def truncated_poses(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("poses") / "cut.npz"
    from hkpd.poses.bank import PoseBank

    rng = np.random.default_rng(0)
    count = 12
    bank = PoseBank(
        body_pose=rng.normal(0, 0.2, (count, 23, 3)).astype(np.float32),
        global_orient=np.zeros((count, 3), np.float32), subject=np.arange(count, dtype=np.int32),
        clip=np.zeros(count, np.int32), clip_names=("c",), frame=np.zeros(count, np.int32),
        mirrored=np.zeros(count, bool), split=np.zeros(count, np.int8),
    )  # fmt: skip
    whole = path.with_name("whole.npz")
    bank.save(whole)
    data = whole.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--batch-size", "0"], "--batch-size must be an integer >= 1"),
        (["--log-every", "0"], "--log-every must be an integer >= 1"),
        (["--checkpoint-every", "0"], "--checkpoint-every must be an integer >= 1"),
        (["--learning-rate", "inf"], "--learning-rate must be a finite number > 0"),
        (["--mode-loss-weight", "-1"], "--mode-loss-weight must be a finite number >= 0"),
        (["--device", "tpu"], "--device must be auto, cpu"),
        (["--steps", "0"], "--steps must be an integer >= 1"),
        (["--steps", "-5"], "--steps must be an integer >= 1"),
        (["--limb-occlusion-probability", "2"], "probability in [0, 1]"),
        (["--limb-occlusion-probability", "-1"], "probability in [0, 1]"),
        (["--data-workers", "-1"], "--data-workers must be an integer >= 0"),
        (["--val-size", "0"], "--val-size must be an integer >= 1"),
    ],
)
def test_train_refuses_nonsense_flags(tmp_path, capsys, flags, message) -> None:
    assert train_main(["--out", str(tmp_path / "r"), "--quiet", *flags]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1


def test_train_refuses_a_truncated_or_absurd_pose_bank(tmp_path, capsys, truncated_poses):
    assert train_main(["--out", str(tmp_path), "--poses", str(truncated_poses), "--quiet"]) == 2
    assert "truncated" in capsys.readouterr().err
    assert poses_main(["info", str(truncated_poses)]) == 2
    assert "truncated" in capsys.readouterr().err


def test_absurd_rotations_are_refused() -> None:
    from hkpd.poses.bank import PoseBank

    body = np.zeros((2, 23, 3), np.float32)
    body[1, 4, 0] = 1e30
    with pytest.raises(ValueError, match="absurd"):
        PoseBank(body, np.zeros((2, 3), np.float32), *(np.zeros(2, np.int32),) * 2, ("c",),
                 np.zeros(2, np.int32), np.zeros(2, bool), np.zeros(2, np.int8))  # fmt: skip


def test_resume_is_bit_exact(tmp_path) -> None:
    # TINY's backbone is 4 channels wide: before core/network/backbone.py kept such backbones
    # in NCHW, torch 2.13's channels-last kernel gave their shortcut projections a random weight
    # gradient (and a corrupted heap with one thread), so this failed from step 2 on.
    whole = train(TrainConfig(out=tmp_path / "whole", steps=4, **TINY), show_progress=False)
    first = TrainConfig(out=tmp_path / "split", steps=2, **TINY)
    train(first, show_progress=False)
    torch.manual_seed(12345)  # whatever happened in between must not matter
    np.random.default_rng(1)
    resumed = train(TrainConfig(**{**vars(first), "steps": 4}), resume=True, show_progress=False)
    a = read_checkpoint(whole.checkpoint)["model"]
    b = read_checkpoint(resumed.checkpoint)["model"]
    assert a.keys() == b.keys()
    for key in a:
        assert torch.equal(a[key], b[key]), key


def test_resume_refuses_a_finished_run_a_foreign_log_and_another_architecture(tmp_path, capsys):
    out = tmp_path / "run"
    assert train_main(["--out", str(out), "--steps", "2", "--quiet", *_flags()]) == 0
    capsys.readouterr()
    before = (out / "val.csv").read_text()
    assert train_main(["--out", str(out), "--resume", "--quiet"]) == 2
    assert "already finished" in capsys.readouterr().err
    assert (out / "val.csv").read_text() == before  # no duplicated row
    wider = ["--out", str(out), "--resume", "--steps", "4", "--backbone-base-width", "8"]
    config_before = (out / "config.json").read_text()
    assert train_main([*wider, "--quiet"]) == 2
    assert "backbone_base_width=4" in capsys.readouterr().err
    assert (out / "config.json").read_text() == config_before  # a refused resume writes nothing
    (out / "train.csv").write_text("a,b\n1,2\n")
    assert train_main(["--out", str(out), "--resume", "--steps", "4", "--quiet"]) == 2
    assert "no 'step' column" in capsys.readouterr().err


def test_a_failed_checkpoint_write_leaves_no_partial_file(tmp_path, monkeypatch) -> None:
    config = NetworkConfig(backbone_base_width=4, image_size=32)

    def full_disk(payload, path) -> None:
        Path(path).write_bytes(b"half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(checkpoints.torch, "save", full_disk)
    target = tmp_path / "last.pt"
    with pytest.raises(OSError, match="No space left"):
        save_checkpoint(target, DistributionNetwork(config), config.to_dict(), 0, {}, 0)
    assert list(tmp_path.iterdir()) == []


def test_a_flipped_byte_in_the_weights_is_detected(tmp_path, tiny_checkpoint) -> None:
    damaged = tmp_path / "damaged.pt"
    shutil.copy(tiny_checkpoint, damaged)
    state = read_checkpoint(tiny_checkpoint)["model"]
    name = max(state, key=lambda key: state[key].numel())
    data = bytearray(damaged.read_bytes())
    offset = data.find(state[name].contiguous().view(torch.uint8).numpy().tobytes()[:64])
    assert offset > 0
    data[offset + 10] ^= 0x40
    damaged.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="damaged"):
        read_checkpoint(damaged)


def test_eval_refuses_nonsense_before_evaluating(
    tmp_path, capsys, tiny_checkpoint, truncated_poses
):
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"\x00" * 100)
    cases = [
        ([str(garbage), "--count", "2"], "not a readable checkpoint"),
        ([str(tiny_checkpoint), "--poses", str(truncated_poses)], "truncated"),
        ([str(tiny_checkpoint), "--count", "0"], "--count must be at least 1"),
        ([str(tiny_checkpoint), "--samples", "0"], "--samples must be at least 1"),
        ([str(tiny_checkpoint), "--out", str(tmp_path / "missing" / "r.md")], "does not exist"),
        ([str(tiny_checkpoint), "--out", str(tmp_path)], "is a folder"),
        ([str(tiny_checkpoint), "--no-synthetic", "--coco", str(tmp_path)], "annotations"),
    ]
    for arguments, message in cases:
        assert eval_main(arguments) == 2, arguments
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, (arguments, err)
