"""hkpd-eval on a tiny checkpoint, and the COCO annotation reader."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from hkpd.evaluation.cli import main as eval_main
from hkpd.evaluation.real_photos import load_coco_people
from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import save_checkpoint
from hkpd.network.config import NetworkConfig


def tiny_checkpoint(tmp_path):
    """A small random network's checkpoint (seeded, 64-pixel input)."""
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    torch.manual_seed(0)
    return save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )


def test_eval_prints_a_markdown_table(tmp_path, capsys) -> None:
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    checkpoint = save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    report = tmp_path / "report.md"
    code = eval_main([str(checkpoint), "--count", "3", "--samples", "2", "--out", str(report)])
    assert code == 0
    assert torch.is_grad_enabled()  # the command must not switch autograd off for its caller
    text = report.read_text()
    assert "MPJPE-SC (mm)" in text and "2D joint err. samples (px)" in text
    row = next(line for line in text.splitlines() if line.startswith(f"| {checkpoint}"))
    values = [float(cell) for cell in row.strip("|").split("|")[1:]]
    assert len(values) == 5 and all(v > 0 for v in values)
    assert eval_main([str(tmp_path / "missing.pt")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_coco_reader_keeps_mostly_visible_people(tmp_path) -> None:
    (tmp_path / "annotations").mkdir()
    (tmp_path / "val2017").mkdir()
    (tmp_path / "val2017" / "1.jpg").write_bytes(b"")
    full = [value for i in range(17) for value in (10 + i, 20 + i, 2)]
    partial = [10, 20, 2] * 5 + [0, 0, 0] * 12
    data = {
        "images": [{"id": 1, "file_name": "1.jpg"}, {"id": 2, "file_name": "gone.jpg"}],
        "annotations": [
            {"image_id": 1, "keypoints": full, "bbox": [5, 6, 100, 200], "iscrowd": 0},
            {"image_id": 1, "keypoints": partial, "bbox": [0, 0, 9, 9], "iscrowd": 0},
            {"image_id": 2, "keypoints": full, "bbox": [0, 0, 9, 9], "iscrowd": 0},
        ],
    }
    (tmp_path / "annotations" / "person_keypoints_val2017.json").write_text(json.dumps(data))
    people = load_coco_people(tmp_path)
    assert len(people) == 1
    np.testing.assert_allclose(people[0].bbox, [5, 6, 105, 206])
    assert people[0].visible.all() and people[0].keypoints[3].tolist() == [13, 23]
    with pytest.raises(ValueError, match="no polygon mask"):
        people[0].silhouette()


def test_coco_person_masks_become_silhouettes_for_silhouette_networks(tmp_path) -> None:
    from hkpd.evaluation.real_photos import evaluate_photos

    (tmp_path / "annotations").mkdir()
    (tmp_path / "val2017").mkdir()
    (tmp_path / "val2017" / "1.jpg").write_bytes(b"")
    full = [value for i in range(17) for value in (10 + i, 20 + i, 2)]
    square = [10, 20, 30, 20, 30, 50, 10, 50]  # x, y pairs
    data = {
        "images": [{"id": 1, "file_name": "1.jpg", "width": 64, "height": 80}],
        "annotations": [
            {"image_id": 1, "keypoints": full, "bbox": [5, 6, 30, 40], "iscrowd": 0,
             "segmentation": [square, [40, 60, 44, 60, 44, 64]]},
        ],
    }  # fmt: skip
    (tmp_path / "annotations" / "person_keypoints_val2017.json").write_text(json.dumps(data))
    (person,) = load_coco_people(tmp_path)
    mask = person.silhouette()
    assert mask.shape == (80, 64) and mask.dtype == bool
    assert mask[20:51, 10:31].all() and mask[61, 41] and mask.sum() < 31 * 21 + 20

    seen = []

    class SilhouettePredictor:
        image_proxy = "silhouette"

        def predict(self, path, bbox, evidence, upright, silhouette):
            seen.append(silhouette)
            raise ValueError("stop here")

    per_person = []
    result = evaluate_photos(
        SilhouettePredictor(), [person], show_progress=False, mode_errors=per_person
    )
    assert result["failed"] == 1 and seen[0] is not None and (seen[0] == mask).all()
    assert len(per_person) == 1 and np.isnan(per_person[0])


def test_occlusion_response_runs_and_covers_the_limb() -> None:
    from hkpd.evaluation.occlusion_response import occlusion_response, summarise
    from hkpd.poses import ProceduralPosePrior
    from hkpd.synthesis.augmentations import AugmentationConfig
    from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator

    config = SyntheticDataConfig(image_size=64, augmentation=AugmentationConfig.disabled())
    generator = SyntheticDataGenerator(ProceduralPosePrior(), config)
    torch.manual_seed(0)
    network = DistributionNetwork(NetworkConfig(backbone_base_width=8, image_size=64)).eval()
    cases = occlusion_response(network, generator, cases=4, samples=4, batch_size=4)
    assert [case.limb for case in cases] == [
        "left_forearm", "right_forearm", "left_lower_leg", "right_lower_leg",
    ]  # fmt: skip
    assert all(np.isfinite(case.ratio) and case.ratio > 0 for case in cases)
    assert all(len(case.other_changes) == 3 for case in cases)
    summary = summarise(cases)
    assert summary["cases"] == 4 and 0 <= summary["fraction_ratio_at_least_1.5"] <= 1
    forearms = [case.ratio for case in cases if case.limb.endswith("forearm")]
    lower_legs = [case.ratio for case in cases if case.limb.endswith("lower_leg")]
    assert summary["occluded_ratio_median_forearms"] == pytest.approx(np.median(forearms))
    assert summary["occluded_ratio_median_lower_legs"] == pytest.approx(np.median(lower_legs))


def test_occlusion_summary_splits_forearms_from_lower_legs() -> None:
    from hkpd.evaluation.occlusion_response import OcclusionCase, summarise

    cases = [
        OcclusionCase("left_forearm", 1.1, [0.0] * 3),
        OcclusionCase("right_forearm", 1.3, [0.0] * 3),
        OcclusionCase("left_lower_leg", 2.0, [0.1] * 3),
    ]
    summary = summarise(cases)
    assert summary["occluded_ratio_median"] == pytest.approx(1.3)
    assert summary["occluded_ratio_median_forearms"] == pytest.approx(1.2)
    assert summary["occluded_ratio_median_lower_legs"] == pytest.approx(2.0)
    only_legs = summarise(cases[2:])
    assert np.isnan(only_legs["occluded_ratio_median_forearms"])


class _FixedPosterior:
    """What ``evaluate_photos`` reads from a prediction, with chosen keypoints."""

    def __init__(self, person, shift_px: float) -> None:
        truth = torch.as_tensor(person.keypoints, dtype=torch.float32)
        self.crop = type("Crop", (), {"side": 512.0})()
        self.keypoints = truth + torch.tensor([shift_px, 0.0])
        self.confidences = torch.full((17,), 0.9)
        self.confidences[0] = 0.1  # dropped by the 0.6 threshold: not scored for the detector
        self.keypoints[0] += 1000.0
        self._body_points = truth + torch.tensor([0.0, 2 * shift_px])

    def mode(self):
        return type("Meshes", (), {"keypoints2d": self._body_points[None]})()

    def sample(self, n: int, seed: int):
        return type("Meshes", (), {"keypoints2d": self._body_points.expand(n, 17, 2)})()


def test_photo_errors_score_the_prediction_and_the_detector_input() -> None:
    from hkpd.evaluation.real_photos import AnnotatedPerson, evaluate_photos

    keypoints = np.stack([np.arange(17) * 10.0, np.arange(17) * 5.0 + 50], axis=1)
    person = AnnotatedPerson(
        image_path=None, bbox=np.array([0, 0, 200, 400]), keypoints=keypoints,
        visible=np.ones(17, dtype=bool),
    )  # fmt: skip
    predictor = type(
        "Predictor", (), {"predict": lambda self, path, bbox, evidence, upright: posterior}
    )()
    posterior = _FixedPosterior(person, shift_px=4.0)
    per_person = []
    result = evaluate_photos(
        predictor, [person], num_samples=3, show_progress=False, mode_errors=per_person
    )
    assert result["people"] == 1 and result["failed"] == 0
    assert per_person == [pytest.approx(result["joint_error_2d_mode"])]
    assert abs(result["joint_error_2d_mode"] - 8.0 * 256 / 512) < 1e-4
    assert abs(result["joint_error_2d_samples"] - 8.0 * 256 / 512) < 1e-4
    assert abs(result["joint_error_2d_mode_box_fraction"] - 8.0 / 400) < 1e-6
    assert abs(result["joint_error_2d_detector"] - 4.0 * 256 / 512) < 1e-4
    # every sample sits on the mode, 8 px from the annotations: no annotated keypoint is covered
    assert result["keypoint_coverage_2d_50"] == result["keypoint_coverage_2d_90"] == 0.0
    posterior = _FixedPosterior(person, shift_px=0.0)
    exact = evaluate_photos(predictor, [person], num_samples=3, show_progress=False)
    assert exact["keypoint_coverage_2d_90"] == 1.0


def test_concentration_scaling_scales_F_and_keeps_the_mode() -> None:
    import pytest

    from hkpd.evaluation.concentration_scaling import ConcentrationScaled

    torch.manual_seed(0)
    network = DistributionNetwork(NetworkConfig(backbone_base_width=8, image_size=64)).eval()
    proxy = torch.rand(2, 18, 64, 64)
    with torch.no_grad():
        plain, widened = network(proxy), ConcentrationScaled(network, 0.25)(proxy)
    torch.testing.assert_close(widened.F, 0.25 * plain.F)
    torch.testing.assert_close(
        widened.pose_distribution().mode, plain.pose_distribution().mode, atol=1e-5, rtol=0
    )
    torch.testing.assert_close(widened.camera, plain.camera)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="positive"):
            ConcentrationScaled(network, bad)


def test_eval_reports_one_row_per_concentration_scale(tmp_path, capsys) -> None:
    checkpoint = tiny_checkpoint(tmp_path)
    report = tmp_path / "report.md"
    arguments = [str(checkpoint), "--count", "3", "--samples", "4", "--out", str(report)]
    assert eval_main([*arguments, "--concentration-scale", "1", "1000"]) == 0
    lines = report.read_text().splitlines()
    rows = {}
    for factor in ("1", "1000"):
        row = next(line for line in lines if line.startswith(f"| {checkpoint} (F x {factor})"))
        rows[factor] = [float(cell) for cell in row.strip("|").split("|")[1:]]
    # MPJPE-SC and the 2D mode error come from the mode, which scaling F does not move ...
    assert rows["1"][0] == rows["1000"][0] and rows["1"][3] == rows["1000"][3]
    # ... while very concentrated distributions pull the samples onto the mode.
    gaps = {factor: abs(values[4] - values[3]) for factor, values in rows.items()}
    assert gaps["1000"] < 0.2 * gaps["1"]
    assert eval_main([*arguments, "--concentration-scale", "0"]) == 2
    assert "positive" in capsys.readouterr().err
    assert eval_main([*arguments, "--concentration-scale", "2", "--coco", str(tmp_path)]) == 2
    assert "separate run" in capsys.readouterr().err


def test_report_keeps_two_decimals_below_ten() -> None:
    from hkpd.evaluation.report import markdown_table

    table = markdown_table({"m": {"a": 0.12345, "b": 1.194, "c": 58.83, "d": float("nan")}})
    assert table.splitlines()[-1] == "| m | 0.123 | 1.19 | 58.8 | – |"


def test_eval_with_evidence_scores_both_posteriors(tmp_path, capsys) -> None:
    checkpoint = tiny_checkpoint(tmp_path)
    report = tmp_path / "report.md"
    arguments = [str(checkpoint), "--count", "4", "--samples", "3", "--out", str(report)]
    assert eval_main([*arguments, "--evidence", "--occlusion-cases", "2"]) == 0
    lines = report.read_text().splitlines()
    evidence_prefix = f"| {checkpoint} (2D evidence, mirror reading)"
    network_prefix = f"| {checkpoint} (network only, mirror reading)"
    evidence_rows = [line for line in lines if line.startswith(evidence_prefix)]
    network_rows = [line for line in lines if line.startswith(network_prefix)]
    assert len(evidence_rows) == 2 and len(network_rows) == 1  # synthetic table + occlusion
    network = [float(cell) for cell in network_rows[0].strip("|").split("|")[1:-1]]
    evidence = [float(cell) for cell in evidence_rows[0].strip("|").split("|")[1:]]
    # An untrained network is far from the keypoints; the evidence pulls the mode onto them.
    assert evidence[0] < 0.5 * network[0]
    assert evidence[-1] == 1.0  # every fit succeeded ("conditioned" share)
    assert eval_main([*arguments, "--evidence", "--concentration-scale", "2"]) == 2
    assert "one of them" in capsys.readouterr().err


def test_eval_scores_the_upright_reading_on_each_split(tmp_path) -> None:
    checkpoint = tiny_checkpoint(tmp_path)
    report = tmp_path / "report.md"
    arguments = [str(checkpoint), "--count", "4", "--samples", "2", "--out", str(report)]
    assert eval_main([*arguments, "--any-orientation", "--upright-reading"]) == 0
    table = report.read_text().split("All synthetic metrics")[0]
    names = [line.split("|")[1].strip() for line in table.splitlines() if line.startswith("| ")]
    assert names[1:] == [
        str(checkpoint),
        f"{checkpoint} (upright + mirror reading)",
        f"{checkpoint} (any orientation)",
        f"{checkpoint} (any orientation) (upright + mirror reading)",
    ]

    def rows_of(path: Path) -> dict[str, list[str]]:
        table = path.read_text().split("All synthetic metrics")[0]
        return {
            line.split("|")[1].strip(): line.split("|")[2:-1]
            for line in table.splitlines()
            if line.startswith(f"| {checkpoint}")
        }

    values = rows_of(report)
    # The rolled views are read differently, so at least one 3D error moves.
    assert (
        values[f"{checkpoint} (any orientation)"]
        != values[f"{checkpoint} (any orientation) (upright + mirror reading)"]
    )
    once = tmp_path / "once.md"
    arguments[-1] = str(once)
    assert eval_main([*arguments, "--any-orientation", "--upright-reading",
                      "--no-mirror-reading"]) == 0  # fmt: skip
    read_once = rows_of(once)
    assert f"{checkpoint} (any orientation) (upright reading)" in read_once
    assert (
        read_once[f"{checkpoint} (any orientation) (upright reading)"]
        != values[f"{checkpoint} (any orientation) (upright + mirror reading)"]
    )


def test_without_image_proxy_blanks_only_the_image_channels() -> None:
    from hkpd.evaluation.image_proxy_blanking import WithoutImageProxy

    seen = []

    class Recorder(torch.nn.Module):
        config = NetworkConfig(image_proxy="rgb", input_channels=20)

        def forward(self, proxy):
            seen.append(proxy)
            return "output"

    proxy = torch.rand(2, 20, 8, 8)
    wrapped = WithoutImageProxy(Recorder())
    assert wrapped(proxy) == "output" and wrapped.config.image_proxy == "rgb"
    assert (seen[0][:, :3] == 0).all()
    torch.testing.assert_close(seen[0][:, 3:], proxy[:, 3:])
    assert (proxy[:, :3] > 0).any()  # the caller's input is untouched
