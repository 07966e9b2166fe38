"""The overview picture ``hkpd-predict`` saves for each photo.

Left to right:

1. the photo, cut to the network's square crop box: the detected 2D keypoints (white dots,
   hollow when the detector's confidence is below 0.5), the reprojected skeletons of the
   posterior samples (thin, semi-transparent) and of the mode (thick), the outline of
   BlazePose's person mask (blue, probability 0.5) and the outline of the mode's silhouette
   (its projected mesh, thin red);
2. the mode mesh from the front (the camera's view) and
3. from the side (seen from the photo's right), both coloured by per-vertex uncertainty;
4. the colour bar of the uncertainty scale, in centimetres.

Meshes are rendered with :class:`hkpd.rendering.MeshRenderer` (exact z-buffer, Lambert +
Blinn-Phong shading) at twice the output size and area-averaged down, which anti-aliases the
silhouette; skeletons are drawn at twice the size too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import torch
from PIL import Image, ImageDraw, ImageFont

from hkpd.coco_keypoints import COCO17_LIMBS
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.detection.person_mask import MASK_THRESHOLD, PersonMask
from hkpd.prediction.exports.uncertainty_colours import (
    UncertaintyColourScale,
    vertex_to_face_values,
)
from hkpd.prediction.image_input import LoadedImage
from hkpd.rendering import Lighting, MeshRenderer

CONFIDENT = 0.5
"""Detected keypoints below this confidence are drawn hollow."""

BACKGROUND = (246, 246, 244)
TEXT = (30, 30, 30)
WARNING_COLOUR = (200, 30, 20)
MODE_COLOUR = (235, 60, 40)
SAMPLE_COLOUR = (255, 170, 40)
SAMPLE_ALPHA = 120
MASK_COLOUR = (30, 110, 230)
SECOND_READER_COLOUR = (200, 40, 200)
"""Magenta: where the second keypoint reader (MoveNet) puts a keypoint the readers dispute."""
"""Outline of BlazePose's person mask."""
VIEW_DISTANCE_M = 4.0
"""Distance of the virtual camera from the mesh centre in the mesh renders, metres."""

FILL = 0.86
"""Fraction of the render's height the mesh's larger extent fills."""

SUPERSAMPLE = 2


def _font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has only the fixed bitmap font
        return ImageFont.load_default()


def _lighting() -> Lighting:
    """One soft white light from the upper left, in front of the body."""
    direction = torch.tensor([[-0.35, -0.55, -0.76]])
    return Lighting(
        ambient=torch.tensor([0.55]),
        diffuse=torch.tensor([0.55]),
        specular=torch.tensor([0.12]),
        direction=direction / direction.norm(dim=1, keepdim=True),
        colour=torch.ones(1, 3),
        shininess=torch.tensor([30.0]),
    )


def _side_rotation() -> torch.Tensor:
    """Quarter turn about the (vertical) y axis bringing the photo's right (+x) to face the
    camera (-z)."""
    return torch.tensor([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def render_uncertainty_views(
    vertices: torch.Tensor,
    faces: torch.Tensor,
    uncertainty: torch.Tensor | np.ndarray,
    scale: UncertaintyColourScale,
    size: int = 512,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Front and side renders of one mesh coloured by per-vertex uncertainty.

    Args:
        vertices: ``(V, 3)`` camera-aligned body frame (OpenCV axes), metres.
        faces: ``(F, 3)`` vertex indices.
        uncertainty: ``(V,)`` metres.
        scale: the colour scale.
        size: side of each square render, pixels.

    Returns:
        ``(front, side, masks)``: two ``(size, size, 3)`` uint8 RGB images on
        :data:`BACKGROUND`, and ``(2, size, size)`` float coverage in [0, 1].
    """
    points = torch.as_tensor(vertices, dtype=torch.float32).cpu()
    points = points - (points.amax(0) + points.amin(0)) / 2
    views = torch.stack([points, points @ _side_rotation().T])
    extent = float((views.amax(1) - views.amin(1))[:, :2].max())
    views[..., 2] += VIEW_DISTANCE_M
    big = size * SUPERSAMPLE
    focal = FILL * big * (VIEW_DISTANCE_M - extent / 2) / max(extent, 1e-3)
    face_values = vertex_to_face_values(np.asarray(uncertainty), faces.cpu().numpy())
    albedo = torch.as_tensor(scale.colours(face_values), dtype=torch.float32)
    renderer = MeshRenderer(faces.cpu(), image_size=big)
    lighting = _lighting()
    lighting = Lighting(**{name: value.repeat(2, *([1] * (value.dim() - 1)))
                           for name, value in vars(lighting).items()})  # fmt: skip
    output = renderer.render(views, torch.full((2,), focal), albedo.expand(2, -1, -1), lighting)
    background = np.asarray(BACKGROUND, np.float32) / 255.0
    images, masks = [], []
    for rgb_tensor, mask_tensor in zip(output.rgb, output.mask, strict=True):
        rgb = rgb_tensor.permute(1, 2, 0).clamp(0, 1).numpy()
        mask = mask_tensor.numpy().astype(np.float32)
        composite = np.where(mask[..., None] > 0, rgb, background)
        small = cv2.resize(composite, (size, size), interpolation=cv2.INTER_AREA)
        masks.append(cv2.resize(mask, (size, size), interpolation=cv2.INTER_AREA))
        images.append(np.round(small * 255.0).astype(np.uint8))
    return images[0], images[1], np.stack(masks)


def _trim_columns(image: np.ndarray, mask: np.ndarray, min_width: int, margin: int) -> np.ndarray:
    """Cut ``image`` to the columns the mask covers, plus ``margin``, at least ``min_width``."""
    columns = np.flatnonzero(mask.max(0) > 0.01)
    width = image.shape[1]
    if columns.size == 0:
        return image
    left, right = int(columns[0]) - margin, int(columns[-1]) + 1 + margin
    if right - left < min_width:
        grow = min_width - (right - left)
        left -= grow // 2
        right += grow - grow // 2
    left, right = max(left, 0), min(right, width)
    return image[:, left:right]


def draw_skeletons(
    photo: LoadedImage,
    crop: CropTransform,
    keypoints: np.ndarray,
    confidences: np.ndarray,
    mode_keypoints2d: np.ndarray,
    sample_keypoints2d: np.ndarray | None,
    size: int = 512,
    outlines: Outlines | None = None,
) -> np.ndarray:
    """The photo inside the crop box, with detected keypoints and reprojected skeletons.

    Args:
        photo: the loaded photo.
        crop: the network's crop box (original-photo pixels); it is shown at ``size`` pixels.
        keypoints, confidences: ``(17, 2)`` detected keypoints (original pixels), ``(17,)``.
        mode_keypoints2d: ``(17, 2)`` reprojected mode keypoints, original pixels.
        sample_keypoints2d: ``(N, 17, 2)`` reprojected sample keypoints, original pixels.
        size: side of the returned square, pixels.
        outlines: the person mask and mode silhouette to outline (None: neither).

    Returns:
        ``(size, size, 3)`` uint8 RGB.
    """
    big = size * SUPERSAMPLE
    view = CropTransform(crop.centre, crop.side, big)
    pixels = view.crop_image(photo)
    # Outside the photo the crop is black; show it as the page background instead.
    inside = view.crop_image(np.full(photo.pixels.shape[:2], 255, np.uint8), photo.scale)
    pixels = np.where(inside[..., None] > 127, pixels, np.asarray(BACKGROUND, np.uint8))
    canvas = Image.fromarray(pixels).convert("RGBA")
    # Fade the photo a little so the skeletons stand out.
    canvas = Image.blend(canvas, Image.new("RGBA", canvas.size, (255, 255, 255, 255)), 0.25)
    overlay = Image.new("RGBA", canvas.size, (0, 0, 0, 0))
    draw = ImageDraw.Draw(overlay)
    line = max(2, big // 200)
    if sample_keypoints2d is not None:
        for sample in np.asarray(sample_keypoints2d):
            _draw_bones(draw, view.image_to_crop(sample), (*SAMPLE_COLOUR, SAMPLE_ALPHA), line)
    canvas = Image.alpha_composite(canvas, overlay)
    draw = ImageDraw.Draw(canvas)
    if outlines is not None:
        _draw_outlines(draw, outlines, view, line)
    _draw_bones(draw, view.image_to_crop(np.asarray(mode_keypoints2d)), MODE_COLOUR, 2 * line)
    if outlines is not None:
        _draw_extremities(draw, outlines, view, np.asarray(mode_keypoints2d), line)
        _draw_disputed(draw, outlines, view, np.asarray(keypoints), line)
    radius = 2.5 * line
    for (u, v), confidence in zip(
        view.image_to_crop(np.asarray(keypoints)), confidences, strict=True
    ):
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        fill = (255, 255, 255) if confidence >= CONFIDENT else None
        box = (u - radius, v - radius, u + radius, v + radius)
        draw.ellipse(box, fill=fill, outline=(20, 20, 20), width=max(2, line // 2 + 1))
    return np.asarray(canvas.convert("RGB").resize((size, size), Image.Resampling.LANCZOS))


@dataclass(frozen=True)
class Outlines:
    """What the photo panel outlines besides the skeletons.

    Attributes:
        person_mask: BlazePose's segmentation of the person (None: not drawn).
        mode_vertices2d: ``(V, 2)`` the mode's vertices projected into original-photo pixels
            (None: not drawn).
        faces: ``(F, 3)`` the mesh's triangles (needed with ``mode_vertices2d``).
        detected_extremities: ``(10, 2)`` BlazePose's hand and foot landmarks, original
            pixels, drawn as small squares (None: not drawn).
        extremity_shown: ``(10,)`` bool, which of them were evidence (hollow otherwise).
        mode_extremities2d: ``(10, 2)`` the mode's landmarks reprojected
            (``BodyMeshes.extremity_keypoints2d``), drawn as bones from the wrists and ankles.
        second_keypoints: ``(17, 2)`` the second keypoint reader's keypoints (MoveNet, issue
            59), original pixels; those in ``second_disputed`` (``(17,)`` bool) are drawn as
            magenta crosses joined to BlazePose's keypoint (None: not drawn).
    """

    person_mask: PersonMask | None = None
    mode_vertices2d: np.ndarray | None = None
    faces: np.ndarray | None = None
    detected_extremities: np.ndarray | None = None
    extremity_shown: np.ndarray | None = None
    mode_extremities2d: np.ndarray | None = None
    second_keypoints: np.ndarray | None = None
    second_disputed: np.ndarray | None = None

    @property
    def shows_second_reader(self) -> bool:
        """A disputed keypoint of the second reader is drawn (the legend names it)."""
        return self.second_keypoints is not None and bool(np.any(self.second_disputed))


EXTREMITY_BONES = (
    (9, 0), (9, 2), (9, 4), (10, 1), (10, 3), (10, 5),
    (15, 6), (15, 8), (16, 7), (16, 9),
)  # fmt: skip
"""(COCO keypoint, extremity landmark) pairs drawn as the mode's hand and foot bones: each wrist
to its pinky, index and thumb, each ankle to its heel and foot index."""


def _draw_extremities(
    draw: ImageDraw.ImageDraw,
    outlines: Outlines,
    view: CropTransform,
    mode_keypoints2d: np.ndarray,
    line: int,
) -> None:
    """The mode's hand and foot bones (to its reprojected landmarks) and the detected
    landmarks as small squares, hollow where they were not evidence (none drawn when
    ``outlines`` lacks them)."""
    if outlines.mode_extremities2d is not None:
        joints = view.image_to_crop(mode_keypoints2d)
        ends = view.image_to_crop(np.asarray(outlines.mode_extremities2d))
        for joint, end in EXTREMITY_BONES:
            draw.line((*joints[joint], *ends[end]), fill=MODE_COLOUR, width=line)
    if outlines.detected_extremities is None:
        return
    shown = outlines.extremity_shown
    half = 1.6 * line
    points = view.image_to_crop(np.asarray(outlines.detected_extremities))
    for index, (u, v) in enumerate(points):
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        fill = (255, 255, 255) if shown is None or shown[index] else None
        draw.rectangle((u - half, v - half, u + half, v + half), fill=fill,
                       outline=(20, 20, 20), width=max(1, line // 2))  # fmt: skip


def _draw_disputed(
    draw: ImageDraw.ImageDraw, outlines: Outlines, view: CropTransform, keypoints: np.ndarray,
    line: int,
) -> None:  # fmt: skip
    """The second reader's disputed keypoints: a magenta cross each, joined to BlazePose's."""
    if not outlines.shows_second_reader:
        return
    first = view.image_to_crop(keypoints)
    second = view.image_to_crop(np.asarray(outlines.second_keypoints, np.float64))
    half = 2.0 * line
    for index in np.flatnonzero(outlines.second_disputed):
        (u, v), start = second[index], first[index]
        if not (np.isfinite(second[index]).all() and np.isfinite(start).all()):
            continue
        draw.line((*start, u, v), fill=SECOND_READER_COLOUR, width=max(1, line // 2))
        draw.line((u - half, v - half, u + half, v + half), fill=SECOND_READER_COLOUR, width=line)
        draw.line((u - half, v + half, u + half, v - half), fill=SECOND_READER_COLOUR, width=line)


def _draw_outlines(
    draw: ImageDraw.ImageDraw, outlines: Outlines, view: CropTransform, line: int
) -> None:
    """The mask's 0.5 outline and the mode silhouette's outline, in ``view``'s pixels."""
    shape = (view.size, view.size)
    if outlines.person_mask is not None:
        probability = outlines.person_mask.in_frame(view.affine_matrix(), shape)
        _draw_contours(draw, probability > MASK_THRESHOLD, MASK_COLOUR, line)
    if outlines.mode_vertices2d is not None and outlines.faces is not None:
        points = view.image_to_crop(np.asarray(outlines.mode_vertices2d, np.float64))
        _draw_contours(draw, mesh_silhouette(points, outlines.faces, shape), MODE_COLOUR, line)


def mesh_silhouette(points: np.ndarray, faces: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` bool: the pixels the triangles ``faces`` of the ``(V, 2)`` projected
    ``points`` (pixels, centres at integers) cover, each filled on its own (a union)."""
    silhouette = np.zeros(shape, np.uint8)
    triangles = np.round(np.asarray(points)[np.asarray(faces)] * 4).astype(np.int32)
    for triangle in triangles:
        cv2.fillConvexPoly(silhouette, triangle, 1, lineType=cv2.LINE_8, shift=2)
    return silhouette > 0


def _draw_contours(
    draw: ImageDraw.ImageDraw, mask: np.ndarray, colour: tuple[int, ...], width: int
) -> None:
    """Draw the outer and inner boundaries of the ``(H, W)`` bool ``mask``."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    for contour in contours:
        points = [tuple(map(float, point)) for point in contour[:, 0]]
        if len(points) > 1:
            draw.line([*points, points[0]], fill=colour, width=width, joint="curve")


def _draw_bones(
    draw: ImageDraw.ImageDraw, points: np.ndarray, colour: tuple[int, ...], width: int
) -> None:
    for first, second in COCO17_LIMBS:
        start, end = points[first], points[second]
        if np.isfinite(start).all() and np.isfinite(end).all():
            draw.line([tuple(start), tuple(end)], fill=colour, width=width, joint="curve")


def draw_colour_bar(scale: UncertaintyColourScale, height: int, width: int = 110) -> np.ndarray:
    """A vertical colour bar of ``scale`` with ticks in cm, ``(height, width, 3)`` uint8."""
    image = Image.new("RGB", (width, height), BACKGROUND)
    draw = ImageDraw.Draw(image)
    font = _font(max(11, height // 34))
    top, bottom = int(height * 0.14), int(height * 0.9)
    left, right = 14, 34
    fractions = np.linspace(1.0, 0.0, bottom - top)
    ramp = scale.colours(scale.minimum_m + fractions * (scale.maximum_m - scale.minimum_m))
    strip = np.round(np.repeat(ramp[:, None], right - left, axis=1) * 255).astype(np.uint8)
    image.paste(Image.fromarray(strip), (left, top))
    draw.rectangle((left - 1, top - 1, right, bottom), outline=TEXT)
    span = scale.maximum_m * 100 - scale.minimum_m * 100
    for tick in scale.ticks_cm(2.0 if span <= 12 else float(math.ceil(span / 5))):
        y = bottom - (tick - scale.minimum_m * 100) / span * (bottom - top)
        draw.line((right, y, right + 5, y), fill=TEXT, width=1)
        label = f"{tick:g}+" if math.isclose(tick, scale.maximum_m * 100) else f"{tick:g}"
        draw.text((right + 8, y), label, fill=TEXT, font=font, anchor="lm")
    size = getattr(font, "size", 11)
    draw.text((left - 8, top - size - 16), "uncertainty", fill=TEXT, font=font, anchor="ls")
    # The scale in words (the explorer's default bar says "log 1-32 cm"): colours compare only
    # between bars that say the same.
    draw.text((left - 8, top - 10), scale.label, fill=TEXT, font=font, anchor="ls")
    return np.asarray(image)


def _draw_legend(
    draw: ImageDraw.ImageDraw,
    x: int,
    y: int,
    font: ImageFont.FreeTypeFont | ImageFont.ImageFont,
    with_mask: bool,
    with_second: bool = False,
) -> None:
    """The photo panel's legend (detected keypoints, mode, samples and, ``with_mask``, the
    mask's outline; ``with_second``: the second reader's disputed keypoints), one row starting
    at ``x`` centred on ``y``."""
    draw.ellipse((x, y - 5, x + 10, y + 5), fill=(255, 255, 255), outline=TEXT)
    draw.text((x + 15, y), "detected", fill=TEXT, font=font, anchor="lm")
    legend_x = x + 15 + int(draw.textlength("detected", font=font)) + 14
    entries = [("mode", MODE_COLOUR, 4), ("samples", SAMPLE_COLOUR, 3)]
    if with_mask:
        entries.append(("mask", MASK_COLOUR, 3))
    if with_second:
        entries.append(("second reader disagrees", SECOND_READER_COLOUR, 3))
    for label, colour, width in entries:
        draw.line((legend_x, y, legend_x + 22, y), fill=colour, width=width)
        draw.text((legend_x + 27, y), label, fill=TEXT, font=font, anchor="lm")
        legend_x += 27 + int(draw.textlength(label, font=font)) + 14


def make_overview(
    photo: LoadedImage,
    crop: CropTransform,
    keypoints: np.ndarray,
    confidences: np.ndarray,
    mode_keypoints2d: np.ndarray,
    sample_keypoints2d: np.ndarray | None,
    mode_vertices: torch.Tensor,
    faces: torch.Tensor,
    uncertainty: torch.Tensor | np.ndarray,
    scale: UncertaintyColourScale,
    height: int = 480,
    caption: str = "",
    outlines: Outlines | None = None,
    body_caption: str = "",
    warning: str = "",
) -> np.ndarray:
    """The whole overview (see the module docstring), ``(H, W, 3)`` uint8 RGB.

    Args:
        photo, crop, keypoints, confidences, mode_keypoints2d, sample_keypoints2d: as in
            :func:`draw_skeletons` (original-photo pixels).
        mode_vertices: ``(V, 3)`` the mode mesh, camera-aligned body frame, metres.
        faces: ``(F, 3)``.
        uncertainty: ``(V,)`` metres.
        scale: the uncertainty colour scale.
        height: height of the panels, pixels (the picture adds a title row and a footer).
        caption: a line of text for the footer.
        outlines: the person mask and mode silhouette to outline on the photo (None: neither).
        body_caption: a line about the drawn body (its sex and measurements,
            :func:`hkpd.prediction.exports.body_summary.body_caption`), shown in the footer
            under the mode's renders, above ``caption`` (empty: the footer keeps one line).
        warning: a line in :data:`WARNING_COLOUR` under the others (the reading's quality
            warning, :meth:`hkpd.prediction.quality.ReadingQuality.warning`; empty: none).
    """
    values = np.asarray(uncertainty, dtype=np.float64)
    skeletons = draw_skeletons(
        photo, crop, keypoints, confidences, mode_keypoints2d, sample_keypoints2d, height,
        outlines,
    )  # fmt: skip
    front, side, masks = render_uncertainty_views(mode_vertices, faces, values, scale, height)
    front = _trim_columns(front, masks[0], int(height * 0.42), height // 20)
    side = _trim_columns(side, masks[1], int(height * 0.42), height // 20)
    bar = draw_colour_bar(scale, height)
    gap = max(8, height // 40)
    title_height, row_height = max(28, height // 16), max(26, height // 18)
    footer_height = row_height * (1 + bool(body_caption) + bool(warning))
    panels = [skeletons, front, side, bar]
    width = sum(panel.shape[1] for panel in panels) + gap * (len(panels) + 1)
    canvas = Image.new("RGB", (width, height + title_height + footer_height), BACKGROUND)
    draw = ImageDraw.Draw(canvas)
    font = _font(max(12, height // 30))
    small = _font(max(11, height // 36))
    titles = [
        "photo: detected keypoints, mode and samples",
        "mode: front",
        "mode: side (from the right)",
        "",
    ]
    x = gap
    for panel, title in zip(panels, titles, strict=True):
        canvas.paste(Image.fromarray(panel), (x, title_height))
        draw.text((x + 2, title_height - 6), title, fill=TEXT, font=font, anchor="ls")
        x += panel.shape[1] + gap
    legend_y = title_height + height + row_height // 2
    drawn = outlines or Outlines()
    _draw_legend(draw, gap, legend_y, small, drawn.person_mask is not None,
                 drawn.shows_second_reader)  # fmt: skip
    mean_cm, max_cm = 100 * float(values.mean()), 100 * float(values.max())
    stats = f"vertex uncertainty: mean {mean_cm:.1f} cm, max {max_cm:.1f} cm"
    text = f"{stats}   {caption}".strip()
    lines = [(body_caption, TEXT, font), (text, TEXT, small), (warning, WARNING_COLOUR, font)]
    for line, colour, face in (line for line in lines if line[0]):
        draw.text((skeletons.shape[1] + 2 * gap, legend_y), line, fill=colour, font=face,
                  anchor="lm")  # fmt: skip
        legend_y += row_height
    return np.asarray(canvas)
