"""The reading stage: the layout of its network calls and the lean search's batches."""

from __future__ import annotations

import math

import numpy as np
import torch
from limb_lean_network import LimbLeanNetwork, rolled_frontal
from test_proxy_reader import LIMBS_ONLY, SIZE, STANDING, proxies_of, turned

from hkpd.prediction.readings import LEAN_SEARCH_BATCH, ReadingConfig, ReadingStage
from hkpd.prediction.readings.lean import LEAN_CANDIDATES_DEGREES
from hkpd.prediction.readings.proxy_reader import proxy_reading_input

AS_IT_IS = ReadingConfig(mirror=False)


class CountingNetwork(LimbLeanNetwork):
    """:class:`LimbLeanNetwork`, also keeping the batch size of every call."""

    def __init__(self, image_size: int, reads_within_degrees: float = 180.0) -> None:
        super().__init__(image_size, reads_within_degrees)
        self.batch_sizes: list[int] = []

    def forward(self, proxy: torch.Tensor):
        self.batch_sizes.append(int(proxy.shape[0]))
        return super().forward(proxy)


def test_keeping_the_reading_as_it_is_appends_the_upright_copies_to_the_same_call() -> None:
    network = CountingNetwork(SIZE)
    stage = ReadingStage(network, config=AS_IT_IS)
    batch = proxy_reading_input(proxies_of(STANDING, turned(STANDING, 100.0), STANDING))
    both = stage.read(batch, keep_as_it_is=True)
    assert network.batch_sizes == [4]  # three proxies as they are, then the one upright copy
    assert both.chosen_rows == (0, 3, 2)
    assert both.row_views[:3] == (None, None, None) and both.row_views[3] is both.views[1]
    assert abs(both.tilts_degrees[1] - 100.0) < 0.5 and np.isnan(both.tilts_degrees[[0, 2]]).all()
    once = stage.read(batch)
    assert network.batch_sizes[-1] == 3  # the copy replaces its proxy
    for mine, theirs in zip(once.chosen().tensors(), both.chosen().tensors(), strict=True):
        torch.testing.assert_close(mine, theirs)
    # The reading as it is of the leaning person is kept too, in the proxy's own frame.
    torch.testing.assert_close(
        both.distribution.global_orient[1], rolled_frontal(100.0), atol=0.06, rtol=0
    )
    assert stage.read(batch, upright=False).views == (None, None, None)


def test_the_lean_search_reads_every_candidate_in_batches_and_keeps_the_best_fit() -> None:
    count = 3  # 3 x 11 or 12 candidate copies: more than one batch
    lying = [turned(STANDING, degrees) for degrees in (110.0, -80.0, 150.0)]
    proxy = proxies_of(*lying, present=LIMBS_ONLY.expand(count, 17))
    network = CountingNetwork(SIZE, reads_within_degrees=40.0)
    readings = ReadingStage(network, config=AS_IT_IS).read(proxy_reading_input(proxy))
    candidates = sum(network.batch_sizes[1:-1])
    assert network.batch_sizes[0] == count and network.batch_sizes[-1] == count
    assert (
        count * len(LEAN_CANDIDATES_DEGREES)
        <= candidates
        <= count * (len(LEAN_CANDIDATES_DEGREES) + 1)
    )
    assert max(network.batch_sizes[1:-1]) == LEAN_SEARCH_BATCH
    for tilt, degrees in zip(readings.tilts_degrees, (110.0, -80.0, 150.0), strict=True):
        off = (tilt - degrees + 180.0) % 360.0 - 180.0
        assert abs(off) <= 40.0 + 1e-6, readings.tilts_degrees  # within the network's range
    no_search = ReadingStage(network, config=ReadingConfig(mirror=False, lean_search=False))
    assert no_search.read(proxy_reading_input(proxy)).views == (None,) * count


def test_the_stage_reads_mirrored_when_asked_and_says_which_readings_were() -> None:
    network = CountingNetwork(SIZE)
    stage = ReadingStage(network, config=ReadingConfig())
    readings = stage.read(proxy_reading_input(proxies_of(STANDING, turned(STANDING, 100.0))))
    assert network.batch_sizes[-1] == 4  # as it is and mirrored, in one call
    assert readings.mirrored.shape == (2,) and readings.mirrored.dtype == bool
    upright = math.isnan(readings.tilts_degrees[0])
    assert upright and abs(readings.tilts_degrees[1] - 100.0) < 0.5
