"""Batched CPU/CUDA rendering of body meshes: RGB (textured, shaded), body-part labels and depth,
plus the camera, lighting, clothing-texture and background samplers used for synthetic data.

- :class:`MeshRenderer` / :class:`RenderOutput`: exact z-buffered rasterisation in pure torch
  (:mod:`hkpd.rendering.rasterizer`), per-face Lambert + Blinn-Phong shading.
- :class:`Lighting`, :func:`sample_lighting`: one directional light per image, paper's ranges.
- :class:`ClothingTextureSampler`: procedural outfits as per-face albedo.
- :class:`BackgroundSource`: procedural clutter or crops of a photo folder.
- :func:`sample_cameras`: the paper's random camera translation and focal length.

Design notes and measured speed: ``docs/rendering.md``.
"""

from hkpd.rendering.backgrounds import BackgroundSource
from hkpd.rendering.cameras import sample_cameras
from hkpd.rendering.clothing import ClothingTextureSampler
from hkpd.rendering.lighting import Lighting, sample_lighting
from hkpd.rendering.mesh_renderer import MeshRenderer, RenderOutput

__all__ = [
    "BackgroundSource",
    "ClothingTextureSampler",
    "Lighting",
    "MeshRenderer",
    "RenderOutput",
    "sample_cameras",
    "sample_lighting",
]
