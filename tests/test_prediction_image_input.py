"""load_image: EXIF orientation, colour modes, bit depth, size limits and clear errors.

Every test image is made here (synthetic pixels written with PIL or OpenCV); no shared data.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from PIL import Image, ImageOps

from hkpd.prediction import (
    MAX_IMAGE_PIXELS,
    MAX_IMAGE_SIDE,
    MIN_IMAGE_SIDE,
    ImageInputError,
    LoadedImage,
    load_image,
)


def asymmetric_rgb(width: int = 64, height: int = 48) -> np.ndarray:
    """``(H, W, 3)`` uint8 with a gradient and a red block in the top-left corner."""
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    image = np.stack([u * 255 // width, v * 255 // height, (u + v) % 256], -1).astype(np.uint8)
    image[:8, :12] = (255, 0, 0)
    return image


def save_with_orientation(path: Path, pixels: np.ndarray, orientation: int) -> None:
    exif = Image.Exif()
    exif[0x0112] = orientation
    Image.fromarray(pixels).save(path, exif=exif.tobytes())


@pytest.mark.parametrize("orientation", range(1, 9))
def test_exif_orientation_matches_pil_transpose(tmp_path: Path, orientation: int) -> None:
    path = tmp_path / f"oriented_{orientation}.png"
    pixels = asymmetric_rgb()
    save_with_orientation(path, pixels, orientation)
    with Image.open(path) as pil:
        expected = np.asarray(ImageOps.exif_transpose(pil).convert("RGB"))
    loaded = load_image(path)
    np.testing.assert_array_equal(loaded.pixels, expected)
    assert loaded.original_size == (expected.shape[1], expected.shape[0])
    if orientation >= 5:  # a quarter turn swaps width and height
        assert loaded.size == (48, 64)


def test_jpeg_rotated_by_exif_shows_the_block_where_a_viewer_would(tmp_path: Path) -> None:
    # Orientation 6: the stored image must be turned 90° clockwise for display, so the red
    # block stored top-left appears top-right.
    path = tmp_path / "camera.jpg"
    save_with_orientation(path, asymmetric_rgb(), 6)
    loaded = load_image(str(path))
    assert loaded.size == (48, 64)
    top_right = loaded.pixels[2:10, -6:-2].reshape(-1, 3).mean(0)  # the block is now 12x8
    top_left = loaded.pixels[2:10, 2:6].reshape(-1, 3).mean(0)
    assert top_right[0] > 200 and top_right[1] < 60
    assert not (top_left[0] > 200 and top_left[1] < 60)


def test_pil_image_input_applies_exif_too(tmp_path: Path) -> None:
    path = tmp_path / "oriented.png"
    save_with_orientation(path, asymmetric_rgb(), 8)
    with Image.open(path) as pil:
        from_pil = load_image(pil)
    np.testing.assert_array_equal(from_pil.pixels, load_image(path).pixels)


def test_grayscale_file_and_arrays_become_three_equal_channels(tmp_path: Path) -> None:
    grey = asymmetric_rgb()[:, :, 1]
    Image.fromarray(grey).save(tmp_path / "grey.png")
    for source in (tmp_path / "grey.png", grey, grey[:, :, None]):
        pixels = load_image(source).pixels
        assert pixels.shape == (48, 64, 3) and pixels.dtype == np.uint8
        for channel in range(3):
            np.testing.assert_array_equal(pixels[:, :, channel], grey)


def test_rgba_is_composited_on_white(tmp_path: Path) -> None:
    rgba = np.zeros((40, 40, 4), np.uint8)
    rgba[..., :3] = (0, 0, 200)
    rgba[:, :10, 3] = 0  # transparent: white
    rgba[:, 10:20, 3] = 255  # opaque: the colour
    rgba[:, 20:, 3] = 128  # half: the mix
    Image.fromarray(rgba).save(tmp_path / "cutout.png")
    for source in (tmp_path / "cutout.png", rgba):
        pixels = load_image(source).pixels.astype(int)
        np.testing.assert_array_equal(pixels[:, :10], 255)
        np.testing.assert_array_equal(pixels[:, 10:20], np.broadcast_to([0, 0, 200], (40, 10, 3)))
        expected_half = np.rint(np.array([0, 0, 200]) * 128 / 255 + 255 * (1 - 128 / 255))
        np.testing.assert_array_equal(pixels[:, 20:], np.broadcast_to(expected_half, (40, 20, 3)))


def test_grey_alpha_and_palette_modes(tmp_path: Path) -> None:
    la = Image.fromarray(
        np.stack([np.full((40, 40), 10, np.uint8), np.zeros((40, 40), np.uint8)], -1)
    )
    assert la.mode == "LA"
    np.testing.assert_array_equal(load_image(la).pixels, 255)  # fully transparent -> white

    palette = Image.fromarray(asymmetric_rgb()).convert("P", palette=Image.Palette.ADAPTIVE)
    palette.save(tmp_path / "palette.png")
    expected = np.asarray(palette.convert("RGB"))
    np.testing.assert_array_equal(load_image(tmp_path / "palette.png").pixels, expected)

    palette.info["transparency"] = int(np.asarray(palette)[0, 0])  # the red block's index
    palette.save(tmp_path / "palette_transparent.png", transparency=palette.info["transparency"])
    pixels = load_image(tmp_path / "palette_transparent.png").pixels
    np.testing.assert_array_equal(pixels[0, 0], [255, 255, 255])


def test_16_bit_is_scaled_with_rounding_not_truncated(tmp_path: Path) -> None:
    # 200/65535*255 = 0.78 -> 1 (truncating the high byte gives 0); 65535 -> 255; 32896 -> 128.
    values = np.array([0, 200, 32896, 65000, 65535], np.uint16)
    expected = np.array([0, 1, 128, 253, 255], np.uint8)
    np.testing.assert_array_equal(
        np.rint(values.astype(float) * 255 / 65535).astype(np.uint8), expected
    )
    grey16 = np.tile(np.repeat(values, 8)[None], (40, 1))  # (40, 40)
    rgb16 = np.stack([grey16, grey16[:, ::-1], grey16], -1)
    Image.fromarray(grey16).save(tmp_path / "grey16.png")
    cv2.imwrite(str(tmp_path / "rgb16.png"), rgb16[:, :, ::-1])  # OpenCV writes BGR
    expected_grey = np.tile(np.repeat(expected, 8)[None], (40, 1))
    expected_rgb = np.stack([expected_grey, expected_grey[:, ::-1], expected_grey], -1)
    for source, want in (
        (tmp_path / "grey16.png", np.repeat(expected_grey[:, :, None], 3, 2)),
        (tmp_path / "rgb16.png", expected_rgb),
        (grey16, np.repeat(expected_grey[:, :, None], 3, 2)),
        (rgb16, expected_rgb),
    ):
        np.testing.assert_array_equal(load_image(source).pixels, want)


def test_16_bit_rgba_array_composites_before_quantising() -> None:
    rgba16 = np.zeros((40, 40, 4), np.uint16)
    rgba16[..., 2] = 65535
    rgba16[..., 3] = 32768
    pixels = load_image(rgba16).pixels
    np.testing.assert_array_equal(pixels[0, 0], [127, 127, 255])


def test_huge_image_is_downscaled_and_points_map_back_to_the_original() -> None:
    height, width = 4000, 6000
    image = np.zeros((height, width, 3), np.uint8)
    image[1000:1200, 4000:4400] = 255  # centroid (4199.5, 1099.5) in original pixels
    loaded = load_image(image)
    assert max(loaded.size) == MAX_IMAGE_SIDE
    assert loaded.size == (4096, 2731)
    assert loaded.original_size == (width, height)
    assert loaded.was_downscaled
    ys, xs = np.nonzero(loaded.pixels[:, :, 0].astype(float) > 0)
    weights = loaded.pixels[ys, xs, 0].astype(float)
    centroid = np.array([np.average(xs, weights=weights), np.average(ys, weights=weights)])
    np.testing.assert_allclose(loaded.to_original(centroid), [4199.5, 1099.5], atol=0.5)

    points = np.array([[0.0, 0.0], [-0.5, -0.5], [5999.5, 3999.5], [1234.5, 987.25]])
    np.testing.assert_allclose(
        loaded.to_original(loaded.from_original(points)), points, rtol=0, atol=1e-9
    )
    # The outer pixel edges of both images coincide.
    np.testing.assert_allclose(loaded.from_original(points[1:3]), [[-0.5, -0.5], [4095.5, 2730.5]])
    as_tensor = loaded.to_original(torch.tensor(points[:2], dtype=torch.float32))
    assert isinstance(as_tensor, torch.Tensor) and as_tensor.dtype == torch.float32


def test_max_side_is_configurable_and_small_images_are_untouched(tmp_path: Path) -> None:
    Image.fromarray(asymmetric_rgb(400, 300)).save(tmp_path / "photo.png")
    loaded = load_image(tmp_path / "photo.png", max_side=100)
    assert loaded.size == (100, 75) and loaded.original_size == (400, 300)
    assert loaded.scale == (0.25, 0.25)
    full = load_image(tmp_path / "photo.png")
    assert not full.was_downscaled and full.scale == (1.0, 1.0)
    np.testing.assert_array_equal(np.asarray(full), asymmetric_rgb(400, 300))
    assert load_image(full) is full  # already loaded: passed through
    again = load_image(full, max_side=200)
    assert again.size == (200, 150) and again.original_size == (400, 300)


def test_tiny_images_are_refused_with_the_minimum_in_the_message() -> None:
    load_image(np.zeros((MIN_IMAGE_SIDE, MIN_IMAGE_SIDE, 3), np.uint8))  # smallest accepted
    with pytest.raises(ImageInputError, match=f"at least {MIN_IMAGE_SIDE} pixels"):
        load_image(np.zeros((20, 200, 3), np.uint8))


def test_missing_directory_empty_corrupt_and_non_image_files(tmp_path: Path) -> None:
    assert issubclass(ImageInputError, ValueError)
    with pytest.raises(ImageInputError, match="no such file"):
        load_image(tmp_path / "missing.jpg")
    with pytest.raises(ImageInputError, match="directory"):
        load_image(tmp_path)
    (tmp_path / "empty.jpg").write_bytes(b"")
    with pytest.raises(ImageInputError, match="empty"):
        load_image(tmp_path / "empty.jpg")
    (tmp_path / "notes.jpg").write_text("this is a text file, not a photo\n" * 20)
    with pytest.raises(ImageInputError, match="not a readable image"):
        load_image(tmp_path / "notes.jpg")
    Image.fromarray(asymmetric_rgb(256, 256)).save(tmp_path / "whole.jpg", quality=95)
    data = (tmp_path / "whole.jpg").read_bytes()
    (tmp_path / "truncated.jpg").write_bytes(data[: len(data) // 2])
    with pytest.raises(ImageInputError, match="corrupt or truncated"):
        load_image(tmp_path / "truncated.jpg")


def test_unsupported_arrays_and_objects() -> None:
    with pytest.raises(ImageInputError, match="uint8"):
        load_image(np.zeros((40, 40, 3), np.float32))
    with pytest.raises(ImageInputError, match="channels"):
        load_image(np.zeros((40, 40, 5), np.uint8))
    with pytest.raises(ImageInputError, match="file path"):
        load_image(12345)  # type: ignore[arg-type]


def test_loaded_image_rejects_mismatched_replacement_pixels() -> None:
    loaded = load_image(asymmetric_rgb())
    assert isinstance(loaded, LoadedImage)
    with pytest.raises(ValueError, match="uint8"):
        loaded.with_pixels(np.zeros((10, 10, 3), np.uint8))


def png_header_only(width: int, height: int) -> bytes:
    """A PNG whose header says ``width x height`` grey pixels, followed by a little IDAT.

    ``Image.open`` reads the size from the header; a few KB stand for a huge image (PIL fills
    what the data lacks), as in a decompression bomb.
    """

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    pixels = zlib.compress(bytes(width + 1) * 4)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", pixels)


@pytest.mark.parametrize("side", [8000, 13300, 30000])
def test_too_many_pixels_are_refused_from_the_header(tmp_path: Path, side: int) -> None:
    # 64 Mpx and 177 Mpx pass PIL's own bomb check (179 Mpx); 900 Mpx is a bomb for PIL too.
    data = png_header_only(side, side)
    path = tmp_path / "huge.png"
    path.write_bytes(data)
    for source in (path, data):
        with pytest.raises(ImageInputError, match="megapixels") as caught:
            load_image(source)
        assert str(MAX_IMAGE_PIXELS // 1_000_000) in str(caught.value)
    if side * side <= Image.MAX_IMAGE_PIXELS * 2:  # below PIL's limit: our check, not PIL's
        assert f"{side}x{side}" in str(caught.value)


def test_pixel_limit_holds_for_arrays_and_pil_images_too() -> None:
    side = int(MAX_IMAGE_PIXELS**0.5) + 1
    view = np.broadcast_to(np.zeros((1, 1, 3), np.uint8), (side, side, 3))  # no memory
    with pytest.raises(ImageInputError, match="megapixels"):
        load_image(view)
    with pytest.raises(ImageInputError, match="megapixels"):
        load_image(Image.new("L", (side, side)))
    at_limit = np.broadcast_to(np.zeros((1, 1), np.uint8), (MAX_IMAGE_PIXELS // 5000, 5000))
    assert load_image(at_limit).original_size == (5000, MAX_IMAGE_PIXELS // 5000)


def test_image_bytes_load_like_the_file(tmp_path: Path) -> None:
    pixels = asymmetric_rgb()
    path = tmp_path / "photo.png"
    save_with_orientation(path, pixels, 6)
    from_bytes = load_image(path.read_bytes())
    np.testing.assert_array_equal(from_bytes.pixels, load_image(path).pixels)
    with pytest.raises(ImageInputError, match="empty"):
        load_image(b"")
    with pytest.raises(ImageInputError, match="corrupt or truncated"):
        load_image(path.read_bytes()[:200])
