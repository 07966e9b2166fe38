"""Writers for what ``hkpd-predict`` saves: meshes (PLY / GLB / OBJ), the distribution (NPZ),
the person mask (PNG) and the JSON summary.

Frames:

- **Mesh files** are in a *Y-up display frame*: the camera-aligned body frame of
  :class:`~hkpd.prediction.posterior.BodyMeshes` (pelvis at the origin, OpenCV axes x right,
  y down, z away from the camera) turned half a turn about x, i.e. ``(x, -y, -z)``: x right,
  y up, z towards the viewer, metres. Mesh viewers (Blender's glTF importer, MeshLab, three.js)
  then show the person upright and facing the viewer, as in the photo. The half turn is a
  rotation, so triangle winding (outward normals) is kept.
- **The NPZ file** keeps the library's camera-aligned body frame (OpenCV axes), so its vertices
  and keypoints match :meth:`BodyPosterior.mode` / :meth:`BodyPosterior.sample` exactly.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
import trimesh
from PIL import Image

if TYPE_CHECKING:
    from hkpd.prediction.detection.person_mask import PersonMask
    from hkpd.prediction.posterior import BodyMeshes, BodyPosterior

MESH_FORMATS = ("ply", "glb", "obj")
"""Mesh file formats ``hkpd-predict`` writes with trimesh."""

ARRAY_FORMAT = "npz"
"""The format of the distribution parameters and all vertices as arrays."""

OUTPUT_FORMATS = (*MESH_FORMATS, ARRAY_FORMAT)

PERSON_MASK_FILE = "person_mask.png"
"""BlazePose's person mask, written beside the meshes (:func:`write_person_mask`)."""

DISPLAY_FROM_CAMERA = np.diag([1.0, -1.0, -1.0])
"""``(3, 3)`` rotation from the camera-aligned body frame (y down, z away) to the Y-up display
frame of the mesh files (y up, z towards the viewer): ``display = camera @ DISPLAY_FROM_CAMERA``
(it is its own transpose and inverse)."""

DISPLAY_FRAME_NOTE = (
    "mesh files: Y-up display frame (x right, y up, z towards the viewer, metres, pelvis at the "
    "origin) = camera-aligned body frame (OpenCV x right, y down, z away from the camera) with y "
    "and z negated; npz arrays: camera-aligned body frame"
)


def to_display_frame(points: np.ndarray | torch.Tensor) -> np.ndarray:
    """``(..., 3)`` camera-aligned body-frame points to the Y-up display frame, ``(x, -y, -z)``,
    as float64 numpy."""
    array = points.detach().cpu().numpy() if isinstance(points, torch.Tensor) else points
    return np.asarray(array, dtype=np.float64) @ DISPLAY_FROM_CAMERA


def write_mesh(
    path: Path,
    vertices: np.ndarray | torch.Tensor,
    faces: np.ndarray | torch.Tensor,
    vertex_colours: np.ndarray | None = None,
) -> Path:
    """Write one body mesh, converted to the Y-up display frame; the format follows the suffix.

    Args:
        path: ``*.ply``, ``*.glb`` or ``*.obj``.
        vertices: ``(V, 3)`` camera-aligned body frame, metres.
        faces: ``(F, 3)`` vertex indices, counter-clockwise seen from outside.
        vertex_colours: optional ``(V, 3)`` uint8 RGB (stored as vertex colours; OBJ gets
            them as the common ``v x y z r g b`` extension).

    Returns:
        ``path``.

    Raises:
        ValueError: unknown suffix or mismatched shapes.
    """
    path = Path(path)
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in MESH_FORMATS:
        raise ValueError(f"mesh format must be one of {', '.join(MESH_FORMATS)}, got {path.name}")
    points = to_display_frame(vertices)
    triangles = faces.cpu().numpy() if isinstance(faces, torch.Tensor) else np.asarray(faces)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"vertices must be (V, 3), got {points.shape}")
    colours = None
    if vertex_colours is not None:
        colours = np.asarray(vertex_colours, dtype=np.uint8)
        if colours.shape != points.shape:
            raise ValueError(f"vertex colours must be {points.shape}, got {colours.shape}")
        colours = np.concatenate([colours, np.full((len(colours), 1), 255, np.uint8)], axis=1)
    mesh = trimesh.Trimesh(
        vertices=points, faces=triangles.astype(np.int64), vertex_colors=colours, process=False
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(path, file_type=suffix)
    return path


def _numpy(value: torch.Tensor | np.ndarray) -> np.ndarray:
    if isinstance(value, torch.Tensor):
        return value.detach().cpu().numpy()
    return np.asarray(value)


def write_distribution_npz(path: Path, arrays: Mapping[str, Any]) -> Path:
    """Write named arrays (tensors are converted; floats stored as float32) to ``path``.

    See :func:`distribution_arrays` for what ``hkpd-predict`` stores.
    """
    converted = {}
    for key, value in arrays.items():
        array = (
            _numpy(value) if isinstance(value, (torch.Tensor, np.ndarray)) else np.asarray(value)
        )
        if np.issubdtype(array.dtype, np.floating):
            array = array.astype(np.float32)
        converted[key] = array
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as handle:
        np.savez_compressed(handle, **converted)
    return path


def distribution_arrays(
    posterior: BodyPosterior,
    mode: BodyMeshes,
    samples: BodyMeshes | None,
    uncertainty: torch.Tensor,
) -> dict[str, np.ndarray]:
    """The arrays of the NPZ file, camera-aligned body frame, metres and original-photo pixels.

    Args:
        posterior: the :class:`~hkpd.prediction.posterior.BodyPosterior`.
        mode: ``posterior.mode()`` (:class:`BodyMeshes`, N = 1).
        samples: ``posterior.sample(n)`` (N = n) or None.
        uncertainty: ``(V,)`` per-vertex uncertainty, metres.

    Returns:
        ``F (23,3,3)``, ``shape_mean (10,)``, ``shape_std (10,)``, ``global_orient (3,3)``,
        ``camera (3,)`` weak-perspective ``[s, tx, ty]`` of the crop, ``crop_centre (2,)``,
        ``crop_side ()`` (original pixels), ``crop_size ()`` (network pixels), ``keypoints
        (17,2)`` detected, ``confidences (17,)``, ``uncertainty (V,)``, ``faces (F,3)``,
        ``mode_vertices (V,3)``, ``mode_joints (24,3)``, ``mode_keypoints3d (17,3)``,
        ``mode_keypoints2d (17,2)``, ``mode_betas (10,)``, ``mode_body_pose (23,3,3)`` and, with
        samples, ``sample_vertices (N,V,3)``, ``sample_keypoints2d (N,17,2)``, ``sample_betas
        (N,10)``, ``sample_body_pose (N,23,3,3)``.
    """
    crop = posterior.crop
    arrays: dict[str, Any] = {
        "F": posterior.F,
        "shape_mean": posterior.shape_mean,
        "shape_std": posterior.shape_std,
        "global_orient": posterior.global_orient,
        "camera": posterior.camera,
        "crop_centre": np.asarray(crop.centre, dtype=np.float64),
        "crop_side": np.float64(crop.side),
        "crop_size": np.int64(crop.size),
        "keypoints": posterior.keypoints,
        "confidences": posterior.confidences,
        "uncertainty": uncertainty,
        "faces": posterior.body.faces.to(torch.int32),
        "mode_vertices": mode.vertices[0],
        "mode_joints": mode.joints[0],
        "mode_keypoints3d": mode.keypoints3d[0],
        "mode_keypoints2d": mode.keypoints2d[0],
        "mode_betas": mode.betas[0],
        "mode_body_pose": mode.body_pose[0],
    }
    if samples is not None:
        arrays |= {
            "sample_vertices": samples.vertices,
            "sample_keypoints2d": samples.keypoints2d,
            "sample_betas": samples.betas,
            "sample_body_pose": samples.body_pose,
        }
    return arrays


def _plain(value: Any) -> Any:
    """JSON-ready copy: arrays and tensors to (rounded) lists, paths to strings."""
    if isinstance(value, torch.Tensor):
        value = value.detach().cpu().numpy()
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, Mapping):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (np.floating, float)):
        number = float(value)
        return round(number, 6) if math.isfinite(number) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def write_json(path: Path, data: Mapping[str, Any]) -> Path:
    """Write ``data`` as indented JSON (numpy/torch values converted, floats to 6 decimals,
    non-finite floats as null)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_plain(data), indent=2) + "\n")
    return path


def write_person_mask(path: Path, mask: PersonMask) -> Path:
    """Write ``mask`` as an 8-bit grayscale PNG of the original photo's size: each pixel is
    ``round(255 × p)``, ``p`` the probability that it shows the person (threshold at 128 for
    BlazePose's 0.5)."""
    probability = mask.in_photo()
    Image.fromarray(np.round(probability * 255.0).astype(np.uint8), mode="L").save(path)
    return Path(path)
