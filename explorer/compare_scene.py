"""The compare columns: B's most likely body with its samples, and B's uncertainty body,
right of A's columns (:mod:`hkpd.explorer.compare`).

B's uncertainty body takes the colouring chosen for A: on the absolute scales (log, linear)
the two uncertainty bodies read on one colour bar; with the change colouring B's body shows B's
uncertainty ÷ A's (red: B less sure), with its own colour bar saying so.
"""

from __future__ import annotations

import threading

import numpy as np
import viser

from hkpd.explorer.colour_map import HeatmapScale, change_legend_image
from hkpd.explorer.layout import DEFAULT_LAYOUT, ColumnLayout
from hkpd.explorer.photo_geometry import HALF_TURN_ABOUT_X
from hkpd.explorer.posterior_view import PosteriorView
from hkpd.explorer.scene import (
    HEATMAP_BASE_COLOUR,
    LEGEND_HEIGHT,
    LEGEND_SIZE_M,
    LEGEND_Z,
    MODE_COLOUR,
    SAMPLE_COLOUR,
    SAMPLE_OPACITY,
)

COMPARE_BODY_OFFSET = DEFAULT_LAYOUT.compare_body_x
"""World x of B's most likely body in the default layout (where a combined shape would stand:
see docs); :attr:`CompareColumns.layout` holds the photo's own."""
COMPARE_HEAT_OFFSET = DEFAULT_LAYOUT.compare_heat_x
"""World x of B's uncertainty body in the default layout."""


def compare_titles(label: str, kind: str) -> tuple[str, str]:
    """B's two column titles for the colouring ``kind`` (they follow the colouring), in short
    lines ("B (label):" over the column's title) so that neighbouring titles do not run into
    each other when the columns stand close (:func:`hkpd.explorer.scene.column_titles`)."""
    heat = "uncertainty ÷ A's" if kind == "change" else "uncertainty\nover samples"
    return f"B ({label}):\nmost likely body\n+ samples", f"B ({label}):\n{heat}"


class CompareColumns:
    """Scene nodes of B's columns (global scene: every tab sees them). Thread-safe."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._lock = threading.Lock()
        self._nodes: dict[str, viser.SceneNodeHandle] = {}
        self._samples: list[viser.MeshHandle] = []
        self._samples_shown = True
        self._titled: tuple[str, HeatmapScale, float] | None = None
        """The label, scale and height the titles and colour bar were last drawn for."""
        self._heat_vertices: np.ndarray | None = None
        """The mode vertices B's heatmap points were last placed at."""
        self.shown = False
        self.layout = DEFAULT_LAYOUT
        """Where B's columns stand (:meth:`set_layout`)."""

    def set_layout(self, layout: ColumnLayout) -> None:
        """Move B's columns (bodies, titles, colour bar) to ``layout``'s places."""
        with self._lock, self.server.atomic():
            self.layout = layout
            places = {"body": layout.compare_body_x, "heat": layout.compare_heat_x,
                      "title_body": layout.compare_body_x, "title_heat": layout.compare_heat_x,
                      "legend": layout.compare_heat_x}  # fmt: skip
            for name, x in places.items():
                handle = self._nodes.get(name)
                if handle is not None:
                    handle.position = (x, float(handle.position[1]), float(handle.position[2]))

    def show(
        self,
        view: PosteriorView,
        faces: np.ndarray,
        scale: HeatmapScale,
        label: str,
        titles_top: float,
        show_samples: bool = True,
        same_bodies: bool = False,
    ) -> None:
        """Draw B's ``view`` (faces ``(F, 3)``) coloured by ``scale``, titled with ``label``;
        ``same_bodies``: B's meshes are drawn already (only its colours may change)."""
        scene = self.server.scene
        with self._lock, self.server.atomic():
            if not self.shown:
                places = (("body", self.layout.compare_body_x),
                          ("heat", self.layout.compare_heat_x))  # fmt: skip
                for name, x in places:
                    self._nodes[name] = scene.add_frame(
                        f"/compare_{name}", wxyz=HALF_TURN_ABOUT_X, position=(x, 0.0, 0.0),
                        show_axes=False,
                    )  # fmt: skip
            if not (same_bodies and self.shown and self._samples_shown == show_samples):
                self._draw_bodies(view, faces, show_samples)
            values = view.change_ratio if scale.kind == "change" else view.uncertainty
            self._show_heat_points(view.mode_vertices, scale.colours(values))
            if self._titled != (label, scale, titles_top):  # unchanged: not sent again
                self._titles(label, scale, titles_top)
                self._titled = (label, scale, titles_top)
            self.shown = True

    def _show_heat_points(self, vertices: np.ndarray, colours: np.ndarray) -> None:
        """B's heatmap points at ``vertices (V, 3)`` in ``colours (V, 3)`` uint8; the positions
        are sent only when they moved (a slider move recolours B's most likely body)."""
        handle = self._nodes.get("points")
        if not isinstance(handle, viser.PointCloudHandle):
            self._nodes["points"] = self.server.scene.add_point_cloud(
                "/compare_heat/points", vertices, colours, point_size=0.03,
                point_shape="circle", point_shading="flat",
            )  # fmt: skip
        else:
            if self._heat_vertices is not vertices and not np.array_equal(
                self._heat_vertices, vertices
            ):
                handle.points = vertices
            handle.colors = colours
        self._heat_vertices = vertices

    def _draw_bodies(self, view: PosteriorView, faces: np.ndarray, show_samples: bool) -> None:
        """B's most likely body (beside its samples, and under its colours) and samples."""
        self._mesh("/compare_body/mode", view.mode_vertices, faces, MODE_COLOUR, 1.0)
        self._mesh("/compare_heat/base", view.mode_vertices, faces, HEATMAP_BASE_COLOUR, 1.0)
        shown = view.sample_vertices if show_samples else view.sample_vertices[:0]
        self._show_samples(shown, faces)
        self._samples_shown = show_samples

    def _titles(self, label: str, scale: HeatmapScale, top: float) -> None:
        body_title, heat_title = compare_titles(label, scale.kind)
        scene = self.server.scene
        for name, text, x in (("title_body", body_title, self.layout.compare_body_x),
                              ("title_heat", heat_title, self.layout.compare_heat_x)):  # fmt: skip
            self._nodes[name] = scene.add_label(
                f"/titles/compare_{name}", text, position=(x, top, 0.0), font_screen_scale=1.15,
                anchor="bottom-center",
            )  # fmt: skip
        legend = (
            change_legend_image(640, 150, title="Uncertainty of B ÷ uncertainty of A")
            if scale.kind == "change"
            else scale.legend(width=640, height=150)
        )
        self._nodes["legend"] = scene.add_image(
            "/compare_legend", legend, *LEGEND_SIZE_M, format="png", wxyz=HALF_TURN_ABOUT_X,
            position=(self.layout.compare_heat_x, LEGEND_HEIGHT, LEGEND_Z), cast_shadow=False,
            receive_shadow=False,
        )  # fmt: skip

    def _mesh(self, name: str, vertices: np.ndarray, faces: np.ndarray, colour, opacity) -> None:
        handle = self._nodes.get(name)
        if handle is not None and isinstance(handle, viser.MeshHandle):
            handle.vertices = vertices
            return
        self._nodes[name] = self.server.scene.add_mesh_simple(
            name, vertices, faces, color=colour, opacity=opacity, cast_shadow=False,
            receive_shadow=False,
        )  # fmt: skip

    def _show_samples(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        while len(self._samples) > len(vertices):
            self._samples.pop().remove()
        for index, sample in enumerate(vertices):
            if index < len(self._samples):
                self._samples[index].vertices = sample
            else:
                self._samples.append(
                    self.server.scene.add_mesh_simple(
                        f"/compare_body/samples/{index:02d}",
                        sample,
                        faces,
                        color=SAMPLE_COLOUR,
                        opacity=SAMPLE_OPACITY,
                        cast_shadow=False,
                        receive_shadow=False,
                    )
                )

    def clear(self) -> None:
        """Remove B's columns."""
        with self._lock, self.server.atomic():
            for handle in self._samples:
                handle.remove()
            for name in ("points", "/compare_body/mode", "/compare_heat/base", "title_body",
                         "title_heat", "legend", "body", "heat"):  # fmt: skip
                handle = self._nodes.pop(name, None)
                if handle is not None:
                    handle.remove()
            self._samples, self._nodes = [], {}
            self._titled, self._heat_vertices = None, None
            self.shown = False
