"""hkpd-tune-evidence: settings parsed, every setting scored on tuning photos and synthetic
validation images, clear errors."""

import json
import math
from pathlib import Path

import pytest
import torch

from hkpd.conditioning import EvidenceConfig
from hkpd.evaluation.evidence_tuning import main as tune_main
from hkpd.evaluation.evidence_tuning import parse_setting
from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import save_checkpoint

SHIPPED_PHOTO = Path(__file__).parents[1] / "assets" / "photos" / "warrior_lunge.jpg"


def test_settings_parse_short_and_long_names() -> None:
    config = parse_setting("w=0.3, sigma=0.04,spread=marginal,robust_scale=2")
    assert config == EvidenceConfig(
        prior_weight=0.3, keypoint_sigma=0.04, joint_spread="marginal", robust_scale=2.0
    )
    assert parse_setting("") == EvidenceConfig()
    with pytest.raises(ValueError, match="names among"):
        parse_setting("weight=0.3")
    with pytest.raises(ValueError, match="must be a number"):
        parse_setting("w=heavy")
    with pytest.raises(ValueError, match="positive"):
        parse_setting("sigma=0")
    with pytest.raises(ValueError, match="'marginal' or 'conditional'"):
        parse_setting("spread=full")


def _coco_folder_of_the_shipped_photo(folder: Path) -> Path:
    """A one-person COCO folder: the shipped photo, its keypoints as BlazePose finds them."""
    from hkpd.prediction.detection.keypoint_detector import KeypointDetector

    with KeypointDetector() as detector:
        detection = detector.detect(str(SHIPPED_PHOTO))
    (folder / "annotations").mkdir(parents=True)
    (folder / "train2017").mkdir()
    (folder / "train2017" / "1.jpg").write_bytes(SHIPPED_PHOTO.read_bytes())
    points = detection.keypoints
    x0, y0 = points.min(0) - 20
    x1, y1 = points.max(0) + 20
    annotation = {
        "image_id": 1,
        "keypoints": [float(v) for point in points for v in (*point, 2)],
        "bbox": [float(x0), float(y0), float(x1 - x0), float(y1 - y0)],
        "iscrowd": 0,
    }
    data = {"images": [{"id": 1, "file_name": "1.jpg"}], "annotations": [annotation]}
    (folder / "annotations" / "person_keypoints_train2017.json").write_text(json.dumps(data))
    return folder


def test_every_setting_gets_a_row_that_depends_on_it(tmp_path, capsys) -> None:
    torch.manual_seed(0)
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    checkpoint = save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    coco = _coco_folder_of_the_shipped_photo(tmp_path / "coco")
    report = tmp_path / "tuning.md"
    arguments = [str(checkpoint), "--coco", str(coco), "--count", "4", "--samples", "4"]
    settings = ["--setting", "w=0.05,sigma=0.02", "--setting", "w=1,sigma=0.06"]
    assert tune_main([*arguments, *settings, "--out", str(report)]) == 0
    lines = [line for line in report.read_text().splitlines() if line.startswith("| ")]
    header, rows = lines[0], {line.split(" | ")[0][2:]: line for line in lines[1:]}
    assert "covered limb" in header and "coverage 90" in header
    assert set(rows) == {
        "network only",
        "w 0.05, sigma 0.02, robust 3, conditional",
        "w 1, sigma 0.06, robust 3, conditional",
    }
    values = {
        name: [float(cell) for cell in line.strip(" |").split(" | ")[1:]]
        for name, line in rows.items()
    }
    assert all(math.isfinite(v) and v >= 0 for row in values.values() for v in row)
    photo_coverage = [header.split(" | ").index(f"photos: 2D coverage {q} %") for q in (50, 90)]
    for row in values.values():  # shares, the 90 % disc holding at least what the 50 % one does
        low, high = (row[column - 1] for column in photo_coverage)
        assert 0.0 <= low <= high <= 1.0
    sharp, loose = (
        values["w 0.05, sigma 0.02, robust 3, conditional"],
        values["w 1, sigma 0.06, robust 3, conditional"],
    )
    assert sharp != loose
    # a strong prior and loose keypoints leave the mode further from the evidence
    assert sharp[0] < loose[0]


def test_missing_inputs_are_clear_errors(tmp_path, capsys) -> None:
    missing = tmp_path / "missing.pt"
    assert tune_main([str(missing), "--coco", str(tmp_path)]) == 2
    assert "does not exist" in capsys.readouterr().err
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    checkpoint = save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    assert tune_main([str(checkpoint), "--coco", str(tmp_path / "nowhere")]) == 2
    assert "COCO folder" in capsys.readouterr().err
    assert tune_main([str(checkpoint), "--coco", str(tmp_path), "--setting", "x=1"]) == 2
    assert "names among" in capsys.readouterr().err


def test_write_to_stores_the_one_setting_in_a_checkpoint_copy(tmp_path, capsys) -> None:
    from hkpd.network.checkpoint import read_checkpoint, stored_evidence_config

    config = NetworkConfig(backbone_base_width=8, image_size=64)
    checkpoint = save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    coco = _coco_folder_of_the_shipped_photo(tmp_path / "coco")
    arguments = [str(checkpoint), "--coco", str(coco), "--count", "2", "--samples", "2"]
    tuned = tmp_path / "tuned.pt"
    assert tune_main([*arguments, "--write-to", str(tuned)]) == 2  # which setting?
    assert "exactly one --setting" in capsys.readouterr().err and not tuned.exists()
    setting = ["--setting", "w=0.3,spread=marginal", "--no-network-row"]
    assert tune_main([*arguments, *setting, "--write-to", str(tuned)]) == 0
    assert f"in {tuned}" in capsys.readouterr().out
    stored = stored_evidence_config(read_checkpoint(tuned))
    assert EvidenceConfig.from_dict(stored, str(tuned)) == parse_setting("w=0.3,spread=marginal")
    assert stored_evidence_config(read_checkpoint(checkpoint)) == {}  # the source is unchanged
