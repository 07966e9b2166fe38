"""The proxy representation shared by synthetic and real inputs: a Canny edge image plus 17
Gaussian COCO joint heatmaps, ``(18, 256, 256)``.

- :func:`build_proxy` (one crop, detector confidences) and :func:`build_proxy_batch` (training
  batches): the representation itself; :func:`edge_bits_batch` then :func:`assemble_proxy` make
  the same in two steps (compact uint8 edges can cross process boundaries cheaply).
- :func:`square_box_around_keypoints`: where the square crop goes, for photos and synthetic
  images alike.
"""

from hkpd.proxy.crop_box import CROP_MARGIN, square_box_around_keypoints
from hkpd.proxy.edges import canny_edges
from hkpd.proxy.heatmaps import HEATMAP_STD_AT_256, heatmap_std, joint_heatmaps
from hkpd.proxy.representation import (
    CONFIDENCE_THRESHOLD,
    PROXY_CHANNELS,
    assemble_proxy,
    build_proxy,
    build_proxy_batch,
    edge_bits_batch,
    joints_kept,
)

__all__ = [
    "CONFIDENCE_THRESHOLD",
    "CROP_MARGIN",
    "HEATMAP_STD_AT_256",
    "PROXY_CHANNELS",
    "assemble_proxy",
    "build_proxy",
    "build_proxy_batch",
    "canny_edges",
    "edge_bits_batch",
    "heatmap_std",
    "joint_heatmaps",
    "joints_kept",
    "square_box_around_keypoints",
]
