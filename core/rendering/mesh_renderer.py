"""``MeshRenderer``: batched, shaded renders of one triangle mesh topology (the body), with the
per-pixel face index, body-part map, mask and depth, on CPU or CUDA with the same torch code.

Visibility comes from :mod:`hkpd.rendering.rasterizer` (exact coverage of pixel centres,
perspective-correct z-buffer). Colour is one Lambert + Blinn-Phong shade per face
(:func:`hkpd.rendering.lighting.shade`) from the face's albedo and, by default, a smoothed
normal: the mean of the face's three area-weighted vertex normals. Faces at 256 px are mostly
sub-pixel to 2 px wide, so per-face shading looks like per-pixel shading; the smoothed normals
reduce the faceting that raw face normals print into the image (and into its Canny edges). The
viewing direction for the highlights is taken once per image (camera to the mesh's mean
vertex), a cheap approximation that shifts highlights slightly. Nothing is anti-aliased:
silhouettes and texture boundaries are hard pixel steps, which suits an edge detector.

Measured speed and the comparison with other designs: :mod:`hkpd.rendering.rasterizer` and
``docs/rendering.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.camera_conventions import CROP_SIZE
from hkpd.rendering.lighting import Lighting, shade
from hkpd.rendering.rasterizer import DEFAULT_CHUNK, DEFAULT_NEAR, ChunkRasterizer


@dataclass
class RenderOutput:
    """What :meth:`MeshRenderer.render` returns (B images of H = W pixels).

    Attributes:
        rgb: ``(B, 3, H, W)`` float32 shaded body in [0, 1], zeros where no body.
        mask: ``(B, H, W)`` bool, body pixels.
        face_index: ``(B, H, W)`` long, visible face per pixel, -1 on the background.
        depth: ``(B, H, W)`` float32 camera-frame z in metres, +inf on the background.
    """

    rgb: torch.Tensor
    mask: torch.Tensor
    face_index: torch.Tensor
    depth: torch.Tensor

    def part_map(self, face_parts: torch.Tensor) -> torch.Tensor:
        """Per-pixel label from per-face labels.

        Args:
            face_parts: ``(F,)`` long label of each face (e.g. ``part_labels[faces[:, 0]]``).

        Returns:
            ``(B, H, W)`` long, the visible face's label, -1 on the background.
        """
        face_parts = face_parts.to(self.face_index.device)
        table = torch.cat((face_parts.new_full((1,), -1), face_parts))
        lookup = (self.face_index + 1).view(-1)
        return table.index_select(0, lookup).view(self.face_index.shape)

    def composite(self, background: torch.Tensor) -> torch.Tensor:
        """The body over a background.

        Args:
            background: ``(B, 3, H, W)`` in [0, 1] (or broadcastable to ``rgb``).

        Returns:
            ``(B, 3, H, W)``: ``rgb`` on body pixels, ``background`` elsewhere.
        """
        if background.shape[-2:] != self.rgb.shape[-2:]:
            raise ValueError(
                f"background is {tuple(background.shape[-2:])} pixels, the render is "
                f"{tuple(self.rgb.shape[-2:])}"
            )
        return torch.where(self.mask[:, None], self.rgb, background.to(self.rgb))


class MeshRenderer:
    """Renders batches of one mesh topology with per-face albedo and one light per image.

    Args:
        faces: ``(F, 3)`` long vertex indices, counter-clockwise seen from outside the body
            (outward normal ``(v1 - v0) x (v2 - v0)``), e.g. ``BodyModel().faces``.
        image_size: side of the square images in pixels.
        device: where renders are computed.
        smooth_normals: shade with the mean of each face's vertex normals (True) or with the
            flat face normal (False).
        cull_backfaces: skip faces seen from behind (right for closed meshes, ~2x faster).
        chunk: images rasterised and shaded together (keeps the work in cache on CPU).
    """

    def __init__(
        self,
        faces: torch.Tensor,
        image_size: int = CROP_SIZE,
        device: torch.device | str = "cpu",
        smooth_normals: bool = True,
        cull_backfaces: bool = True,
        chunk: int = DEFAULT_CHUNK,
    ) -> None:
        if faces.dim() != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must be (F, 3), got {tuple(faces.shape)}")
        if faces.dtype not in (torch.int32, torch.int64):
            raise ValueError(f"faces must be an integer tensor, got {faces.dtype}")
        if image_size < 1:
            raise ValueError(f"image_size must be positive, got {image_size}")
        self.device = torch.device(device)
        self.faces = faces.to(self.device, torch.long)
        self.num_vertices = int(self.faces.max()) + 1
        self.image_size = image_size
        self.smooth_normals = smooth_normals
        self.cull_backfaces = cull_backfaces
        self.chunk = chunk
        self.rasterizer = ChunkRasterizer(
            self.faces, image_size, cull_backfaces, DEFAULT_NEAR, self.device
        )
        self.corners = self.rasterizer.corners

    @property
    def num_faces(self) -> int:
        return int(self.faces.shape[0])

    @torch.no_grad()
    def render(
        self,
        vertices: torch.Tensor,
        focal_px: torch.Tensor,
        face_colours: torch.Tensor,
        lighting: Lighting,
    ) -> RenderOutput:
        """Render B meshes.

        Args:
            vertices: ``(B, V, 3)`` camera-frame metres (OpenCV: x right, y down, z forward,
                z > 0 in front of the camera).
            focal_px: ``(B,)`` focal lengths in pixels; principal point at the image centre,
                pixel centres at integer coordinates (:func:`~hkpd.camera_conventions.
                perspective_project`).
            face_colours: ``(B, F, 3)`` albedo in [0, 1].
            lighting: B lights (:func:`~hkpd.rendering.lighting.sample_lighting`).

        Returns:
            :class:`RenderOutput`. Not differentiable: it runs without autograd, whatever the
            inputs require.
        """
        batch = self._check_inputs(vertices, focal_px, face_colours, lighting)
        size = self.image_size
        device = self.device
        vertices = vertices.to(device, torch.float32)
        focal_px = focal_px.to(device, torch.float32)
        face_colours = face_colours.to(device, torch.float32)
        lighting = lighting.to(device)

        face_index = torch.empty(batch, size, size, dtype=torch.long, device=device)
        depth = torch.empty(batch, size, size, dtype=torch.float32, device=device)
        rgb = torch.empty(batch, 3, size, size, dtype=torch.float32, device=device)
        for start in range(0, batch, self.chunk):
            part = slice(start, min(start + self.chunk, batch))
            self.rasterizer(vertices[part], focal_px[part], face_index[part], depth[part])
            colours = self._face_colours(
                vertices[part], face_colours[part], _slice_lighting(lighting, part)
            )
            self._fill_pixels(colours, face_index[part], rgb[part])
        return RenderOutput(rgb=rgb, mask=face_index >= 0, face_index=face_index, depth=depth)

    # --- shading ----------------------------------------------------------------------------

    def _face_colours(
        self, vertices: torch.Tensor, albedo: torch.Tensor, lighting: Lighting
    ) -> torch.Tensor:
        """``(b, 3, F)`` shaded colour of every face (component-major, for fast gathers)."""
        batch, num_vertices, _ = vertices.shape
        planes = vertices.transpose(1, 2).reshape(batch * 3, num_vertices)
        corners = [planes.index_select(1, corner).view(batch, 3, -1) for corner in self.corners]
        face_normals = _cross(corners[1] - corners[0], corners[2] - corners[0])
        if self.smooth_normals:
            vertex_normals = vertices.new_zeros(batch, 3, num_vertices)
            for corner in self.corners:
                vertex_normals.index_add_(2, corner, face_normals)
            vertex_planes = vertex_normals.view(batch * 3, num_vertices)
            normals = vertex_planes.index_select(1, self.corners[0])
            normals += vertex_planes.index_select(1, self.corners[1])
            normals += vertex_planes.index_select(1, self.corners[2])
            normals = normals.view(batch, 3, -1)
        else:
            normals = face_normals
        # One viewing direction per image (camera to the mesh's centre): highlights barely move
        # and the per-face view and halfway vectors are not needed.
        view = _normalized(-vertices.mean(dim=1)[:, :, None])
        normals = _normalized(normals)
        if not self.cull_backfaces:
            # Two-sided: turn normals of faces seen from behind towards the camera.
            facing = (face_normals * corners[0]).sum(dim=1, keepdim=True) < 0
            normals = torch.where(facing, normals, -normals)
        return shade(albedo.transpose(1, 2), normals, view, lighting)

    def _fill_pixels(
        self, face_colours: torch.Tensor, face_index: torch.Tensor, rgb_out: torch.Tensor
    ) -> None:
        """Write ``(b, 3, H, W)`` pixel colours from ``(b, 3, F)`` face colours."""
        batch = face_colours.shape[0]
        table = torch.cat((face_colours.new_zeros(batch, 3, 1), face_colours), dim=2)
        lookup = (face_index + 1).view(batch, 1, -1).expand(batch, 3, -1)
        torch.gather(table, 2, lookup, out=rgb_out.view(batch, 3, -1))

    # --- validation -------------------------------------------------------------------------

    def _check_inputs(
        self,
        vertices: torch.Tensor,
        focal_px: torch.Tensor,
        face_colours: torch.Tensor,
        lighting: Lighting,
    ) -> int:
        if vertices.dim() != 3 or vertices.shape[2] != 3:
            raise ValueError(f"vertices must be (B, V, 3), got {tuple(vertices.shape)}")
        batch, num_vertices, _ = vertices.shape
        if num_vertices < self.num_vertices:
            raise ValueError(
                f"vertices has {num_vertices} vertices but the faces index up to "
                f"{self.num_vertices - 1}"
            )
        if tuple(focal_px.shape) != (batch,):
            raise ValueError(f"focal_px must be ({batch},), got {tuple(focal_px.shape)}")
        if tuple(face_colours.shape) != (batch, self.num_faces, 3):
            raise ValueError(
                f"face_colours must be ({batch}, {self.num_faces}, 3), got "
                f"{tuple(face_colours.shape)}"
            )
        lighting.check(batch)
        return batch


def _cross(first: torch.Tensor, second: torch.Tensor) -> torch.Tensor:
    """Cross product of ``(b, 3, N)`` component-major vectors (faster than the generic one)."""
    x1, y1, z1 = first.unbind(1)
    x2, y2, z2 = second.unbind(1)
    return torch.stack((y1 * z2 - z1 * y2, z1 * x2 - x1 * z2, x1 * y2 - y1 * x2), dim=1)


def _normalized(vectors: torch.Tensor) -> torch.Tensor:
    """``(b, 3, N)`` vectors scaled to unit length along dim 1 (zero vectors stay zero)."""
    squared = (vectors * vectors).sum(dim=1, keepdim=True)
    return vectors * squared.clamp_(min=1e-30).rsqrt_()


def _slice_lighting(lighting: Lighting, part: slice) -> Lighting:
    return Lighting(
        ambient=lighting.ambient[part],
        diffuse=lighting.diffuse[part],
        specular=lighting.specular[part],
        direction=lighting.direction[part],
        colour=lighting.colour[part],
        shininess=lighting.shininess[part],
    )
