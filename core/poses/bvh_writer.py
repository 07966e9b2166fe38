"""Write a :class:`~hkpd.poses.bvh.BvhMotion` back to BVH text (used to make test clips and to
export retargeting inputs; end sites are written as ``End Site`` blocks)."""

from __future__ import annotations

from pathlib import Path

from hkpd.poses.bvh import BvhMotion


def format_bvh(motion: BvhMotion, line_ending: str = "\n") -> str:
    """The BVH text of ``motion`` (offsets and values printed with 6 decimals)."""
    skeleton = motion.skeleton
    children: dict[int, list[int]] = {j: [] for j in range(skeleton.num_joints)}
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            children[parent].append(joint)
    lines = ["HIERARCHY"]

    def emit(joint: int, depth: int) -> None:
        pad = "  " * depth
        if skeleton.is_end_site[joint]:
            lines.append(f"{pad}End Site")
        else:
            keyword = "ROOT" if skeleton.parents[joint] < 0 else "JOINT"
            lines.append(f"{pad}{keyword} {skeleton.names[joint]}")
        lines.append(f"{pad}{{")
        offset = " ".join(f"{v:.6f}" for v in skeleton.offsets[joint])
        lines.append(f"{pad}  OFFSET {offset}")
        if skeleton.channels[joint]:
            channels = " ".join(skeleton.channels[joint])
            lines.append(f"{pad}  CHANNELS {len(skeleton.channels[joint])} {channels}")
        for child in children[joint]:
            emit(child, depth + 1)
        lines.append(f"{pad}}}")

    emit(0, 0)
    lines += ["MOTION", f"Frames: {motion.num_frames}", f"Frame Time: {motion.frame_time:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in motion.frames]
    return line_ending.join(lines) + line_ending


def write_bvh(motion: BvhMotion, path: str | Path, line_ending: str = "\n") -> Path:
    """Write ``motion`` to ``path`` as BVH text; returns the path."""
    path = Path(path)
    path.write_text(format_bvh(motion, line_ending), encoding="utf-8", newline="")
    return path
