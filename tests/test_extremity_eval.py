"""``hkpd-eval --extremities``: hands and feet with and without the landmark term."""

from __future__ import annotations

import json
import math

import torch

from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_NAMES, extremity_landmarks
from hkpd.evaluation.cli import main as eval_main
from hkpd.evaluation.extremity_eval import (
    EVIDENCE,
    JOINT_METRICS,
    PART_METRICS,
    PARTS,
    exact_extremity_landmarks,
    rotation_angle_deg,
    shown_sides,
    summarise,
)
from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import save_checkpoint
from hkpd.network.config import NetworkConfig
from hkpd.poses import ProceduralPosePrior
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator


def test_exact_landmarks_land_beside_their_wrists_and_ankles() -> None:
    generator = SyntheticDataGenerator(ProceduralPosePrior(), SyntheticDataConfig(image_size=64))
    batch = generator.generate(4, seed=3).batch  # training augmentations: crop scale jitter
    regressor = extremity_landmarks(generator.body).rows(BLAZEPOSE_EXTREMITY_NAMES)
    landmarks, misfit = exact_extremity_landmarks(generator.body, batch, regressor)
    assert landmarks.shape == (4, 10, 2)
    assert float(misfit.max()) < 0.01  # the crop is a similarity of the perspective image
    joints = batch.keypoints2d[:, [9, 10, 9, 10, 9, 10, 15, 16, 15, 16]]
    other = batch.keypoints2d[:, [10, 9, 10, 9, 10, 9, 16, 15, 16, 15]]
    near = (landmarks - joints).norm(dim=-1)
    assert float(near.max()) < 0.2 * 64  # a hand or a foot long (a person is ~0.8 crop)
    assert bool((near < (landmarks - other).norm(dim=-1) + 1.0).float().mean() > 0.8)


def test_rotation_angle_of_a_known_turn() -> None:
    turn = torch.tensor([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert abs(float(rotation_angle_deg(torch.eye(3), turn)) - 90.0) < 1e-4
    assert float(rotation_angle_deg(turn, turn)) < 0.1


def test_summary_counts_only_the_shown_sides_as_shown() -> None:
    def scores(value: float) -> dict:
        table = {(n, s): torch.full((len(PART_METRICS),), value) for n in PARTS
                 for s in ("left", "right")}  # fmt: skip
        return table | {(n, s): torch.full((len(JOINT_METRICS),), value)
                        for n in ("wrist", "ankle") for s in ("left", "right")}  # fmt: skip

    visible = torch.zeros(17, dtype=torch.bool)
    visible[9] = True  # the left wrist only
    sides = shown_sides(visible)
    assert sides[("fingers", "left")] and not sides[("fingers", "right")]
    assert sides[("wrist", "left")] and not sides[("foot", "left")]
    record = summarise({EVIDENCE[0]: [(scores(1.0), sides, True), (scores(3.0), sides, False)]})
    hand = record[EVIDENCE[0]]["all"]["hand"]
    assert hand["mode_error_cm"] == 2.0 and hand["sides"] == 4
    assert record[EVIDENCE[0]]["shown"]["hand"]["sides"] == 2
    assert math.isnan(record[EVIDENCE[0]]["shown"]["foot"]["coverage_90"])
    assert record[EVIDENCE[0]]["conditioned"] == 0.5


def test_hkpd_eval_extremities_writes_both_fits(tmp_path, capsys) -> None:
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    torch.manual_seed(0)
    checkpoint = save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    report = tmp_path / "report.md"
    arguments = [str(checkpoint), "--no-synthetic", "--samples", "6", "--out", str(report)]
    assert eval_main([*arguments, "--extremities", "2", "--no-mirror-reading"]) == 0
    text = report.read_text()
    assert "| keypoints + landmarks | shown" in text and "mode rotation error deg" in text
    records = json.loads((tmp_path / "extremities.json").read_text())
    record = records[str(checkpoint)]
    assert record["examples"] == 2 and record["landmark_misfit_px"] < 0.01
    for evidence in EVIDENCE:
        assert record[evidence]["conditioned"] == 1.0
        for part in PARTS:
            row = record[evidence]["all"][part]
            assert row["sides"] == 4
            assert 0.0 <= row["coverage_50"] <= row["coverage_90"] <= 1.0
            assert 0.0 < row["local_uncertainty_cm"] < row["uncertainty_cm"] + 1e-6
    without, with_landmarks = (record[e]["all"]["hand"]["mode_error_cm"] for e in EVIDENCE)
    assert without != with_landmarks  # the second fit did use the landmarks
    assert eval_main([*arguments, "--extremities", "-1"]) == 2
    assert "--extremities must be >= 0" in capsys.readouterr().err
