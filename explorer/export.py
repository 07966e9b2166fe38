"""Exporting what the explorer shows: meshes as GLB or PLY (via trimesh), screenshots as PNG."""

from __future__ import annotations

import cv2
import numpy as np

MESH_FORMATS = ("glb", "ply")

# Colours of the exported bodies (RGBA): the mode opaque in the explorer's clay (a mannequin,
# as the field draws its figures), the samples see-through.
MODE_RGBA = (200, 194, 186, 255)
SAMPLE_RGBA = (110, 160, 230, 110)


def meshes_file(
    mode_vertices: np.ndarray, sample_vertices: np.ndarray, faces: np.ndarray, file_format: str
) -> bytes:
    """The mode and the samples as one file.

    Args:
        mode_vertices: ``(V, 3)`` metres, camera-aligned body frame (x right, y down, z away);
            written turned to y up so that viewers show the body upright.
        sample_vertices: ``(K, V, 3)``.
        faces: ``(F, 3)`` int.
        file_format: ``"glb"`` (one node per body: ``mode``, ``sample_00`` ...) or ``"ply"``
            (all bodies merged into one mesh, the mode first).
    """
    if file_format not in MESH_FORMATS:
        raise ValueError(f"unknown mesh format {file_format!r}; use one of {MESH_FORMATS}")
    import trimesh  # imported on the first export: it (and its scipy) costs ~1 s of start-up

    upright = np.diag([1.0, -1.0, -1.0])
    bodies = [("mode", mode_vertices, MODE_RGBA)] + [
        (f"sample_{i:02d}", vertices, SAMPLE_RGBA) for i, vertices in enumerate(sample_vertices)
    ]
    meshes = []
    for name, vertices, colour in bodies:
        mesh = trimesh.Trimesh(
            vertices=np.asarray(vertices, dtype=np.float64) @ upright,
            faces=np.asarray(faces),
            process=False,
        )
        # Vertex colours, not face colours: glTF stores colours per vertex, and trimesh turns
        # face colours into vertex colours through a scipy sparse matrix (scipy is not a
        # dependency of the main install).
        mesh.visual.vertex_colors = np.tile(np.array(colour, dtype=np.uint8), (len(vertices), 1))
        meshes.append((name, mesh))
    if file_format == "ply":
        merged = trimesh.util.concatenate([mesh for _, mesh in meshes])
        return merged.export(file_type="ply")
    scene = trimesh.Scene()
    for name, mesh in meshes:
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return scene.export(file_type="glb")


def png_bytes(image: np.ndarray) -> bytes:
    """``(H, W, 3|4)`` uint8 RGB(A) as PNG file bytes."""
    array = np.asarray(image)
    if array.ndim != 3 or array.shape[2] not in (3, 4) or array.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3|4) uint8 image, got {array.shape} {array.dtype}")
    code = cv2.COLOR_RGBA2BGRA if array.shape[2] == 4 else cv2.COLOR_RGB2BGR
    ok, encoded = cv2.imencode(".png", cv2.cvtColor(array, code))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return encoded.tobytes()
