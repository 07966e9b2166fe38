"""Pose bank: save/load round trip, sampling, errors, and the hkpd-poses CLI on synthetic BVHs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import roma
import torch
from test_poses_bvh import max_flavour_motion, max_flavour_skeleton

from hkpd.poses import PoseBank, PoseSource, build_pose_bank
from hkpd.poses.bvh_writer import write_bvh
from hkpd.poses.cli import main


def make_bank(count: int = 12) -> PoseBank:
    generator = np.random.default_rng(0)
    return PoseBank(
        body_pose=generator.normal(0, 0.4, (count, 23, 3)).astype(np.float32),
        global_orient=generator.normal(0, 0.4, (count, 3)).astype(np.float32),
        subject=np.repeat(np.array([1, 2, 3], np.int32), count // 3),
        clip=np.repeat(np.array([0, 1, 2], np.int32), count // 3),
        clip_names=("01_01", "02_01", "03_01"),
        frame=np.arange(count, dtype=np.int32),
        mirrored=np.arange(count) % 2 == 1,
        split=np.repeat(np.array([0, 1, 2], np.int8), count // 3),
    )


def write_synthetic_clips(folder: Path, subjects: range, frames: int = 30) -> None:
    """Walking-like clips (knee and elbow swinging) in the 'max' flavour, one per subject."""
    skeleton = max_flavour_skeleton()
    folder.mkdir(parents=True, exist_ok=True)
    for subject in subjects:
        settings: list[dict[str, dict[str, float]]] = [{}]  # the dropped T-pose frame
        for f in range(frames):
            phase = 2 * np.pi * f / frames + subject
            settings.append(
                {
                    "Hips": {"Yrotation": 10.0 * f, "Zposition": 3.0 * f},
                    "LeftKnee": {"Xrotation": 30 + 30 * np.sin(phase)},
                    "RightKnee": {"Xrotation": 30 - 30 * np.sin(phase)},
                    "LeftElbow": {"Yrotation": -20 - 20 * np.cos(phase)},
                }
            )
        motion = max_flavour_motion(skeleton, settings, name=f"{subject:02d}_01")
        write_bvh(motion, folder / f"{subject:02d}_01.bvh", line_ending="\r\n")


def test_save_load_round_trip_and_splits(tmp_path: Path) -> None:
    bank = make_bank()
    path = bank.save(tmp_path / "sub" / "bank.npz")
    loaded = PoseBank.load(path, split="all")
    np.testing.assert_array_equal(loaded.body_pose, bank.body_pose)
    np.testing.assert_array_equal(loaded.global_orient, bank.global_orient)
    np.testing.assert_array_equal(loaded.mirrored, bank.mirrored)
    assert loaded.clip_names == bank.clip_names
    train = PoseBank.load(path)
    assert len(train) == 4 and train.subjects == (1,) and train.split_name == "train"
    assert PoseBank.load(path, "test").subjects == (3,)


def test_sampling_shapes_values_and_determinism(tmp_path: Path) -> None:
    bank = PoseBank.load(make_bank().save(tmp_path / "bank.npz"), split="val")
    assert isinstance(bank, PoseSource)
    body, orient = bank.sample(50, torch.Generator().manual_seed(0))
    assert body.shape == (50, 23, 3, 3) and orient.shape == (50, 3, 3)
    assert body.dtype == torch.float32
    stored = roma.rotvec_to_rotmat(torch.from_numpy(bank.body_pose))
    distances = (body[:, None] - stored[None]).abs().amax(dim=(-1, -2, -3))
    assert (distances.amin(dim=1) < 1e-6).all()  # every sample is a stored pose
    again, _ = bank.sample(50, torch.Generator().manual_seed(0))
    torch.testing.assert_close(body, again, rtol=0, atol=0)


def test_load_errors_are_clear(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="hkpd-poses build"):
        PoseBank.load(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a readable"):
        PoseBank.load(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="not a pose bank"):
        PoseBank.load(tmp_path / "other.npz")
    path = make_bank().save(tmp_path / "bank.npz")
    with pytest.raises(ValueError, match="unknown split"):
        PoseBank.load(path, split="training")


def test_builder_drops_duplicates_mirrors_and_splits_by_subject(tmp_path: Path) -> None:
    write_synthetic_clips(tmp_path / "a", range(1, 6))
    write_synthetic_clips(tmp_path / "b", range(6, 11))
    bank, summary = build_pose_bank([tmp_path / "a", tmp_path / "b"], progress=False)
    assert len(summary.files) == 10 and not summary.skipped
    assert sum(summary.frames.values()) == 300  # T-pose frames dropped
    kept = sum(summary.kept.values())
    assert 50 < kept < 300  # 12-degree steps of the knees: some frames merge, many stay
    assert len(bank) == 2 * kept and bank.mirrored.sum() == kept
    assert bank.frame.min() >= 1  # frame numbers refer to the file, T-pose frame = 0
    split_of_subject: dict[int, set[int]] = {}
    for subject, split in zip(bank.subject, bank.split, strict=True):
        split_of_subject.setdefault(int(subject), set()).add(int(split))
    assert all(len(splits) == 1 for splits in split_of_subject.values())
    assert {s for splits in split_of_subject.values() for s in splits} == {0, 1, 2}


def test_cli_build_and_info(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "bvh"
    write_synthetic_clips(folder, range(1, 6), frames=12)
    (folder / "09_01.bvh").write_text("HIERARCHY\nROOT x\n{\n")  # broken file, skipped
    out = tmp_path / "poses.npz"
    with pytest.warns(UserWarning, match="09_01.bvh"):
        status = main(["build", str(folder), "--out", str(out), "--quiet"])
    assert status == 0
    printed = capsys.readouterr().out
    assert "train" in printed and "test" in printed and f"to {out}" in printed
    train = PoseBank.load(out, "train")
    test = PoseBank.load(out, "test")
    assert not set(train.subjects) & set(test.subjects)
    assert main(["info", str(out)]) == 0
    assert "poses" in capsys.readouterr().out


def test_cli_reports_bad_folders(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = str(tmp_path / "poses.npz")
    assert main(["build", str(tmp_path / "nowhere"), "--out", out, "--quiet"]) == 2
    assert "does not exist" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert main(["build", str(tmp_path / "empty"), "--out", out, "--quiet"]) == 2
    assert "no .bvh files" in capsys.readouterr().err
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "01_01.bvh").write_text("garbage")
    with pytest.warns(UserWarning):
        assert main(["build", str(tmp_path / "bad"), "--out", out, "--quiet"]) == 2
    assert "none of the 1 BVH files" in capsys.readouterr().err
