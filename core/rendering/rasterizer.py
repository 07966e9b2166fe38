"""Exact, batched triangle rasterisation in pure torch (CPU and CUDA, same code).

Visibility only: for every pixel of every image, the nearest triangle whose interior contains the
pixel centre, and its depth. Shading is done elsewhere from the winning face index.

Method (edge functions over per-triangle bounding boxes, with a packed-key z-buffer):

1. Project, cull back faces and faces touching the near plane, and compute each triangle's
   bounding box of *pixel centres* (integers; pixel centres sit at integer coordinates). A
   triangle whose box holds no pixel centre covers no pixel and is dropped (at 256 px about 57%
   of the body's front faces are such slivers: they lie between pixel centres, and the pixels
   around them are covered by their neighbours, so dropping them leaves no hole).
2. Group the remaining triangles by the size of their box: exact ``w x h`` up to 4 x 4 (nearly
   all of them at 256 px), squares of side 6, 8, 12, 16, 24, ... beyond; each group enumerates
   a fixed grid of candidate pixels per triangle, and there are few groups (Python overhead).
3. For a group, the three barycentric coordinates, two image-border guards and the inverse depth
   (affine in screen space) are affine functions of the integer pixel offset inside the box;
   they are evaluated for all candidates with one batched matrix product
   ``(6, n, 3) @ (3, w*h)``, in coordinates local to the box (small numbers, so float32 keeps
   ~1e-5 px accuracy even for sub-pixel triangles).
4. A candidate inside the triangle gets the key ``bits(1/z) << 32 | (face + 1)``: the bit
   pattern of a positive float32 orders like the float, so ``scatter_reduce(..., "amax")`` over
   the flat ``B*H*W`` buffer keeps the nearest face per pixel (ties: the larger face index) in
   one pass, deterministically. The key's two 32-bit halves are read back as the face (+1) and
   the inverse depth without further arithmetic; an empty pixel (key 0) decodes to face -1 and
   depth +inf.

Coverage uses a small tolerance (a pixel centre on a shared edge belongs to both triangles), so a
closed mesh renders without cracks; the z-buffer resolves the double cover. The batch is
processed in chunks of a few images so that the per-face arrays stay in cache.

Candidates measured before choosing (``benchmarks/bench_rendering.py``, body mesh with 26,972
triangles, 256 px, B = 64, CPU, 1 torch thread, shared 2-vCPU VM under load; details and the
two-thread numbers in ``docs/rendering.md``):

==========================================  ===========  ==============  ===============
candidate                                   CPU ms/img   body px empty   interior holes
==========================================  ===========  ==============  ===============
B: edge functions over boxes (this module)  2.9          0 (reference)   0 cracks
A: splat 7 points per triangle, same keys   10.8         15.9%           312 per image
==========================================  ===========  ==============  ===============

(B's ~1.6 interior empty pixels per image are all true gaps between body parts: none lies
inside a front-facing triangle in float64. Library options: PyTorch3D is a compiled C++/CUDA
extension; nvdiffrast has no CPU rasteriser; OpenGL renderers need a context per worker and give
no batched torch tensors.)
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.camera_conventions import perspective_project

COVERAGE_TOLERANCE = 1e-5
"""Barycentric slack: pixel centres this close outside an edge still count as covered."""

DEFAULT_NEAR = 1e-2
"""Triangles with a vertex nearer than this (metres) are not drawn."""

SMALL_BOX = 4
"""Boxes up to this many pixels a side get a grid of their exact size; larger ones a square."""

DEFAULT_CHUNK = 8
"""Images rasterised together; larger chunks leave the cache, smaller ones pay Python overhead."""


@dataclass
class Rasterization:
    """Per-pixel visibility.

    Attributes:
        face_index: ``(B, H, W)`` long, index of the visible face, -1 where no face.
        depth: ``(B, H, W)`` float32, camera-frame z of the visible surface in metres (perspective
            correct), +inf where no face.
    """

    face_index: torch.Tensor
    depth: torch.Tensor


def size_classes(limit: int) -> list[int]:
    """Box-size classes ``1, 2, 3, 4, 6, 8, 12, 16, ...`` up to at least ``limit``."""
    classes = [1, 2, 3, 4]
    while classes[-1] < limit:
        classes.append(classes[-2] * 2)
    return classes


def rasterize(
    vertices: torch.Tensor,
    faces: torch.Tensor,
    focal_px: torch.Tensor,
    image_size: int,
    cull_backfaces: bool = True,
    near: float = DEFAULT_NEAR,
    chunk: int = DEFAULT_CHUNK,
) -> Rasterization:
    """Nearest visible face and its depth for every pixel.

    Args:
        vertices: ``(B, V, 3)`` camera-frame points in metres (OpenCV: x right, y down, z
            forward).
        faces: ``(F, 3)`` long vertex indices, counter-clockwise seen from outside (outward
            normal ``(v1 - v0) x (v2 - v0)``).
        focal_px: ``(B,)`` focal length in pixels; principal point at the image centre.
        image_size: side of the square image in pixels.
        cull_backfaces: drop faces seen from behind (right for closed meshes, and about twice
            as fast); False draws both sides.
        near: faces with any vertex at ``z <= near`` metres are skipped.
        chunk: images processed together.

    Returns:
        :class:`Rasterization` with ``(B, H, W)`` face index and depth.
    """
    batch = vertices.shape[0]
    size = image_size
    device = vertices.device
    face_index = torch.empty(batch, size, size, dtype=torch.long, device=device)
    depth = torch.empty(batch, size, size, dtype=torch.float32, device=device)
    rasterizer = ChunkRasterizer(faces, size, cull_backfaces, near, device)
    for start in range(0, batch, chunk):
        stop = min(start + chunk, batch)
        rasterizer(
            vertices[start:stop], focal_px[start:stop], face_index[start:stop], depth[start:stop]
        )
    return Rasterization(face_index=face_index, depth=depth)


@dataclass(frozen=True)
class _ProjectedFaces:
    """A chunk's faces on screen.

    Attributes:
        xs, ys: per corner, ``(b, F)`` projected pixel coordinates.
        vertex_z: ``(b, V)`` camera-frame depths of the vertices.
        area: ``(b, F)`` twice the signed screen area (positive: facing the camera).
    """

    xs: list[torch.Tensor]
    ys: list[torch.Tensor]
    vertex_z: torch.Tensor
    area: torch.Tensor


@dataclass(frozen=True)
class _FaceBoxes:
    """The drawable faces of a chunk, sorted by the size group of their boxes.

    Attributes:
        selected: ``(n,)`` flat index ``image * F + face`` of each drawable face.
        low_x, low_y: ``(n,)`` float, the box's first pixel centre (clamped to the image).
        counts: faces per size group (``ChunkRasterizer.shapes``), in sorted order.
    """

    selected: torch.Tensor
    low_x: torch.Tensor
    low_y: torch.Tensor
    counts: list[int]


class ChunkRasterizer:
    """Rasterises a few images at a time into caller-provided outputs.

    Holds the per-mesh constants (face corners, size-class table, cached candidate grids) so
    that a renderer can build it once and call it per chunk.

    Args:
        faces: ``(F, 3)`` long vertex indices, counter-clockwise seen from outside.
        size: image side in pixels.
        cull_backfaces, near: as in :func:`rasterize`.
        device: where the images are rendered.
    """

    def __init__(
        self,
        faces: torch.Tensor,
        size: int,
        cull_backfaces: bool,
        near: float,
        device: torch.device,
    ) -> None:
        self.size = size
        self.cull_backfaces = cull_backfaces
        self.near = near
        self.corners = [faces[:, k].contiguous().to(device) for k in range(3)]
        self.num_faces = faces.shape[0]
        # Candidate grids: exact w x h boxes up to SMALL_BOX (most triangles), squares of the
        # next size class beyond; group_of[w * (size + 1) + h] is the grid of a w x h box.
        small = [(w, h) for w in range(1, SMALL_BOX + 1) for h in range(1, SMALL_BOX + 1)]
        sides = [c for c in size_classes(size) if c > SMALL_BOX]
        self.shapes: list[tuple[int, int]] = small + [(side, side) for side in sides]
        extent = torch.arange(size + 1)
        width, height = extent[:, None], extent[None, :]
        longest = torch.maximum(width, height)
        small_group = (width - 1) * SMALL_BOX + (height - 1)
        square_group = len(small) + torch.searchsorted(
            torch.tensor(sides), longest.contiguous(), right=False
        )
        group_of = torch.where(longest <= SMALL_BOX, small_group, square_group).clamp_(min=0)
        self.group_of = group_of.reshape(-1).to(device)
        self.grids: dict[tuple[int, int], tuple[torch.Tensor, torch.Tensor]] = {}
        self.device = device

    def grid(self, width: int, height: int) -> tuple[torch.Tensor, torch.Tensor]:
        """``(3, w*h)`` rows (x offset, y offset, 1) and the ``(w*h,)`` flat pixel offsets."""
        key = (width, height)
        if key not in self.grids:
            offset_y, offset_x = torch.meshgrid(
                torch.arange(height, device=self.device),
                torch.arange(width, device=self.device),
                indexing="ij",
            )
            offset_x, offset_y = offset_x.reshape(-1), offset_y.reshape(-1)
            rows = torch.stack((offset_x, offset_y, torch.ones_like(offset_x))).float()
            self.grids[key] = (rows, offset_y * self.size + offset_x)
        return self.grids[key]

    def __call__(
        self,
        vertices: torch.Tensor,
        focal_px: torch.Tensor,
        face_index_out: torch.Tensor,
        depth_out: torch.Tensor,
    ) -> None:
        """Write ``(b, H, W)`` face indices (-1 empty) and depths (+inf empty) for ``(b, V, 3)``
        camera-frame vertices and ``(b,)`` focal lengths into the two output tensors."""
        size = self.size
        batch = vertices.shape[0]
        vertices = vertices.float()
        pixels = perspective_project(vertices, focal_px.to(vertices)[:, None], size)
        pixel_x = pixels[..., 0].contiguous()
        pixel_y = pixels[..., 1].contiguous()
        vertex_z = vertices[..., 2].contiguous()
        xs = [pixel_x.index_select(1, corner) for corner in self.corners]
        ys = [pixel_y.index_select(1, corner) for corner in self.corners]
        area = (xs[2] - xs[0]) * (ys[1] - ys[0]) - (xs[1] - xs[0]) * (ys[2] - ys[0])
        faces = _ProjectedFaces(xs, ys, vertex_z, area)
        boxes = self._face_boxes(faces)
        coefficients = self._pixel_functions(faces, boxes)
        buffer = self._nearest_keys(coefficients, boxes, batch, vertices.device)
        words = buffer[: batch * size * size].view(torch.int32).view(batch, size, size, 2)
        torch.sub(words[..., 0], 1, out=face_index_out)
        torch.reciprocal(words[..., 1].view(torch.float32), out=depth_out)

    def _face_boxes(self, faces: _ProjectedFaces) -> _FaceBoxes:
        """Method steps 1-2: the drawable faces' boxes of pixel centres, sorted by size group."""
        size, xs, ys, vertex_z, area = self.size, faces.xs, faces.ys, faces.vertex_z, faces.area
        drawable = area > 0 if self.cull_backfaces else area != 0
        low_x = torch.minimum(torch.minimum(xs[0], xs[1]), xs[2]).ceil_()
        high_x = torch.maximum(torch.maximum(xs[0], xs[1]), xs[2]).floor_()
        low_y = torch.minimum(torch.minimum(ys[0], ys[1]), ys[2]).ceil_()
        high_y = torch.maximum(torch.maximum(ys[0], ys[1]), ys[2]).floor_()
        drawable &= high_x >= low_x
        drawable &= high_y >= low_y
        if bool((vertex_z <= self.near).any()):
            near_vertex = vertex_z <= self.near
            for corner in self.corners:
                drawable &= ~near_vertex.index_select(1, corner)

        selected = drawable.view(-1).nonzero().squeeze(1)
        low_x = low_x.view(-1).index_select(0, selected).clamp_(min=0.0)
        low_y = low_y.view(-1).index_select(0, selected).clamp_(min=0.0)
        extent_x = (
            high_x.view(-1).index_select(0, selected).clamp_(max=size - 1) - low_x
        ).long().clamp_(0) + 1
        extent_y = (
            high_y.view(-1).index_select(0, selected).clamp_(max=size - 1) - low_y
        ).long().clamp_(0) + 1
        group = self.group_of.index_select(0, extent_x * (size + 1) + extent_y)
        group, order = group.sort()
        return _FaceBoxes(
            selected=selected.index_select(0, order),
            low_x=low_x.index_select(0, order),
            low_y=low_y.index_select(0, order),
            counts=torch.bincount(group, minlength=len(self.shapes)).tolist(),
        )

    def _pixel_functions(self, faces: _ProjectedFaces, boxes: _FaceBoxes) -> torch.Tensor:
        """Method step 3: ``(6, n, 3)`` the affine functions of the pixel offset inside each
        box: three barycentrics, two image-border guards and the inverse depth."""
        size, selected, low_x, low_y = self.size, boxes.selected, boxes.low_x, boxes.low_y
        xs, ys, vertex_z, area = faces.xs, faces.ys, faces.vertex_z, faces.area
        # Corner coordinates local to the box, and their inverse depths: (3 corners, n).
        corner_x = torch.stack([c.view(-1).index_select(0, selected) for c in xs]) - low_x
        corner_y = torch.stack([c.view(-1).index_select(0, selected) for c in ys]) - low_y
        inverse_vertex_z = vertex_z.reciprocal()
        inverse_z = torch.stack(
            [
                inverse_vertex_z.index_select(1, corner).view(-1).index_select(0, selected)
                for corner in self.corners
            ]
        )
        inverse_area = area.view(-1).index_select(0, selected).reciprocal_()

        # Barycentric coordinate of corner i: edge function of the opposite edge (j = i+1 to
        # k = i+2), affine in the pixel offset (ox, oy): coef_x * ox + coef_y * oy + coef_1.
        x_j, x_k = corner_x.roll(-1, 0), corner_x.roll(-2, 0)
        y_j, y_k = corner_y.roll(-1, 0), corner_y.roll(-2, 0)
        barycentric = torch.stack(
            ((y_k - y_j) * inverse_area, (x_j - x_k) * inverse_area, (x_k * y_j - x_j * y_k)),
            dim=2,
        )  # (3, n, 3)
        barycentric[..., 2] *= inverse_area
        inverse_depth = (barycentric * inverse_z[..., None]).sum(dim=0, keepdim=True)
        ones = torch.ones_like(inverse_area)
        zeros = torch.zeros_like(inverse_area)
        x_guard = torch.stack((-ones, zeros, (size - 1) - low_x), dim=1)  # ox <= size-1-low_x
        y_guard = torch.stack((zeros, -ones, (size - 1) - low_y), dim=1)
        return torch.cat(
            (barycentric, x_guard[None], y_guard[None], inverse_depth), dim=0
        )  # (6, n, 3): three barycentrics, two guards, inverse depth

    def _nearest_keys(
        self, coefficients: torch.Tensor, boxes: _FaceBoxes, batch: int, device: torch.device
    ) -> torch.Tensor:
        """Method step 4: the flat ``(b*H*W + pad,)`` z-buffer of packed keys
        ``bits(1/z) << 32 | (face + 1)``, the nearest face's per pixel (0 where empty)."""
        size, selected = self.size, boxes.selected
        image = torch.div(selected, self.num_faces, rounding_mode="floor")
        face_plus_one = selected - image * self.num_faces + 1
        base = image * (size * size) + boxes.low_y.long() * size + boxes.low_x.long()
        largest_offset = (max(self.shapes)[0] - 1) * (size + 1)
        buffer = torch.zeros(
            batch * size * size + largest_offset + 1, dtype=torch.long, device=device
        )
        start = 0
        for group_id, count in enumerate(boxes.counts):
            if count == 0:
                continue
            stop = start + count
            width, height = self.shapes[group_id]
            grid_rows, pixel_offset = self.grid(width, height)
            values = torch.matmul(coefficients[:, start:stop], grid_rows)  # (6, count, w*h)
            lowest = torch.minimum(values[0], values[1])
            for row in (2, 3, 4):
                torch.minimum(lowest, values[row], out=lowest)
            packed = (values[5].view(torch.int32).long() << 32) | face_plus_one[start:stop, None]
            packed.masked_fill_(lowest < -COVERAGE_TOLERANCE, 0)
            index = base[start:stop, None] + pixel_offset
            buffer.scatter_reduce_(0, index.view(-1), packed.view(-1), "amax")
            start = stop
        return buffer
