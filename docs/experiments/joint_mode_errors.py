"""Per-joint health of one or more networks: mode error, concentration and log-gain per joint.

On the first synthetic test images (the fixed test set of ``hkpd-eval``, upright), for every
body joint: the median angle between the predicted mode and the true relative rotation
(degrees), the median log10 of the summed singular values of ``F`` (the concentration), and the
median raw log-gain where the network has one (beyond ±6 it is clamped: such a joint has been
stuck there, see ``hkpd.training.revive_gains``). Left and right joints should look alike; the
docs/model_history.md (section 5) used this table to find the stuck right collar.

    python docs/experiments/joint_mode_errors.py assets/models/hkpd_hierarchical.pt other.pt \\
        --poses poses.npz
"""

from __future__ import annotations

import argparse
from pathlib import Path

import roma
import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.network.checkpoint import load_network
from hkpd.poses import pose_source
from hkpd.synthesis.generator import (
    SyntheticDataConfig,
    SyntheticDataGenerator,
    iter_fixed_test_set,
)
from hkpd.training.revive_gains import log_gains

TEST_SET_SEED = 2021  # hkpd-eval's


def joint_table(checkpoint: Path, poses: Path | None, count: int) -> dict[str, list[float]]:
    """Per joint name: [median mode error (deg), median log10 concentration, median log-gain]."""
    network, _ = load_network(checkpoint)
    network.eval()
    config = SyntheticDataConfig(
        image_size=int(network.config.image_size), image_proxy=network.config.image_proxy
    )
    generator = SyntheticDataGenerator(pose_source(poses, "test"), config)
    batch = next(iter(iter_fixed_test_set(generator, count, TEST_SET_SEED, count)))
    with torch.no_grad():
        F = network(batch.proxy).F.double()
    U, _, Vh = torch.linalg.svd(F)
    signs = torch.ones(F.shape[:-1], dtype=F.dtype)
    signs[..., 2] = torch.det(U @ Vh)
    mode = U @ torch.diag_embed(signs) @ Vh
    error = roma.rotmat_geodesic_distance(mode, batch.body_pose.double()).rad2deg()
    concentration = torch.linalg.svdvals(F).sum(-1).log10()
    try:
        gains = log_gains(network, batch.proxy)
    except ValueError:  # no gain (or not the hierarchical head)
        gains = torch.full(error.shape, float("nan"))
    return {
        name: [
            float(error[:, joint].median()),
            float(concentration[:, joint].median()),
            float(gains[:, joint].median()),
        ]
        for joint, name in enumerate(BODY_JOINT_NAMES)
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoints", type=Path, nargs="+")
    parser.add_argument("--poses", type=Path, help="pose bank (test split); else procedural")
    parser.add_argument("--count", type=int, default=100, help="test images")
    arguments = parser.parse_args()
    tables = [joint_table(path, arguments.poses, arguments.count) for path in arguments.checkpoints]
    names = [path.name for path in arguments.checkpoints]
    header = " | ".join(f"{name}: error° / log10 conc. / gain" for name in names)
    print(f"| joint | {header} |")
    print("|---|" + "---|" * len(tables))
    for name in BODY_JOINT_NAMES:
        cells = " | ".join(
            "{:.1f} / {:.2f} / {:.1f}".format(*table[name]).replace("nan", "-") for table in tables
        )
        print(f"| {name} | {cells} |")


if __name__ == "__main__":
    main()
