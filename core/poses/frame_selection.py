"""Dropping near-duplicate mocap frames (120 fps mocap changes little from frame to frame)."""

from __future__ import annotations

import torch


def select_distinct_frames(body_pose: torch.Tensor, min_change_deg: float) -> torch.Tensor:
    """Greedy subsampling: keep the first frame, then every frame in which some joint has turned
    by at least ``min_change_deg`` since the last kept frame.

    Args:
        body_pose: ``(F, J, 3, 3)`` relative joint rotations of one clip, in time order.
        min_change_deg: threshold in degrees; 0 keeps every frame.

    Returns:
        ``(K,)`` int64 indices of the kept frames, increasing, K >= 1 when F >= 1.
    """
    if body_pose.shape[0] == 0:
        return torch.zeros(0, dtype=torch.long)
    if min_change_deg <= 0:
        return torch.arange(body_pose.shape[0])
    # For each kept frame, find the first later frame whose largest joint change reaches the
    # threshold; trace(A^T B) is the sum of the element-wise product of the flattened matrices.
    flat = body_pose.reshape(body_pose.shape[0], -1, 9)
    num_frames = flat.shape[0]
    kept = [0]
    start = 0
    window = 32
    while start + 1 < num_frames:
        stop = min(start + 1 + window, num_frames)
        traces = (flat[start + 1 : stop] * flat[start]).sum(-1)
        angles = torch.rad2deg(torch.arccos(((traces - 1) / 2).clamp(-1.0, 1.0)))
        far = torch.nonzero(angles.amax(dim=-1) >= min_change_deg)
        if far.numel() == 0:
            if stop == num_frames:
                break
            window *= 2  # nothing moved enough yet: look further ahead
            continue
        start = start + 1 + int(far[0])
        kept.append(start)
        window = 32
    return torch.tensor(kept, dtype=torch.long)
