"""The tuned evidence settings travel with the weights: stored in the checkpoint, read back by
the predictor, old checkpoints on the defaults, nothing unknown ignored."""

from __future__ import annotations

import pytest
import torch

from hkpd.conditioning import EvidenceConfig
from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import (
    VERSION,
    CheckpointError,
    model_checksum,
    read_checkpoint,
    save_checkpoint,
    store_evidence_config,
    stored_evidence_config,
)
from hkpd.prediction.predictor import Predictor, shipped_model_path

TUNED = EvidenceConfig(prior_weight=0.3, keypoint_sigma=0.04, joint_spread="marginal")


@pytest.fixture
def plain_checkpoint(tmp_path):
    """A tiny network's checkpoint with no evidence settings (as every one before them)."""
    torch.manual_seed(0)
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    network = DistributionNetwork(config)
    return save_checkpoint(tmp_path / "plain.pt", network, config.to_dict(), 3, {}, 48)


def test_settings_round_trip_through_a_checkpoint(tmp_path, plain_checkpoint) -> None:
    assert EvidenceConfig.from_dict(TUNED.to_dict(), "here") == TUNED
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    saved = save_checkpoint(
        tmp_path / "tuned.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0,
        evidence_config=TUNED.to_dict(),
    )  # fmt: skip
    payload = read_checkpoint(saved)
    assert EvidenceConfig.from_dict(stored_evidence_config(payload), str(saved)) == TUNED
    # stored into a copy of an existing checkpoint: the weights and the rest as they were
    copy = store_evidence_config(plain_checkpoint, tmp_path / "copy.pt", TUNED.to_dict())
    before, after = read_checkpoint(plain_checkpoint), read_checkpoint(copy)
    assert after["version"] == VERSION and after["step"] == before["step"] == 3
    assert model_checksum(after["model"]) == model_checksum(before["model"]) == after["checksum"]
    assert EvidenceConfig.from_dict(stored_evidence_config(after), str(copy)) == TUNED
    assert stored_evidence_config(before) == {}


def test_old_checkpoints_get_todays_defaults(plain_checkpoint) -> None:
    shipped = read_checkpoint(shipped_model_path())
    assert stored_evidence_config(shipped) == {}
    assert EvidenceConfig.from_dict({}, "shipped") == EvidenceConfig()
    predictor = Predictor.from_pretrained(plain_checkpoint, device="cpu")
    assert predictor.evidence_config == EvidenceConfig()
    # a partial dict: what it names, the defaults for the rest
    partial = EvidenceConfig.from_dict({"prior_weight": 1, "max_iterations": 12.0}, "x")
    assert partial == EvidenceConfig(prior_weight=1.0, max_iterations=12)
    assert isinstance(partial.prior_weight, float) and isinstance(partial.max_iterations, int)


def test_the_predictor_uses_the_stored_settings_unless_given_others(
    tmp_path, plain_checkpoint
) -> None:
    tuned = store_evidence_config(plain_checkpoint, tmp_path / "tuned.pt", TUNED.to_dict())
    assert Predictor.from_pretrained(tuned, device="cpu").evidence_config == TUNED
    mine = EvidenceConfig(prior_weight=0.7)
    given = Predictor.from_pretrained(tuned, device="cpu", evidence_config=mine)
    assert given.evidence_config == mine


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"prior_wieght": 0.3}, r"unknown evidence setting\(s\) \['prior_wieght'\]"),
        ({"prior_weight": "heavy"}, "prior_weight must be like 0.5, got 'heavy'"),
        ({"max_iterations": 2.5}, "max_iterations must be like 30"),
        ({"joint_spread": True}, "joint_spread must be like 'conditional'"),
        ({"prior_weight": -1.0}, "prior_weight must be a positive number"),
    ],
)
def test_bad_stored_settings_are_errors_naming_the_file(
    tmp_path, plain_checkpoint, settings, message
) -> None:
    bad = store_evidence_config(plain_checkpoint, tmp_path / "bad.pt", settings)
    with pytest.raises(ValueError, match=message) as error:
        Predictor.from_pretrained(bad, device="cpu")
    assert str(bad) in str(error.value)


def test_malformed_settings_make_the_checkpoint_unreadable(tmp_path, plain_checkpoint) -> None:
    payload = read_checkpoint(plain_checkpoint)
    payload["evidence_config"] = [0.3]
    torch.save(payload, tmp_path / "malformed.pt")
    with pytest.raises(CheckpointError, match="malformed evidence settings"):
        read_checkpoint(tmp_path / "malformed.pt")


def test_tools_that_rewrite_weights_keep_the_stored_settings(tmp_path, plain_checkpoint) -> None:
    from hkpd.evaluation.test_set import stored_evidence_settings
    from hkpd.training.average_weights import average_checkpoints
    from hkpd.training.export import export_weights

    tuned = store_evidence_config(plain_checkpoint, tmp_path / "tuned.pt", TUNED.to_dict())
    exported = export_weights(tuned, tmp_path / "exported.pt")
    averaged = average_checkpoints([tuned, exported], tmp_path / "averaged.pt")
    for path in (tuned, exported, averaged):
        assert stored_evidence_settings(path) == TUNED, path
    # hkpd-eval's synthetic evidence rows read the same settings the predictor does
    assert stored_evidence_settings(plain_checkpoint) == EvidenceConfig()
    assert Predictor.from_pretrained(exported, device="cpu").evidence_config == TUNED
