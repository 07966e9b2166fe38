"""Reading leaning people from an upright copy: heatmap peaks, the torso's lean, the reader."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from limb_lean_network import LimbLeanNetwork, rolled_frontal

from hkpd.body import BodyModel
from hkpd.distributions import BodyDistribution
from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.lean import mode_torso_tilts
from hkpd.prediction.readings.proxy_reader import ProxyReader
from hkpd.prediction.readings.upright_view import UprightView, torso_tilt
from hkpd.proxy import assemble_proxy
from hkpd.proxy.heatmaps import heatmap_peaks, joint_heatmaps

SIZE = 64


def upright_reader(network: torch.nn.Module, **settings: object) -> ProxyReader:
    """The reading stage without the mirror reading: upright copies and the lean search."""
    return ProxyReader(network, ReadingConfig(mirror=False, **settings))


STANDING = np.array(
    [[32, 10], [31, 9], [33, 9], [30, 10], [34, 10],  # head
     [27, 16], [37, 16], [25, 24], [39, 24], [24, 31], [40, 31],  # arms
     [29, 32], [35, 32], [29, 43], [35, 43], [29, 54], [35, 54]],  # legs
    dtype=np.float64,
)  # fmt: skip
"""A person standing upright in a 64-pixel crop, COCO order, pixels."""


def turned(points: np.ndarray, degrees: float) -> np.ndarray:
    """``points`` turned clockwise on screen (v down) about the crop centre."""
    angle = math.radians(degrees)
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    centre = (SIZE - 1) / 2
    return (points - centre) @ rotation.T + centre


def test_heatmap_peaks_read_back_the_drawn_points_to_sub_pixel_precision() -> None:
    generator = torch.Generator().manual_seed(3)
    points = torch.rand(4, 17, 2, generator=generator) * (SIZE - 8) + 4
    present = torch.rand(4, 17, generator=generator) > 0.3
    found, found_present = heatmap_peaks(joint_heatmaps(points, present, SIZE))
    assert torch.equal(found_present, present)
    assert (found[present] - points[present]).norm(dim=-1).max() < 0.02
    assert (found[~present] == 0).all()


def test_torso_tilt_uses_one_side_or_stand_ins_when_the_torso_is_half_seen() -> None:
    lying = turned(STANDING, 90.0)
    everything = np.ones(17, dtype=bool)
    assert math.degrees(torso_tilt(lying, everything)) == pytest.approx(90.0, abs=1e-6)
    left_side = np.zeros(17, dtype=bool)
    left_side[[5, 11]] = True  # the left shoulder and hip only (seen from the side)
    standing_left = math.degrees(torso_tilt(STANDING, left_side))  # that side slants a little
    assert math.degrees(torso_tilt(lying, left_side)) == pytest.approx(90.0 + standing_left)
    head_and_knees = np.zeros(17, dtype=bool)
    head_and_knees[[0, 13, 14]] = True
    assert abs(math.degrees(torso_tilt(lying, head_and_knees)) - 90.0) < 10.0
    arms_only = np.zeros(17, dtype=bool)
    arms_only[[7, 8, 9, 10]] = True
    assert torso_tilt(lying, arms_only) is None


class RecordingNetwork(torch.nn.Module):
    """Answers the identity rotation and a fixed camera; keeps the proxies it was shown."""

    def __init__(self) -> None:
        super().__init__()
        self.config = NetworkConfig(backbone_base_width=8, image_size=SIZE)
        self.seen: list[torch.Tensor] = []

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        self.seen.append(proxy.clone())
        count = proxy.shape[0]
        return BodyDistribution(
            F=torch.eye(3).expand(count, 23, 3, 3) * 10.0,
            shape_mean=torch.zeros(count, 10),
            shape_std=torch.ones(count, 10),
            global_orient=torch.eye(3).expand(count, 3, 3).clone(),
            camera=torch.tensor([1.0, 0.0, 0.0]).expand(count, 3).clone(),
        )


def proxies_of(*people: np.ndarray, present: torch.Tensor | None = None) -> torch.Tensor:
    points = torch.as_tensor(np.stack(people), dtype=torch.float32)
    edges = torch.zeros(len(people), 1, SIZE, SIZE, dtype=torch.uint8)
    edges[:, :, 30:34, 20:44] = 255  # a bar, to see the edge channel move with the copy
    if present is None:
        present = torch.ones(len(people), 17, dtype=torch.bool)
    return assemble_proxy(edges, points, present)


def test_the_upright_copy_frames_only_the_joints_that_are_there() -> None:
    observed = np.ones(17, dtype=bool)
    observed[[0, 1, 2, 15, 16]] = False  # no face, no ankles
    lying = turned(STANDING, -120.0)
    read_as_zero, elsewhere = lying.copy(), lying.copy()
    read_as_zero[~observed] = 0.0  # where heatmap_peaks puts absent joints
    elsewhere[~observed] = 50.0
    tilt = torso_tilt(lying, observed)
    framed = [UprightView.from_tilt(tilt, points, SIZE, observed).box
              for points in (read_as_zero, elsewhere)]  # fmt: skip
    assert framed[0] == framed[1]
    unframed = [UprightView.from_tilt(tilt, points, SIZE).box
                for points in (read_as_zero, elsewhere)]  # fmt: skip
    assert unframed[0] != unframed[1]  # without ``observed`` every point counts


def test_the_reader_turns_leaning_people_upright_and_maps_the_answer_back() -> None:
    network = RecordingNetwork()
    reader = upright_reader(network)
    output = reader(proxies_of(STANDING, turned(STANDING, 100.0)))
    shown = network.seen[-1]
    assert math.isnan(reader.last_tilts_degrees[0])
    assert reader.last_tilts_degrees[1] == pytest.approx(100.0, abs=0.5)
    torch.testing.assert_close(shown[0], proxies_of(STANDING)[0])  # upright: untouched
    keypoints, present = heatmap_peaks(shown[1:, 1:])
    tilt = torso_tilt(keypoints[0].numpy(), present[0].numpy())
    assert abs(math.degrees(tilt)) < 1.0  # the network saw the lying person upright
    assert shown[1, 0].sum() > 0 and not torch.equal(shown[1, 0], shown[0, 0])  # edges turned
    torch.testing.assert_close(output.global_orient[0], torch.eye(3))
    rotation = output.global_orient[1].double()
    about_axis = math.degrees(math.atan2(float(rotation[1, 0]), float(rotation[0, 0])))
    assert about_axis == pytest.approx(reader.last_tilts_degrees[1], abs=1e-3)
    torch.testing.assert_close(output.F, network(shown).F)  # relative rotations stay


def test_the_reader_frames_its_copies_on_the_crops_keypoints_when_given() -> None:
    network = RecordingNetwork()
    reader = upright_reader(network)
    lying = turned(STANDING, 100.0)
    present = torch.ones(1, 17, dtype=torch.bool)
    present[0, [0, 1, 2, 3, 4, 15, 16]] = False  # no face, no ankles in the heatmaps
    proxy = proxies_of(lying, present=present)
    reader(proxy)
    on_shown = network.seen[-1]
    reader(proxy, crop_keypoints=torch.as_tensor(lying[None], dtype=torch.float32))
    on_all = network.seen[-1]

    # Framed on all 17 points, the copy shows the person smaller than framed on the shown ones.
    def spread(shown: torch.Tensor) -> float:
        keypoints, seen = heatmap_peaks(shown[:, 1:])
        return float(keypoints[0][seen[0]].std(0).norm())

    assert spread(on_all) < 0.9 * spread(on_shown)
    keypoints, seen = heatmap_peaks(on_all[:, 1:])
    view = UprightView.from_tilt(math.radians(reader.last_tilts_degrees[0]), lying, SIZE)
    torch.testing.assert_close(
        keypoints[0][seen[0]].double(),
        torch.as_tensor(view.points(lying)[present[0].numpy()]),
        atol=0.05,
        rtol=0,
    )
    with pytest.raises(ValueError, match="crop_keypoints"):
        reader(proxy, crop_keypoints=torch.zeros(1, 16, 2))


def test_the_reader_is_the_network_itself_for_upright_people() -> None:
    torch.manual_seed(0)
    network = DistributionNetwork(NetworkConfig(backbone_base_width=8, image_size=SIZE)).eval()
    proxy = proxies_of(STANDING, turned(STANDING, 15.0))
    with torch.no_grad():
        direct, read = network(proxy), upright_reader(network)(proxy)
    for mine, theirs in zip(read.tensors(), direct.tensors(), strict=True):
        torch.testing.assert_close(mine, theirs, rtol=0, atol=0)
    with pytest.raises(ValueError, match="upright_start_degrees"):
        ReadingConfig(upright_start_degrees=-1.0)


LIMBS_ONLY = torch.zeros(1, 17, dtype=torch.bool)
LIMBS_ONLY[0, [7, 8, 9, 10, 15, 16]] = True  # elbows, wrists, ankles: no torso, no stand-in


def test_the_lean_of_the_body_a_network_reads_is_its_torsos_on_screen() -> None:
    leans = [0.0, 70.0, -135.0, 180.0]
    output = BodyDistribution(
        F=torch.eye(3).expand(4, 23, 3, 3) * 1000.0,
        shape_mean=torch.zeros(4, 10),
        shape_std=torch.ones(4, 10),
        global_orient=torch.stack([rolled_frontal(lean) for lean in leans]),
        camera=torch.tensor([[1.0, 0.0, 0.0], [2.0, 0.1, 0.0], [1.0, 0.0, 0.3], [0.5, 0, 0]]),
    )
    tilts = mode_torso_tilts(output, BodyModel(), SIZE)
    for tilt, lean in zip(tilts, leans, strict=True):
        off = (math.degrees(tilt) - lean + 180.0) % 360.0 - 180.0
        assert abs(off) < 1.0, (math.degrees(tilt), lean)


def test_without_a_torso_the_reader_turns_people_by_the_lean_that_fits_what_is_shown() -> None:
    lying = turned(STANDING, 110.0)
    proxy = proxies_of(STANDING, lying, present=LIMBS_ONLY.expand(2, 17))
    network = LimbLeanNetwork(SIZE, reads_within_degrees=40.0)  # reads lying people as upright
    reader = upright_reader(network)
    output = reader(proxy)
    # The lying person is turned by a lean that shows them within the network's range, and
    # read right there; whichever copy is read, both answers come back as the people lie.
    assert abs(reader.last_tilts_degrees[1] - 110.0) <= 40.0, reader.last_tilts_degrees
    assert abs(network.leans[-1][1]) <= 40.0
    for index, lean in enumerate((0.0, 110.0)):
        torch.testing.assert_close(
            output.global_orient[index].double(), rolled_frontal(lean).double(), atol=0.06, rtol=0
        )  # within about 3 degrees
    # Read as it is, the same network answers upright: a body 110 degrees off.
    direct = network(proxy)
    assert (direct.global_orient[1] - rolled_frontal(110.0)).abs().max() > 0.5
    as_read = upright_reader(LimbLeanNetwork(SIZE), lean_search=False)
    as_read(proxy)
    assert np.isnan(as_read.last_tilts_degrees).all()
