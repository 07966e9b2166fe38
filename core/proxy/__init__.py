"""The proxy representation shared by synthetic and real inputs: a Canny edge image plus 17
Gaussian COCO joint heatmaps, ``(18, 256, 256)`` (or, for the proxy ablation, a silhouette or
the RGB crop instead of the edges: :data:`IMAGE_PROXIES`).

- :func:`build_proxy` (one crop, detector confidences) and :func:`build_proxy_batch` (training
  batches): the representation itself; :func:`image_planes_batch` then :func:`assemble_proxy`
  make the same in two steps (compact uint8 planes can cross process boundaries cheaply).
- :func:`square_box_around_keypoints`: where the square crop goes, for photos and synthetic
  images alike.
"""

from hkpd.proxy.crop_box import CROP_MARGIN, square_box_around_keypoints
from hkpd.proxy.edges import canny_edges
from hkpd.proxy.heatmaps import HEATMAP_STD_AT_256, heatmap_std, joint_heatmaps
from hkpd.proxy.representation import (
    CONFIDENCE_THRESHOLD,
    DEFAULT_IMAGE_PROXY,
    IMAGE_PROXIES,
    NUM_KEYPOINTS,
    PROXY_CHANNELS,
    assemble_proxy,
    build_proxy,
    build_proxy_batch,
    edge_bits_batch,
    image_planes_batch,
    image_proxy_channels,
    joints_kept,
    proxy_channels,
    proxy_image_planes,
)

__all__ = [
    "CONFIDENCE_THRESHOLD",
    "CROP_MARGIN",
    "DEFAULT_IMAGE_PROXY",
    "HEATMAP_STD_AT_256",
    "IMAGE_PROXIES",
    "NUM_KEYPOINTS",
    "PROXY_CHANNELS",
    "assemble_proxy",
    "build_proxy",
    "build_proxy_batch",
    "canny_edges",
    "edge_bits_batch",
    "heatmap_std",
    "image_planes_batch",
    "image_proxy_channels",
    "joint_heatmaps",
    "joints_kept",
    "proxy_channels",
    "proxy_image_planes",
    "square_box_around_keypoints",
]
