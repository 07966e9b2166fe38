"""Reading the mirror image of a proxy and choosing between the two readings by keypoint fit."""

from __future__ import annotations

import roma
import torch

from hkpd.body import BodyModel
from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.coco_keypoints import COCO17_MIRROR_ORDER, COCO17_NAMES
from hkpd.distributions import BodyDistribution
from hkpd.network import NetworkConfig
from hkpd.prediction.readings.mirror import MirrorChoosingReader, mirror_proxy, unmirror_output
from hkpd.proxy import assemble_proxy

SIZE = 64


def a_reading(count: int, seed: int) -> BodyDistribution:
    """A random, confident reading: a bent body, turned and shifted in its crop."""
    generator = torch.Generator().manual_seed(seed)
    pose = roma.rotvec_to_rotmat(0.4 * torch.randn(count, 23, 3, generator=generator))
    turn = roma.rotvec_to_rotmat(torch.tensor([[3.14159, 0.0, 0.0]]) + 0.5 * torch.randn(
        count, 3, generator=generator))  # fmt: skip
    camera = torch.stack([torch.full((count,), 0.9), *(0.2 * torch.randn(2, count,
                          generator=generator))], -1)  # fmt: skip
    return BodyDistribution(
        F=pose * 200.0,
        shape_mean=0.5 * torch.randn(count, 10, generator=generator),
        shape_std=torch.ones(count, 10),
        global_orient=turn,
        camera=camera,
    )


def mode_keypoints(output: BodyDistribution, body: BodyModel) -> torch.Tensor:
    """``(B, 17, 2)`` crop pixels of the reading's most likely body."""
    joints, _ = pelvis_relative_body(
        body, output.shape_mean, output.pose_distribution().mode, output.global_orient
    )
    return ndc_to_pixels(weak_perspective_project(joints, output.camera), SIZE)


def test_the_mirror_order_swaps_every_left_keypoint_with_its_right_partner() -> None:
    for index, name in enumerate(COCO17_NAMES):
        partner = COCO17_NAMES[COCO17_MIRROR_ORDER[index]]
        expected = name.replace("left", "RIGHT").replace("right", "left").replace("RIGHT", "right")
        assert partner == expected


def test_mirroring_twice_gives_back_the_proxy_and_the_reading() -> None:
    proxy = torch.rand(2, 18, SIZE, SIZE)
    torch.testing.assert_close(mirror_proxy(mirror_proxy(proxy)), proxy, rtol=0, atol=0)
    assert not torch.equal(mirror_proxy(proxy), proxy)
    reading = a_reading(3, 0)
    again = unmirror_output(unmirror_output(reading))
    for mine, theirs in zip(again.tensors(), reading.tensors(), strict=True):
        torch.testing.assert_close(mine, theirs)


def test_a_mirrored_reading_maps_back_to_the_mirror_image_of_its_keypoints() -> None:
    """The body read off a mirror image, mapped back, is the mirror image of that body: its
    keypoints are the reading's, columns reflected (u -> S - 1 - u), left and right swapped."""
    body = BodyModel()
    reading = a_reading(3, 1)
    shown = mode_keypoints(reading, body)
    mapped = mode_keypoints(unmirror_output(reading), body)
    expected = shown[:, list(COCO17_MIRROR_ORDER)] * torch.tensor([-1.0, 1.0]) + torch.tensor(
        [SIZE - 1.0, 0.0]
    )
    # The body's rest skeleton is left/right symmetric to ~4e-5 m (< 0.01 px here).
    torch.testing.assert_close(mapped, expected, atol=0.02, rtol=0)
    assert (mapped - shown).abs().max() > 1.0


class FixedReading(torch.nn.Module):
    """Answers the same reading for every proxy it is shown; records the batch sizes."""

    def __init__(self, reading: BodyDistribution) -> None:
        super().__init__()
        self.config = NetworkConfig(backbone_base_width=8, image_size=SIZE)
        self.reading = reading
        self.batch_sizes: list[int] = []

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        self.batch_sizes.append(int(proxy.shape[0]))
        count = proxy.shape[0]
        return self.reading.map(lambda tensor: tensor.expand(count, *tensor.shape[1:]).clone())


def test_the_reader_keeps_whichever_reading_fits_the_shown_keypoints() -> None:
    """A network that always answers body B reads B as it is and mirror(B) mirrored; with
    heatmaps drawn where mirror(B)'s keypoints are, the mirrored reading must win, with
    heatmaps at B's the reading as it is."""
    body = BodyModel()
    reading = a_reading(1, 2)
    network = FixedReading(reading)
    reader = MirrorChoosingReader(network, body=body)
    own, mirrored = mode_keypoints(reading, body), mode_keypoints(unmirror_output(reading), body)
    points = torch.cat([own, mirrored]).clamp(1, SIZE - 2)  # heatmap peaks stay inside
    proxy = assemble_proxy(
        torch.zeros(2, 1, SIZE, SIZE, dtype=torch.uint8), points, torch.ones(2, 17, dtype=bool)
    )
    output = reader(proxy)
    assert network.batch_sizes == [4]  # both readings of both examples in one batch
    assert reader.last_mirrored.tolist() == [False, True]
    torch.testing.assert_close(output.global_orient[0], reading.global_orient[0])
    torch.testing.assert_close(output.global_orient[1], unmirror_output(reading).global_orient[0])
    torch.testing.assert_close(output.camera[1], reading.camera[0] * torch.tensor([1, -1, 1.0]))
    # The readings not kept are the other way round.
    torch.testing.assert_close(reader.last_other.camera[0], output.camera[1])
    torch.testing.assert_close(reader.last_other.camera[1], output.camera[0])
    nothing_shown = assemble_proxy(
        torch.zeros(1, 1, SIZE, SIZE, dtype=torch.uint8), points[:1], torch.zeros(1, 17, dtype=bool)
    )
    reader(nothing_shown)
    assert reader.last_mirrored.tolist() == [False]  # no evidence: the reading as it is
