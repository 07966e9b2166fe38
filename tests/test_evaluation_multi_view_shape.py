"""Shape from several photos of one person on synthetic data (hkpd.evaluation.multi_view_shape)."""

from __future__ import annotations

import pytest
import torch
from test_evaluation_shape import _ShapePull  # a toy term: coefficient 1 is 3 ± 0.05

from hkpd.evaluation.cli import main as eval_main
from hkpd.evaluation.multi_view_shape import (
    MULTI_VIEW_COLUMNS,
    MultiViewPredictions,
    multi_view_shape_table,
    predict_multi_view_shapes,
)
from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import save_checkpoint
from hkpd.network.config import NetworkConfig
from hkpd.poses import ProceduralPosePrior
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator


class RecordingNetwork(torch.nn.Module):
    """A tiny network that also records the batches it saw."""

    def __init__(self) -> None:
        super().__init__()
        torch.manual_seed(0)
        self.network = DistributionNetwork(NetworkConfig(backbone_base_width=8, image_size=64))
        self.seen: list[torch.Tensor] = []

    def forward(self, proxy: torch.Tensor):
        self.seen.append(proxy)
        return self.network(proxy)


def test_views_of_one_body_share_betas_and_differ_in_pictures() -> None:
    generator = SyntheticDataGenerator(ProceduralPosePrior(), SyntheticDataConfig(image_size=64))
    network = RecordingNetwork().eval()
    predictions = predict_multi_view_shapes(network, generator, bodies=3, views=2, batch_size=2)
    assert predictions.true_betas.shape == (3, 10)
    assert predictions.means.shape == predictions.stds.shape == (2, 3, 10)
    assert (predictions.stds > 0).all()
    assert [proxy.shape[0] for proxy in network.seen] == [2, 1, 2, 1]  # views x chunks
    assert not torch.equal(network.seen[0][:1], network.seen[2][:1])  # another view, same body
    again = predict_multi_view_shapes(RecordingNetwork().eval(), generator, 3, 2, batch_size=2)
    torch.testing.assert_close(again.means, predictions.means)  # reproducible


def test_table_scores_a_perfect_and_a_biased_photo() -> None:
    from hkpd.body import BodyModel

    truth = torch.randn(4, 10, generator=torch.Generator().manual_seed(1))
    # Photo 1 is exact and sure; photo 2 is off by 2 and very unsure.
    means = torch.stack([truth, truth + 2.0])
    stds = torch.stack([torch.full((4, 10), 0.1), torch.full((4, 10), 10.0)])
    rows = multi_view_shape_table(MultiViewPredictions(truth, means, stds), BodyModel(),
                                  uncertainty_samples=8, uncertainty_bodies=2)  # fmt: skip
    assert list(rows) == ["1 photo", "2 photos"]
    assert list(rows["1 photo"]) == MULTI_VIEW_COLUMNS
    two = rows["2 photos"]
    assert two["pve_t_sc_product"] < 0.05  # mm: the product keeps the sure, exact photo
    assert two["pve_t_sc_mean"] > 5.0  # the plain mean is pulled by the unsure one
    # One photo: the mean of the two single scores, each photo once.
    assert rows["1 photo"]["pve_t_sc_product"] == pytest.approx(two["pve_t_sc_single"])
    assert rows["1 photo"]["pve_t_sc_mean"] == pytest.approx(two["pve_t_sc_single"])
    assert two["shape_std_product"] == pytest.approx((0.1**-2 + 10.0**-2) ** -0.5, rel=1e-5)
    assert rows["1 photo"]["shape_std_product"] == pytest.approx((0.1 + 10.0) / 2, rel=1e-5)
    assert 0 < two["shape_uncertainty_product_mm"] < rows["1 photo"]["shape_uncertainty_product_mm"]


def test_eval_flag_prints_the_multi_view_table(tmp_path, capsys) -> None:
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    checkpoint = save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    code = eval_main([str(checkpoint), "--no-synthetic", "--multi-view-shape", "2"])
    text = capsys.readouterr().out
    assert code == 0
    assert "Shape from 1-5 photos of one person" in text and "2 synthetic bodies x 5 views" in text
    assert "PVE-T-SC probabilistic (mm)" in text
    rows = [line.split("|")[1].strip() for line in text.splitlines() if line.startswith("| ")]
    assert rows[-5:] == ["1 photo", "2 photos", "3 photos", "4 photos", "5 photos"]
    assert eval_main([str(checkpoint), "--multi-view-shape", "-1"]) == 2
    assert "--multi-view-shape must be >= 0" in capsys.readouterr().err


def test_evidence_views_are_the_network_views_and_their_terms_reach_each_fit() -> None:
    from hkpd.conditioning import EvidenceConfig
    from hkpd.evaluation.multi_view_evidence import predict_multi_view_evidence_shapes
    from hkpd.evaluation.shape_eval import MaskedExample, no_extra_terms

    generator = SyntheticDataGenerator(ProceduralPosePrior(), SyntheticDataConfig(image_size=64))
    network = RecordingNetwork().eval()
    seen: list[MaskedExample] = []

    def pull(example: MaskedExample) -> list:
        seen.append(example)
        return [_ShapePull()]

    predictions = predict_multi_view_evidence_shapes(
        network, generator, {"evidence": no_extra_terms, "pulled": pull}, EvidenceConfig(),
        bodies=3, views=2, batch_size=2,
    )  # fmt: skip
    assert list(predictions) == ["network", "evidence", "pulled"]
    plain = predict_multi_view_shapes(RecordingNetwork().eval(), generator, 3, 2, batch_size=2)
    # The same bodies and views as the network-only table: the same readings.
    torch.testing.assert_close(predictions["network"].true_betas, plain.true_betas)
    torch.testing.assert_close(predictions["network"].means, plain.means)
    assert len(seen) == 6 and all(bool(e.silhouette.any()) for e in seen)  # 2 views x 3 bodies
    for name in ("evidence", "pulled"):
        assert predictions[name].means.shape == predictions[name].stds.shape == (2, 3, 10)
        assert (predictions[name].stds > 0).all()
    # The pull reaches every view's fit, and only the posterior it was given to.
    assert (predictions["pulled"].means[..., 1] - 3.0).abs().max() < 0.3
    assert (predictions["evidence"].means[..., 1] - 3.0).abs().min() > 0.5
    with pytest.raises(ValueError, match="differ"):
        predict_multi_view_evidence_shapes(
            network, generator, {"network": no_extra_terms}, EvidenceConfig(), bodies=1, views=1
        )


def test_eval_flag_with_evidence_adds_the_evidence_posteriors_tables(tmp_path, capsys) -> None:
    config = NetworkConfig(backbone_base_width=8, image_size=64)
    checkpoint = save_checkpoint(
        tmp_path / "tiny.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    arguments = [str(checkpoint), "--no-synthetic", "--multi-view-shape", "1", "--evidence"]
    assert eval_main([*arguments, "--silhouette-evidence"]) == 0
    text = capsys.readouterr().out
    for name in ("network", "evidence", "evidence_silhouette"):
        assert f"one person, {name} posterior" in text
    assert text.count("PVE-T-SC probabilistic (mm)") == 4  # the plain table and three more
