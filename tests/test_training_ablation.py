"""The four-way ablation driver: configurations, training, export and resumption."""

from __future__ import annotations

import pytest

from hkpd.network.checkpoint import load_network, read_checkpoint
from hkpd.training.ablation import ABLATION_RUNS, PROXY_RUNS, ablation_configs, main
from hkpd.training.config import TrainConfig


def test_configs_differ_only_in_head_and_samples_loss(tmp_path) -> None:
    base = TrainConfig(steps=123, samples_loss_from=7, joints3d_loss_from=9, image_size=96)
    configs = ablation_configs(base, tmp_path)
    assert list(configs) == list(ABLATION_RUNS)
    heads = {name: c.pose_head for name, c in configs.items()}
    assert heads["independent_samples"] == "independent"
    assert heads["hierarchical_no_samples"] == "hierarchical"
    assert configs["independent_no_samples"].samples_loss_from == -1
    assert configs["hierarchical_samples"].samples_loss_from == 7
    for name, config in configs.items():
        assert config.out == tmp_path / name
        assert (config.steps, config.joints3d_loss_from, config.image_size) == (123, 9, 96)
    with pytest.raises(ValueError, match="samples-loss-from"):
        ablation_configs(TrainConfig(samples_loss_from=-1), tmp_path)


def test_proxy_study_differs_only_in_the_image_proxy(tmp_path) -> None:
    base = TrainConfig(steps=50, samples_loss_from=7, image_size=96, pose_head="hierarchical")
    configs = ablation_configs(base, tmp_path, "proxies")
    assert list(configs) == list(PROXY_RUNS)
    assert [c.image_proxy for c in configs.values()] == ["silhouette", "rgb", "edges"]
    for config in configs.values():
        assert (config.pose_head, config.samples_loss_from) == ("independent", -1)  # paper rows 1-3
        assert config.network_config().input_channels == (20 if config.image_proxy == "rgb" else 18)
        assert config.data_config().image_proxy == config.image_proxy
    # Without the samples loss in the base the proxy study is still well defined.
    assert len(ablation_configs(TrainConfig(samples_loss_from=-1), tmp_path, "proxies")) == 3
    with pytest.raises(ValueError, match="unknown study"):
        ablation_configs(base, tmp_path, "losses")


def test_tiny_ablation_trains_exports_and_skips_finished_runs(tmp_path, capsys) -> None:
    flags = [
        "--out", str(tmp_path), "--steps", "2", "--batch-size", "2", "--image-size", "32",
        "--backbone-base-width", "8", "--samples-loss-from", "1", "--joints3d-loss-from", "-1",
        "--num-samples", "2", "--val-every", "0", "--val-size", "2", "--log-every", "1",
        "--quiet",
    ]  # fmt: skip
    assert main(flags) == 0
    printed = capsys.readouterr().out
    assert "hkpd-eval" in printed
    for name in ABLATION_RUNS:
        _network, payload = load_network(tmp_path / f"{name}.pt")
        assert payload["network_config"]["pose_head"] == ABLATION_RUNS[name]["pose_head"]
        assert read_checkpoint(tmp_path / name / "last.pt")["step"] == 2
    # A second call finds every run finished and trains nothing.
    assert main(flags) == 0
    assert "training" not in capsys.readouterr().out
