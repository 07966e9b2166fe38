"""The proxy representation: one code path for synthetic training images and real photos.

The first channels are an image proxy of the crop, then 17 Gaussian heatmaps of the COCO-17
joints, with joints whose detector confidence is below ``CONFIDENCE_THRESHOLD`` left out
(all-zero maps), as in the paper. The image proxy is one of :data:`IMAGE_PROXIES`:

- ``"edges"`` (1 channel, the paper's and hkpd's choice): the Canny edge image of the RGB crop;
- ``"silhouette"`` (1 channel): the person's mask (synthetic: the rendered body minus what
  occluders hide; photos: a segmentation the caller supplies, e.g. COCO's person masks);
- ``"rgb"`` (3 channels): the crop's colours in [0, 1];
- ``"edges+mask"`` (2 channels): the edge image, then a person-probability mask in [0, 1]
  (photos: BlazePose's segmentation, :class:`hkpd.prediction.detection.PersonMask`, zero inside
  occluders and outside the photo; synthetic: the rendered silhouette degraded like a
  segmenter's mask, :mod:`hkpd.synthesis.mask_noise`). A zero mask plane means "no mask": a
  network trained with dropped masks then reads the edges and keypoints alone.

``"silhouette"`` and ``"rgb"`` exist for the paper's proxy ablation (Table 1, rows 1-3);
``"edges+mask"`` is the input of networks that read the body's shape (issue 41).

In compact form (crossing process boundaries, warping) an image proxy is ``(B, C, S, S)``
uint8 *image planes* in [0, 255]; the float proxy holds ``planes / 255``, so edges and
silhouettes are {0, 1} there and colours [0, 1].
"""

from __future__ import annotations

import numpy as np
import torch

from hkpd.proxy.edges import canny_edge_bits
from hkpd.proxy.heatmaps import joint_heatmaps

CONFIDENCE_THRESHOLD = 0.6
"""Joints detected with a lower confidence are dropped from the heatmaps (paper, Section 3.1)."""

NUM_KEYPOINTS = 17
PROXY_CHANNELS = 1 + NUM_KEYPOINTS
"""Channels of the default (edge) proxy."""

IMAGE_PROXIES: dict[str, int] = {"edges": 1, "silhouette": 1, "rgb": 3, "edges+mask": 2}
"""The image proxies and their channel counts (see the module docstring)."""

DEFAULT_IMAGE_PROXY = "edges"


def image_proxy_channels(image_proxy: str) -> int:
    """Channels of ``image_proxy``'s planes (1, 2 or 3).

    Raises:
        ValueError: an unknown image proxy.
    """
    if image_proxy not in IMAGE_PROXIES:
        raise ValueError(
            f"unknown image proxy {image_proxy!r}; choose one of {sorted(IMAGE_PROXIES)}"
        )
    return IMAGE_PROXIES[image_proxy]


def proxy_channels(image_proxy: str = DEFAULT_IMAGE_PROXY) -> int:
    """Channels of the whole proxy: the image proxy's plus 17 heatmaps (18, 19 or 20)."""
    return image_proxy_channels(image_proxy) + NUM_KEYPOINTS


def joints_kept(confidences: torch.Tensor | np.ndarray) -> torch.Tensor:
    """``(..., 17)`` bool: which joints are confident enough to enter the proxy."""
    return torch.as_tensor(confidences) >= CONFIDENCE_THRESHOLD


def build_proxy_batch(
    images: np.ndarray | torch.Tensor,
    keypoints: torch.Tensor,
    present: torch.Tensor,
    device: torch.device | str | None = None,
    image_proxy: str = DEFAULT_IMAGE_PROXY,
    silhouettes: np.ndarray | torch.Tensor | None = None,
) -> torch.Tensor:
    """Proxy representations of a batch of square RGB crops.

    Args:
        images: ``(B, S, S, 3)`` uint8 RGB crops (numpy, or a CPU/GPU tensor).
        keypoints: ``(B, 17, 2)`` joint positions in crop pixels.
        present: ``(B, 17)`` bool, the joints to draw (e.g. ``joints_kept(confidences)``).
        device: where the result lives; defaults to ``keypoints``' device.
        image_proxy: one of :data:`IMAGE_PROXIES`.
        silhouettes: ``(B, S, S)`` bool (or 0/1) person masks, needed for ``"silhouette"``;
            or float person probabilities in [0, 1] for ``"edges+mask"`` (None: no mask).

    Returns:
        ``(B, C + 17, S, S)`` float32: the image proxy's ``C`` channels, then 17 heatmaps in
        [0, 1].

    Raises:
        ValueError: on inconsistent shapes, an unknown image proxy, or a missing silhouette.
    """
    planes = image_planes_batch(images, image_proxy, silhouettes)
    return assemble_proxy(planes, keypoints, present, device)


def edge_bits_batch(images: np.ndarray | torch.Tensor) -> torch.Tensor:
    """Canny edges of a batch of square RGB crops.

    Args:
        images: ``(B, S, S, 3)`` uint8 RGB crops (numpy, or a CPU/GPU tensor).

    Returns:
        ``(B, S, S)`` uint8 in {0, 1}, on the CPU.

    Raises:
        ValueError: the images are not square RGB crops.
    """
    images_np = _square_rgb_crops(images)
    edges = np.empty(images_np.shape[:3], dtype=np.uint8)
    for index, image in enumerate(images_np):
        edges[index] = canny_edge_bits(image)
    return torch.from_numpy(edges)


def image_planes_batch(
    images: np.ndarray | torch.Tensor,
    image_proxy: str = DEFAULT_IMAGE_PROXY,
    silhouettes: np.ndarray | torch.Tensor | None = None,
) -> torch.Tensor:
    """The image proxy of a batch of square RGB crops in compact form.

    Args:
        images: ``(B, S, S, 3)`` uint8 RGB crops (numpy, or a CPU/GPU tensor).
        image_proxy: one of :data:`IMAGE_PROXIES`.
        silhouettes: ``(B, S, S)`` bool (or 0/1) person masks, needed for ``"silhouette"``;
            float person probabilities in [0, 1] for ``"edges+mask"`` (None: an all-zero
            mask plane, "no mask"); ignored otherwise.

    Returns:
        ``(B, C, S, S)`` uint8 in [0, 255] on the CPU (edges and silhouettes are 0 or 255).

    Raises:
        ValueError: the images are not square RGB crops, the image proxy is unknown, or the
            silhouettes are missing or of another size.
    """
    image_proxy_channels(image_proxy)
    images_np = _square_rgb_crops(images)
    if image_proxy == "edges":
        return (edge_bits_batch(images_np) * 255)[:, None]
    if image_proxy == "rgb":
        return torch.from_numpy(np.ascontiguousarray(images_np.transpose(0, 3, 1, 2)))
    if image_proxy == "edges+mask":
        edges = edge_bits_batch(images_np) * 255
        return torch.stack([edges, _probability_plane(silhouettes, images_np.shape[:3])], 1)
    if silhouettes is None:
        raise ValueError(
            "the silhouette proxy needs person masks: pass silhouettes (B, S, S), e.g. a "
            "segmentation of the photo"
        )
    masks = torch.as_tensor(silhouettes).cpu()
    if tuple(masks.shape) != images_np.shape[:3]:
        raise ValueError(
            f"silhouettes must be {images_np.shape[:3]} like the crops, got {tuple(masks.shape)}"
        )
    return ((masks > 0).to(torch.uint8) * 255)[:, None]


def _probability_plane(
    probabilities: np.ndarray | torch.Tensor | None, shape: tuple[int, ...]
) -> torch.Tensor:
    """``(B, S, S)`` uint8 in [0, 255]: person probabilities (None: zeros, "no mask")."""
    if probabilities is None:
        return torch.zeros(shape, dtype=torch.uint8)
    values = torch.as_tensor(probabilities).detach().cpu().float()
    if tuple(values.shape) != tuple(shape):
        raise ValueError(f"person masks must be {tuple(shape)} like the crops, got "
                         f"{tuple(values.shape)}")  # fmt: skip
    if not bool(torch.isfinite(values).all()):
        raise ValueError("person masks must be finite probabilities in [0, 1]")
    return values.clamp(0.0, 1.0).mul(255.0).round().to(torch.uint8)


def _square_rgb_crops(images: np.ndarray | torch.Tensor) -> np.ndarray:
    """``images`` as a ``(B, S, S, 3)`` numpy array, or a ValueError."""
    images_np = images.cpu().numpy() if isinstance(images, torch.Tensor) else np.asarray(images)
    if images_np.ndim != 4 or images_np.shape[-1] != 3 or images_np.shape[1] != images_np.shape[2]:
        raise ValueError(f"images must be (B, S, S, 3) uint8 RGB, got {images_np.shape}")
    return images_np


def assemble_proxy(
    image_planes: torch.Tensor,
    keypoints: torch.Tensor,
    present: torch.Tensor,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """The float proxy from image planes and keypoints (the heatmaps are drawn here).

    Args:
        image_planes: ``(B, C, S, S)`` uint8 in [0, 255], e.g. from :func:`image_planes_batch`.
        keypoints: ``(B, 17, 2)`` joint positions in crop pixels.
        present: ``(B, 17)`` bool, the joints to draw.
        device: where the result lives; defaults to ``keypoints``' device.

    Returns:
        ``(B, C + 17, S, S)`` float32: ``image_planes / 255``, then 17 heatmaps in [0, 1].

    Raises:
        ValueError: on inconsistent shapes.
    """
    if image_planes.dim() != 4 or image_planes.shape[2] != image_planes.shape[3]:
        raise ValueError(f"image planes must be (B, C, S, S), got {tuple(image_planes.shape)}")
    if image_planes.dtype != torch.uint8:
        raise ValueError(f"image planes must be uint8 in [0, 255], got {image_planes.dtype}")
    count, channels, size = image_planes.shape[0], image_planes.shape[1], image_planes.shape[2]
    if keypoints.shape != (count, NUM_KEYPOINTS, 2) or present.shape != (count, NUM_KEYPOINTS):
        raise ValueError(
            f"keypoints must be ({count}, 17, 2) and present ({count}, 17); got "
            f"{tuple(keypoints.shape)} and {tuple(present.shape)}"
        )
    device = keypoints.device if device is None else torch.device(device)
    proxy = torch.empty(count, channels + NUM_KEYPOINTS, size, size, device=device)
    torch.div(image_planes.to(device), 255.0, out=proxy[:, :channels])
    joint_heatmaps(keypoints.to(device), present.to(device), size, out=proxy[:, channels:])
    return proxy


def proxy_image_planes(proxy: torch.Tensor) -> torch.Tensor:
    """The compact image planes back from float proxies (inverse of :func:`assemble_proxy`'s
    first channels).

    Args:
        proxy: ``(B, C + 17, S, S)`` float proxies.

    Returns:
        ``(B, C, S, S)`` uint8 in [0, 255], on the proxy's device.
    """
    planes = proxy[:, : proxy.shape[1] - NUM_KEYPOINTS]
    return planes.mul(255.0).round_().clamp_(0, 255).to(torch.uint8)


def build_proxy(
    image: np.ndarray,
    keypoints: np.ndarray | torch.Tensor,
    confidences: np.ndarray | torch.Tensor,
    image_proxy: str = DEFAULT_IMAGE_PROXY,
    silhouette: np.ndarray | None = None,
) -> torch.Tensor:
    """Proxy representation of one square RGB crop from detected keypoints.

    Args:
        image: ``(S, S, 3)`` uint8 RGB crop.
        keypoints: ``(17, 2)`` COCO keypoints in crop pixels.
        confidences: ``(17,)`` detector confidences in [0, 1]; joints below
            ``CONFIDENCE_THRESHOLD`` are dropped.
        image_proxy: one of :data:`IMAGE_PROXIES`.
        silhouette: ``(S, S)`` bool person mask, needed for ``"silhouette"``; or float person
            probabilities in [0, 1] for ``"edges+mask"`` (None: no mask).

    Returns:
        ``(C + 17, S, S)`` float32 on the CPU.
    """
    points = torch.as_tensor(np.asarray(keypoints), dtype=torch.float32).reshape(1, -1, 2)
    kept = joints_kept(np.asarray(confidences, dtype=np.float32)).reshape(1, -1)
    silhouettes = None if silhouette is None else np.asarray(silhouette)[None]
    return build_proxy_batch(np.asarray(image)[None], points, kept, None, image_proxy,
                             silhouettes)[0]  # fmt: skip
