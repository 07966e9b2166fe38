"""MeshRenderer / rasterizer: exact coverage, occlusion, depth, culling, outputs (CPU, fast)."""

from __future__ import annotations

import pytest
import torch

from hkpd.camera_conventions import perspective_project
from hkpd.rendering import Lighting, MeshRenderer, RenderOutput, sample_lighting
from hkpd.rendering.rasterizer import rasterize

SIZE = 48
FOCAL = 60.0


def pixel_centres(size: int) -> torch.Tensor:
    """``(size, size, 2)`` float64 (u, v) of every pixel centre."""
    v, u = torch.meshgrid(
        torch.arange(size, dtype=torch.float64),
        torch.arange(size, dtype=torch.float64),
        indexing="ij",
    )
    return torch.stack((u, v), dim=-1)


def analytic_inside(corners_px: torch.Tensor, size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixel centres inside a 2D triangle (float64): ``(size, size)`` bool inside, and bool
    "ambiguous" for centres within 1e-3 px of an edge line (float32 rounding may go either way).
    """
    points = pixel_centres(size)
    signs = []
    distances = []
    for i in range(3):
        start, end = corners_px[i], corners_px[(i + 1) % 3]
        edge = end - start
        relative = points - start
        cross = edge[0] * relative[..., 1] - edge[1] * relative[..., 0]
        signs.append(cross)
        distances.append(cross.abs() / edge.norm())
    signs = torch.stack(signs)
    inside = (signs > 0).all(dim=0) | (signs < 0).all(dim=0)
    return inside, (torch.stack(distances) < 1e-3).any(dim=0)


def one_light(batch: int = 1) -> Lighting:
    return Lighting(
        ambient=torch.full((batch,), 0.5),
        diffuse=torch.full((batch,), 0.5),
        specular=torch.zeros(batch),
        direction=torch.tensor([[0.0, 0.0, -1.0]]).expand(batch, 3),
        colour=torch.ones(batch, 3),
        shininess=torch.full((batch,), 32.0),
    )


def render(vertices: torch.Tensor, faces: torch.Tensor, **options) -> RenderOutput:
    batch = vertices.shape[0]
    renderer = MeshRenderer(faces, SIZE, **options)
    colours = torch.full((batch, faces.shape[0], 3), 0.8)
    return renderer.render(vertices, torch.full((batch,), FOCAL), colours, one_light(batch))


def quad(x0: float, x1: float, y0: float, y1: float, z: float) -> torch.Tensor:
    """Four corners of a camera-facing rectangle at depth z (camera frame, metres)."""
    return torch.tensor([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])


# Counter-clockwise seen from the camera side (outward normal towards -z) in OpenCV axes.
QUAD_FACES = torch.tensor([[0, 2, 1], [0, 3, 2]])


def test_single_triangle_covers_exactly_the_analytic_pixels():
    generator = torch.Generator().manual_seed(3)
    for _ in range(20):
        corners = torch.rand(1, 3, 3, generator=generator, dtype=torch.float64)
        corners[..., :2] = corners[..., :2] * 1.6 - 0.8
        corners[..., 2] = 1.5 + corners[..., 2]
        faces = torch.tensor([[0, 1, 2]])
        out = render(corners.float(), faces, cull_backfaces=False)
        projected = perspective_project(corners[0], FOCAL, SIZE)
        expected, ambiguous = analytic_inside(projected, SIZE)
        assert ambiguous.sum() <= 2
        clear = ~ambiguous
        assert torch.equal(out.mask[0][clear], expected[clear])
        assert torch.equal((out.face_index[0] == 0)[clear], expected[clear])


def test_quad_covers_its_projected_rectangle_without_a_seam():
    corners = quad(-0.31, 0.27, -0.19, 0.42, 2.0)[None]
    out = render(corners, QUAD_FACES)
    pixels = pixel_centres(SIZE)
    low = perspective_project(torch.tensor([-0.31, -0.19, 2.0]), FOCAL, SIZE).double()
    high = perspective_project(torch.tensor([0.27, 0.42, 2.0]), FOCAL, SIZE).double()
    expected = ((pixels >= low) & (pixels <= high)).all(dim=-1)
    assert expected.sum() > 100
    assert torch.equal(out.mask[0], expected)
    # Both triangles are used; the diagonal leaves no gap.
    assert set(out.face_index[0][expected].unique().tolist()) == {0, 1}


@pytest.mark.parametrize("near_first", [True, False])
def test_nearer_surface_wins(near_first: bool):
    near = quad(-0.5, 0.2, -0.5, 0.2, 2.0)
    far = quad(-0.2, 0.5, -0.2, 0.5, 3.0)
    first, second = (near, far) if near_first else (far, near)
    vertices = torch.cat((first, second))[None]
    faces = torch.cat((QUAD_FACES, QUAD_FACES + 4))
    out = render(vertices, faces)
    near_faces = {0, 1} if near_first else {2, 3}
    near_mask = torch.isin(out.face_index[0], torch.tensor(sorted(near_faces)))
    far_mask = out.mask[0] & ~near_mask
    near_px = perspective_project(near[[0, 2]], FOCAL, SIZE)
    far_px = perspective_project(far[[0, 2]], FOCAL, SIZE)
    pixels = pixel_centres(SIZE).float()
    inside_near = ((pixels >= near_px[0]) & (pixels <= near_px[1])).all(-1)
    inside_far = ((pixels >= far_px[0]) & (pixels <= far_px[1])).all(-1)
    assert (inside_near & inside_far).any()  # the quads do overlap on screen
    assert torch.equal(near_mask, inside_near)
    assert torch.equal(far_mask, inside_far & ~inside_near)
    assert torch.allclose(out.depth[0][near_mask], torch.tensor(2.0))
    assert torch.allclose(out.depth[0][far_mask], torch.tensor(3.0))


def test_depth_of_a_tilted_plane_is_perspective_correct():
    # Plane z = 2.5 + 0.8 y, seen through a large quad.
    xs, ys = (-0.6, 0.6), (-0.6, 0.6)
    corners = torch.tensor([[x, y, 2.5 + 0.8 * y] for y in ys for x in xs])  # 00, 10, 01, 11
    faces = torch.tensor([[0, 3, 1], [0, 2, 3]])
    out = render(corners[None], faces)
    pixels = pixel_centres(SIZE)
    ray_y = (pixels[..., 1] - (SIZE - 1) / 2) / FOCAL
    expected = 2.5 / (1.0 - 0.8 * ray_y)  # z = 2.5 + 0.8 * (ray_y * z)
    mask = out.mask[0]
    assert mask.sum() > 500
    assert torch.allclose(out.depth[0][mask].double(), expected[mask], rtol=1e-5)


def test_background_and_output_shapes():
    corners = quad(-0.2, 0.2, -0.2, 0.2, 2.0)[None].expand(3, 4, 3)
    out = render(corners, QUAD_FACES)
    assert out.rgb.shape == (3, 3, SIZE, SIZE) and out.rgb.dtype == torch.float32
    assert out.mask.shape == (3, SIZE, SIZE) and out.mask.dtype == torch.bool
    assert out.face_index.shape == (3, SIZE, SIZE) and out.face_index.dtype == torch.long
    assert out.depth.shape == (3, SIZE, SIZE) and out.depth.dtype == torch.float32
    background = ~out.mask
    assert background.any()
    assert (out.face_index[background] == -1).all()
    assert torch.isinf(out.depth[background]).all()
    assert (out.rgb.permute(0, 2, 3, 1)[background] == 0).all()
    assert (out.rgb.permute(0, 2, 3, 1)[out.mask] > 0).all()
    assert torch.equal(out.mask, out.face_index >= 0)


def test_back_faces_are_culled_unless_asked_for():
    corners = quad(-0.2, 0.2, -0.2, 0.2, 2.0)[None]
    reversed_faces = QUAD_FACES[:, [0, 2, 1]]
    assert not render(corners, reversed_faces).mask.any()
    two_sided = render(corners, reversed_faces, cull_backfaces=False)
    assert torch.equal(two_sided.mask, render(corners, QUAD_FACES).mask)


def test_geometry_behind_the_camera_is_not_drawn():
    corners = quad(-0.2, 0.2, -0.2, 0.2, -2.0)[None]
    assert not render(corners, QUAD_FACES, cull_backfaces=False).mask.any()


def test_part_map_and_composite():
    vertices = torch.cat((quad(-0.5, 0.0, -0.3, 0.3, 2.0), quad(0.0, 0.5, -0.3, 0.3, 2.5)))[None]
    faces = torch.cat((QUAD_FACES, QUAD_FACES + 4))
    out = render(vertices, faces)
    parts = torch.tensor([7, 7, 3, 3])
    part_map = out.part_map(parts)
    assert torch.equal(part_map == -1, ~out.mask)
    assert torch.equal(part_map[out.mask], parts[out.face_index[out.mask]])
    assert set(part_map.unique().tolist()) == {-1, 3, 7}
    background = torch.rand(1, 3, SIZE, SIZE)
    image = out.composite(background)
    mask = out.mask[:, None].expand_as(image)
    assert torch.equal(image[mask], out.rgb[mask])
    assert torch.equal(image[~mask], background[~mask])


def test_chunked_and_batched_rendering_agree_and_are_deterministic():
    generator = torch.Generator().manual_seed(0)
    centres = torch.rand(5, 1, 3, generator=generator) * torch.tensor([0.4, 0.4, 1.0])
    vertices = quad(-0.3, 0.3, -0.3, 0.3, 2.0)[None] + centres
    renderer = MeshRenderer(QUAD_FACES, SIZE, chunk=2)
    colours = torch.rand(5, 2, 3, generator=generator)
    lighting = sample_lighting(5, generator)
    focal = torch.full((5,), FOCAL)
    first = renderer.render(vertices, focal, colours, lighting)
    second = renderer.render(vertices, focal, colours, lighting)
    single = MeshRenderer(QUAD_FACES, SIZE, chunk=8).render(
        vertices[3:4],
        focal[3:4],
        colours[3:4],
        Lighting(**{name: getattr(lighting, name)[3:4] for name in lighting.__dataclass_fields__}),
    )
    for name in ("rgb", "face_index", "depth"):
        assert torch.equal(getattr(first, name), getattr(second, name))
        assert torch.equal(getattr(first, name)[3:4], getattr(single, name))


def test_rasterize_function_matches_the_renderer():
    vertices = quad(-0.3, 0.3, -0.3, 0.3, 2.0)[None]
    raster = rasterize(vertices, QUAD_FACES, torch.tensor([FOCAL]), SIZE)
    out = render(vertices, QUAD_FACES)
    assert torch.equal(raster.face_index, out.face_index)
    assert torch.equal(raster.depth, out.depth)


def test_bad_inputs_are_rejected_with_clear_messages():
    renderer = MeshRenderer(QUAD_FACES, SIZE)
    vertices = quad(-0.3, 0.3, -0.3, 0.3, 2.0)[None]
    colours = torch.rand(1, 2, 3)
    with pytest.raises(ValueError, match="face_colours"):
        renderer.render(vertices, torch.tensor([FOCAL]), colours[:, :1], one_light())
    with pytest.raises(ValueError, match="focal_px"):
        renderer.render(vertices, torch.tensor(FOCAL), colours, one_light())
    with pytest.raises(ValueError, match="vertices"):
        renderer.render(vertices[:, :3], torch.tensor([FOCAL]), colours, one_light())
    with pytest.raises(ValueError, match=r"Lighting\.ambient"):
        renderer.render(vertices, torch.tensor([FOCAL]), colours, one_light(2))
    with pytest.raises(ValueError, match="faces"):
        MeshRenderer(torch.zeros(4, 2, dtype=torch.long))


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_cuda_matches_cpu():
    generator = torch.Generator().manual_seed(1)
    vertices = quad(-0.3, 0.3, -0.3, 0.3, 2.0)[None] + torch.rand(4, 1, 3, generator=generator)
    faces = QUAD_FACES
    colours = torch.rand(4, 2, 3, generator=generator)
    lighting = sample_lighting(4, generator)
    focal = torch.full((4,), FOCAL)
    cpu = MeshRenderer(faces, SIZE).render(vertices, focal, colours, lighting)
    gpu = MeshRenderer(faces, SIZE, device="cuda").render(vertices, focal, colours, lighting)
    assert gpu.rgb.is_cuda
    assert (gpu.face_index.cpu() != cpu.face_index).float().mean() < 1e-3
    assert torch.allclose(gpu.rgb.cpu(), cpu.rgb, atol=1e-4)
