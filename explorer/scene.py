"""Everything drawn in the 3D scene, through viser's GLOBAL scene (broadcast to every tab).

Layout (world y up, viewer on +z): the photo on the left, the mode body with its sample
"ghosts" in the middle, and a second copy of the mode coloured by per-vertex uncertainty on the
right; once further photos of the same person are added, their combined shape stands in a
T-pose, coloured by shape uncertainty, right of that. Photo and bodies live in nodes turned to
OpenCV axes (see :mod:`photo_geometry`), so pixel and body-frame coordinates are used as they
are.

The per-vertex heatmap is a coloured point cloud over the vertices of a neutral mesh:
``add_mesh_simple`` has one colour per mesh, and updating a point cloud's colours and positions
is a small message (see ``docs/explorer.md`` for the measured alternative, a per-vertex
coloured GLB).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator

import numpy as np
import viser

from hkpd.coco_keypoints import COCO17_LIMBS
from hkpd.explorer.colour_map import HeatmapScale
from hkpd.explorer.layout import DEFAULT_LAYOUT, ColumnLayout
from hkpd.explorer.people_marks import PeopleMarks
from hkpd.explorer.photo_geometry import HALF_TURN_ABOUT_X, PhotoPlacement
from hkpd.explorer.posterior_view import PosteriorView
from hkpd.explorer.state import Occluder

MODE_COLOUR = (200, 194, 186)
"""The most likely body's default colour: a neutral clay, as the field draws its figures (a
mannequin, not a person's skin)."""
SKIN_COLOUR = (236, 168, 128)
LOOK_COLOURS: dict[str, tuple[int, int, int]] = {"clay": MODE_COLOUR, "skin": SKIN_COLOUR}
"""The looks of the most likely body (the Body section's *Look* menu) and their colours."""
SAMPLE_COLOUR = (90, 150, 235)
SAMPLE_OPACITY = 0.16
HEATMAP_BASE_COLOUR = (70, 95, 165)
AXIS_COLOURS = np.array([[230, 60, 60], [60, 180, 75], [60, 110, 230]], dtype=np.uint8)

BODY_POSITION = (0.0, 0.0, 0.0)
HEATMAP_OFFSET = DEFAULT_LAYOUT.heat_x
"""Metres between the sample body and the heatmap body in the default layout (an arm span,
~1.7 m, so that outstretched arms and their samples never overlap); a photo's own layout
(:func:`hkpd.explorer.layout.column_layout`, :attr:`ExplorerScene.layout`) may be narrower."""
COMBINED_OFFSET = DEFAULT_LAYOUT.combined_x
"""x of the combined-shape body (a T-pose arm span, ~1.7 m, right of the heatmap body)."""
PHOTO_GAP = DEFAULT_LAYOUT.photo_gap
"""Metres between the photo's right edge and the body's centre (half an arm span) in the
default layout."""
LEGEND_HEIGHT = -1.22
"""World height of the colour bar's centre."""
LEGEND_SIZE_M = (1.4, 1.4 * 150 / 640)
"""World width and height of the colour bar."""
LEGEND_Z = 0.05
"""World z of the colour bar (in front of the photo plane)."""
FLOOR_HEIGHT = -1.0
"""World y of the floor grid."""
FLOOR_DEPTH = 4.0
"""Metres the floor grid reaches back from the photo plane (z = 0) into the scene."""
FLOOR_RIGHT = COMBINED_OFFSET + 1.2
"""World x of the floor's right edge (past the combined-shape body's hand)."""
JOINT_LABEL_HEIGHT = LEGEND_HEIGHT - LEGEND_SIZE_M[1] / 2 - 0.02
"""World height of the top of the selected joint's concentration label, under the mode body
(beside the joint it ran into the uncertainty body), and lower than the colour bar's bottom
(level with the bar it ran into the bar when the columns stand close)."""
OVERLAY_LIFT = -0.004
"""Local z of drawings on the photo (negative: towards the viewer)."""


BODY_DRAWINGS = (
    "/body/joint_axes",
    "/joint_axes_label",
    "/legend",
    "/photo/keypoints",
    "/photo/reprojection",
)
"""Scene nodes of one person's prediction that are added by name (see
:meth:`ExplorerScene.clear_bodies`)."""


class ExplorerScene:
    """Creates and updates the scene nodes. Thread-safe (one lock around every update).

    Args:
        server: the viser server.
    """

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.faces = np.zeros((0, 3), dtype=np.uint32)
        self.placement: PhotoPlacement | None = None
        self.show_samples = True
        self.show_heatmap = True
        self.show_reprojection = True
        self.heatmap = HeatmapScale()
        self.legend_scale: HeatmapScale | None = None
        """The colouring the drawn colour bar shows (the change colouring without a baseline
        falls back to the log scale, and the colour bar says so)."""
        self._lock = threading.RLock()
        self._samples: list[viser.MeshHandle] = []
        self._mode: viser.MeshHandle | None = None
        self.mode_colour: tuple[int, int, int] = MODE_COLOUR
        self._heat_base: viser.MeshHandle | None = None
        self._heat_points: viser.PointCloudHandle | None = None
        self._occluder_nodes: list[viser.SceneNodeHandle] = []
        self._person_node: viser.SceneNodeHandle | None = None
        self._fit_node: viser.SceneNodeHandle | None = None
        self._combined: list[viser.SceneNodeHandle] = []
        self.combined_shown = False
        self.titles_top = 1.08
        """World height of the column titles (the combined-shape body's title too)."""
        self.static = False
        """Titles for a saved page (nothing of the live app: no "shift+drag")."""
        self.compared = False
        """B's columns are shown: A's titles say "A" (:meth:`set_compared`)."""
        self.people_marks = PeopleMarks(self)
        """The listed people, numbered on the photo (the Person menu's entries)."""
        self.layout = DEFAULT_LAYOUT
        """Where the columns stand (:meth:`set_layout`)."""
        server.scene.set_up_direction("+y")
        server.scene.world_axes.visible = False
        self.scene_body = server.scene.add_frame(
            "/body", wxyz=HALF_TURN_ABOUT_X, position=BODY_POSITION, show_axes=False
        )
        self.scene_heat = server.scene.add_frame(
            "/heat", wxyz=HALF_TURN_ABOUT_X, position=(HEATMAP_OFFSET, 0.0, 0.0), show_axes=False
        )
        self.scene_combined = server.scene.add_frame(
            "/combined", wxyz=HALF_TURN_ABOUT_X, position=(COMBINED_OFFSET, 0.0, 0.0),
            show_axes=False,
        )  # fmt: skip
        add_floor(server.scene, left=-(PHOTO_GAP + 2.0))

    @property
    def absolute_scale(self) -> HeatmapScale:
        """The colouring of absolute uncertainty in use (the log scale while the uncertainty
        body shows the change colouring): the combined-shape body's."""
        return HeatmapScale("log") if self.heatmap.kind == "change" else self.heatmap

    def show_titles(self, top: float) -> None:
        """Titles above the three columns and the colour bar under the heatmap body.

        Args:
            top: world height (metres) of the titles.
        """
        with self._lock:
            assert self.placement is not None
            photo, body, uncertainty = column_titles(self.heatmap.kind, compared=self.compared)
            titles = (
                ("photo", photo, self.placement.centre[0]),
                ("samples", body, BODY_POSITION[0]),
                ("uncertainty", uncertainty, self.layout.heat_x),
            )
            self.titles_top = top
            for name, text, x in titles:
                self.server.scene.add_label(
                    f"/titles/{name}",
                    text,
                    position=(x, top, 0.0),
                    font_screen_scale=1.15,
                    anchor="bottom-center",
                )
            if self.legend_scale is not None:  # not while no body is drawn ("No person")
                self.show_legend()

    def set_compared(self, compared: bool) -> None:
        """A's column titles say "A" while B's columns are shown (they said nothing, so a
        class could not tell A's bodies from the photo's own)."""
        with self._lock:
            if self.compared != bool(compared):
                self.compared = bool(compared)
                if self.placement is not None:
                    self.show_titles(self.titles_top)

    @contextlib.contextmanager
    def static_titles(self) -> Iterator[None]:
        """Inside: the titles of a saved page (see :func:`column_titles`); after: the live
        app's again."""
        with self._lock:
            self.static = True
            if self.placement is not None:
                self.show_titles(self.titles_top)
            try:
                yield
            finally:
                self.static = False
                if self.placement is not None:
                    self.show_titles(self.titles_top)

    def show_legend(self, scale: HeatmapScale | None = None) -> None:
        """The colour bar of ``scale`` (default: :attr:`heatmap`) under the heatmap body; its
        title says what is shown and in which unit."""
        with self._lock:
            scale = self.heatmap if scale is None else scale
            self.legend_scale = scale
            # Large enough that its labels read at the framed distance (they were tiny).
            self.server.scene.add_image(
                "/legend",
                scale.legend(width=640, height=150),
                *LEGEND_SIZE_M,
                format="png",
                wxyz=HALF_TURN_ABOUT_X,
                position=(self.layout.heat_x, LEGEND_HEIGHT, LEGEND_Z),
                cast_shadow=False,
                receive_shadow=False,
            )

    def set_layout(self, layout: ColumnLayout) -> None:
        """Move the uncertainty and combined-shape columns (bodies, titles, colour bars) to
        ``layout``'s places (world metres along x)."""
        with self._lock, self.server.atomic():
            self.layout = layout
            self.scene_heat.position = (layout.heat_x, 0.0, 0.0)
            self.scene_combined.position = (layout.combined_x, 0.0, 0.0)
            nodes = self.server.scene._handle_from_node_name
            for name, x in (("/titles/uncertainty", layout.heat_x), ("/legend", layout.heat_x),
                            ("/combined_title", layout.combined_x),
                            ("/combined_legend", layout.combined_x)):  # fmt: skip
                handle = nodes.get(name)
                if handle is not None:
                    handle.position = (x, float(handle.position[1]), float(handle.position[2]))

    # ------------------------------------------------------------------ photo
    def place_photo(self, image: np.ndarray, placement: PhotoPlacement) -> None:
        """Show a new photo (``(H, W, 3)`` uint8) at ``placement``; clears overlays.

        Occluders belong to their photo: the old photo's boxes are removed from the scene
        (replacing the ``/photo`` node keeps its children, in this tab and in tabs opened
        later, so they must be removed by hand).
        """
        with self._lock:
            for node in reversed(self._occluder_nodes):  # children first, then their frame
                node.remove()
            self._occluder_nodes = []
            if self._person_node is not None:
                self._person_node.remove()
                self._person_node = None
            self.placement = placement
            self.people_marks.show(())  # the last photo's people
            add_floor(self.server.scene, left=placement.centre[0] - placement.width_m / 2)
            self.server.scene.add_image(
                "/photo",
                image,
                placement.width_m,
                placement.height_m,
                format="jpeg",
                jpeg_quality=90,
                wxyz=HALF_TURN_ABOUT_X,
                position=placement.centre,
                cast_shadow=False,
                receive_shadow=False,
            )
            self._occluder_nodes = []

    def photo_points(self, pixels: np.ndarray) -> np.ndarray:
        """``(..., 2)`` photo pixels (pixel-centre coords) to ``(..., 3)`` photo-local points,
        lifted off the photo towards the viewer (for drawings on it)."""
        return self._photo_points(pixels)

    def _photo_points(self, pixels: np.ndarray) -> np.ndarray:
        """``(..., 2)`` photo pixels (pixel-centre coords) to ``(..., 3)`` photo-local points."""
        assert self.placement is not None
        local = self.placement.pixels_to_local(np.asarray(pixels) + 0.5)
        lift = np.full((*local.shape[:-1], 1), OVERLAY_LIFT)
        return np.concatenate([local, lift], axis=-1).astype(np.float32)

    def show_keypoints(self, keypoints: np.ndarray, confidences: np.ndarray) -> None:
        """Detected keypoints ``(17, 2)`` on the photo; confident green, doubtful red."""
        with self._lock:
            if self.placement is None:
                return
            colours = np.where(
                (np.asarray(confidences) >= 0.6)[:, None], [[40, 220, 90]], [[235, 50, 50]]
            ).astype(np.uint8)
            shown = self.placement.on_photo(keypoints)  # none drawn beside or below the photo
            self.server.scene.add_point_cloud(
                "/photo/keypoints",
                self._photo_points(np.asarray(keypoints)[shown]),
                colours[shown],
                point_size=0.018,
                point_shape="circle",
                point_shading="flat",
            )

    def show_fit_overlay(
        self, rgba: np.ndarray | None, box: tuple[float, float, float, float] | None
    ) -> None:
        """The mode mesh rendered with the predicted camera, pasted over the photo's crop box
        (``rgba (S, S, 4)`` uint8, ``box`` in photo pixels); None hides it. Only the part on
        the photo is drawn (a crop box reaching past the photo's edge left the body drawn
        below it)."""
        with self._lock:
            if self._fit_node is not None:
                self._fit_node.remove()
                self._fit_node = None
            if rgba is None or box is None or self.placement is None:
                return
            clipped = self.placement.clip_image(np.asarray(rgba), box)
            if clipped is None:
                return
            rgba, (x0, y0, x1, y1) = clipped
            centre = self._photo_points(np.array([[(x0 + x1) / 2, (y0 + y1) / 2]]) - 0.5)[0]
            centre[2] = 1.5 * OVERLAY_LIFT
            metres = self.placement.metres_per_pixel
            self._fit_node = self.server.scene.add_image(
                "/photo/fit", np.ascontiguousarray(rgba), (x1 - x0) * metres, (y1 - y0) * metres,
                format="png", position=tuple(centre), cast_shadow=False, receive_shadow=False,
            )  # fmt: skip

    def show_person_box(self, box: tuple[float, float, float, float] | None) -> None:
        """Outline the box the person is looked for in (None removes it)."""
        with self._lock:
            if self._person_node is not None:
                self._person_node.remove()
                self._person_node = None
            if box is None or self.placement is None:
                return
            x0, y0, x1, y1 = box
            corners = self._photo_points(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]) - 0.5)
            edges = np.stack([corners, np.roll(corners, -1, axis=0)], axis=1)
            edges[:, :, 2] = 3 * OVERLAY_LIFT
            self._person_node = self.server.scene.add_line_segments(
                "/photo/person_box", edges, (40, 200, 255), thickness=3.0,
                thickness_units="screen",
            )  # fmt: skip

    def show_occluders(self, occluders: tuple[Occluder, ...]) -> None:
        """Draw every occluder: enabled ones dark and filled, disabled ones as outlines."""
        with self._lock:
            if self.placement is None:
                return
            for node in reversed(self._occluder_nodes):  # children first, then their frame
                node.remove()
            self._occluder_nodes = []
            for occluder in occluders:
                x0, y0, x1, y1 = occluder.box
                corners = self._photo_points(
                    np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]) - 0.5
                )
                corners[:, 2] = 2 * OVERLAY_LIFT
                name = f"/photo/occluders/{occluder.ident}"
                # One frame per box, so that removing it removes the whole box (fill, outline,
                # label) from the scene, also for tabs that connect later.
                self._occluder_nodes.append(self.server.scene.add_frame(name, show_axes=False))
                if occluder.enabled:
                    self._occluder_nodes.append(
                        self.server.scene.add_mesh_simple(
                            f"{name}/fill",
                            corners,
                            np.array([[0, 1, 2], [0, 2, 3]]),
                            color=(15, 15, 20),
                            opacity=0.85,
                            side="double",
                            cast_shadow=False,
                            receive_shadow=False,
                        )
                    )
                edges = np.stack([corners, np.roll(corners, -1, axis=0)], axis=1)
                edges[:, :, 2] = 3 * OVERLAY_LIFT
                self._occluder_nodes.append(
                    self.server.scene.add_line_segments(
                        f"{name}/outline",
                        edges,
                        (250, 200, 40) if occluder.enabled else (160, 160, 160),
                        thickness=2.0,
                        thickness_units="screen",
                    )
                )
                self._occluder_nodes.append(
                    self.server.scene.add_label(
                        f"{name}/label",
                        f"#{occluder.ident}",
                        position=tuple(corners[0]),
                        font_screen_scale=0.8,
                        anchor="bottom-left",
                    )
                )

    # ------------------------------------------------------------------ same person
    def show_combined_shape(
        self, vertices: np.ndarray | None, uncertainty_m: np.ndarray | None, title: str = ""
    ) -> None:
        """The shape combined from several photos: ``vertices (V, 3)`` T-pose in the body frame
        (metres, drawn at scale 1 like the other bodies: a standing T-pose is taller than a
        kneeling mode), coloured by ``uncertainty_m (V,)`` on the absolute scale in use, with
        its own colour bar under it and ``title`` in the row of the column titles; None
        removes it. Needs the faces of a drawn view."""
        with self._lock, self.server.atomic():
            for node in self._combined:
                node.remove()
            self._combined = []
            self.combined_shown = vertices is not None
            if vertices is None or uncertainty_m is None or len(self.faces) == 0:
                return
            points = np.ascontiguousarray(vertices, dtype=np.float32)
            self._combined = [
                self.server.scene.add_mesh_simple(
                    "/combined/base", points, self.faces, color=HEATMAP_BASE_COLOUR,
                    cast_shadow=False, receive_shadow=False,
                ),
                self.server.scene.add_point_cloud(
                    "/combined/points", points,
                    self.absolute_scale.colours(uncertainty_m), point_size=0.03,
                    point_shape="circle", point_shading="flat",
                ),
                self.server.scene.add_label(
                    "/combined_title", title,
                    position=(self.layout.combined_x, self.titles_top, 0.0),
                    font_screen_scale=1.15, anchor="bottom-center",
                ),
                self.server.scene.add_image(
                    "/combined_legend", self.absolute_scale.legend(width=640, height=150),
                    *LEGEND_SIZE_M, format="png", wxyz=HALF_TURN_ABOUT_X,
                    position=(self.layout.combined_x, LEGEND_HEIGHT, LEGEND_Z), cast_shadow=False,
                    receive_shadow=False,
                ),
            ]  # fmt: skip

    # ------------------------------------------------------------------ bodies
    def show_view(self, view: PosteriorView, faces: np.ndarray | None = None) -> None:
        """Update meshes, heatmap, axes and reprojections from a computed view.

        Args:
            view: what to draw.
            faces: ``(F, 3)`` body mesh faces; needed the first time and when they change.
        """
        with self._lock, self.server.atomic():
            if faces is not None and not np.array_equal(faces, self.faces):
                self._drop_meshes()
                self.faces = np.ascontiguousarray(faces, dtype=np.uint32)
            self._update_mode(view.mode_vertices)
            self._update_samples(view.sample_vertices if self.show_samples else None)
            self._update_heatmap(view)
            self._update_axes(view)
            self._update_reprojection(view)

    def clear_bodies(self) -> None:
        """Remove the bodies, the heatmap, the joint axes and the keypoints, reprojections and
        fit drawn on the photo (nobody was found: nothing of the last person may stay)."""
        with self._lock, self.server.atomic():
            self._drop_meshes()
            if self._heat_points is not None:
                self._heat_points.remove()
                self._heat_points = None
            if self._fit_node is not None:
                self._fit_node.remove()
                self._fit_node = None
            for name in BODY_DRAWINGS:  # added by name (re-adding replaces): remove by name
                handle = self.server.scene._handle_from_node_name.get(name)
                if handle is not None:
                    handle.remove()
            self.legend_scale = None  # the next body's view draws its colour bar again

    def _drop_meshes(self) -> None:
        for handle in [*self._samples, self._mode, self._heat_base]:
            if handle is not None:
                handle.remove()
        self._samples, self._mode, self._heat_base = [], None, None

    def _update_mode(self, vertices: np.ndarray) -> None:
        if self._mode is None:
            self._mode = self.server.scene.add_mesh_simple(
                "/body/mode",
                vertices,
                self.faces,
                color=self.mode_colour,
                cast_shadow=False,
                receive_shadow=False,
            )
        else:
            self._mode.vertices = vertices

    def set_mode_colour(self, colour: tuple[int, int, int]) -> None:
        """Draw the most likely body in ``colour`` (RGB 0-255) from now on."""
        with self._lock:
            self.mode_colour = tuple(int(c) for c in colour)  # type: ignore[assignment]
            if self._mode is not None:
                self._mode.color = self.mode_colour

    def _update_samples(self, vertices: np.ndarray | None) -> None:
        count = 0 if vertices is None else len(vertices)
        while len(self._samples) > count:
            self._samples.pop().remove()
        for index in range(count):
            assert vertices is not None
            if index < len(self._samples):
                self._samples[index].vertices = vertices[index]
            else:
                self._samples.append(
                    self.server.scene.add_mesh_simple(
                        f"/body/samples/{index:02d}",
                        vertices[index],
                        self.faces,
                        color=SAMPLE_COLOUR,
                        opacity=SAMPLE_OPACITY,
                        cast_shadow=False,
                        receive_shadow=False,
                    )
                )

    def _update_heatmap(self, view: PosteriorView) -> None:
        visible = self.show_heatmap
        if self._heat_base is None:
            self._heat_base = self.server.scene.add_mesh_simple(
                "/heat/base",
                view.mode_vertices,
                self.faces,
                color=HEATMAP_BASE_COLOUR,
                cast_shadow=False,
                receive_shadow=False,
            )
        else:
            self._heat_base.vertices = view.mode_vertices
        scale, values = self.heatmap, view.uncertainty
        if scale.kind == "change" and view.change_ratio is not None:
            values = view.change_ratio
        elif scale.kind == "change":
            scale = HeatmapScale("log")  # no baseline (yet): absolute, and the bar says so
        if scale != self.legend_scale:
            self.show_legend(scale)
        colours = scale.colours(values)
        if self._heat_points is None:
            self._heat_points = self.server.scene.add_point_cloud(
                "/heat/points",
                view.mode_vertices,
                colours,
                point_size=0.03,
                point_shape="circle",
                point_shading="flat",
            )
        else:
            self._heat_points.points = view.mode_vertices
            self._heat_points.colors = colours
        self._heat_base.visible = visible
        self._heat_points.visible = visible

    def _update_axes(self, view: PosteriorView) -> None:
        axes = view.axes
        length = 0.22
        starts = np.repeat(axes.origin[None], 3, axis=0)
        ends = starts + length * axes.axes.T
        self.server.scene.add_arrows(
            "/body/joint_axes",
            np.stack([starts, ends], axis=1).astype(np.float32),
            AXIS_COLOURS,
            shaft_radius=0.005,
            head_radius=0.012,
            head_length=0.03,
        )
        # One label beside the joint, not one per arrow tip: tips that point at the viewer
        # crowd together and their numbers overlapped ("2797" printed over "2721").
        text = " · ".join(
            f"{name} {_concentration_text(value)}"
            for name, value in zip(("red", "green", "blue"), axes.concentrations, strict=True)
        )
        # Under the mode body in world coordinates (not beside the joint, where it ran into
        # the uncertainty body): the arrows' colours name the axes.
        self.server.scene.add_label(
            "/joint_axes_label",
            f"Arrows at the {view.axes.joint.replace('_', ' ')}: {text}",
            position=(BODY_POSITION[0], JOINT_LABEL_HEIGHT, LEGEND_Z),
            font_screen_scale=0.85,
            anchor="top-center",
        )

    def _update_reprojection(self, view: PosteriorView) -> None:
        if self.placement is None:
            return
        bones = np.array(COCO17_LIMBS)
        shown = view.sample_keypoints2d[: max(len(view.sample_vertices), 1)]
        size = (self.placement.width_px, self.placement.height_px)
        # Clipped to the photo: the lines of a limb reprojected off the photo stay on it.
        segments = self._photo_points(clip_segments(shown[:, bones].reshape(-1, 2, 2), size))
        mode_segments = self._photo_points(clip_segments(view.mode_keypoints2d[bones], size))
        points = np.concatenate([segments, mode_segments]).astype(np.float32)
        colours = np.concatenate(
            [
                np.broadcast_to(np.array(SAMPLE_COLOUR, np.uint8), (len(segments), 2, 3)),
                np.broadcast_to(np.array((255, 140, 30), np.uint8), (len(mode_segments), 2, 3)),
            ]
        )
        self.server.scene.add_line_segments(
            "/photo/reprojection",
            points,
            colours,
            thickness=1.5,
            thickness_units="screen",
            visible=self.show_reprojection,
        )


def column_titles(kind: str, static: bool = False, compared: bool = False) -> tuple[str, str, str]:
    """The photo's, the most likely body's and the uncertainty body's column titles for the
    colouring ``kind`` (a key of ``COLOURINGS``); ``compared``: B's columns are shown beside
    them, so the bodies' titles begin with "A".

    The titles are short lines (at most "most likely body + samples" wide): the columns stand
    closer than a one-line title is long when the row is narrowed for the person's reach or
    for B's columns ("samplesUncertainty"). The same in the live app and in a saved page or
    PNG (``static`` is kept for callers): a title changed just for a screenshot was still
    re-drawing in the browser when the PNG was taken, so PNGs kept the live hint; how to draw
    a box is said in the *Photo* panel instead.
    """
    del static
    body, heat = "most likely body\n+ samples", "uncertainty\nover samples"
    if kind == "change":
        heat = "change: uncertainty\n÷ no occluders,\n1× concentrations"
    if compared:
        return "Photo", f"A: {body}", f"A: {heat}"
    return "Photo", body[0].upper() + body[1:], heat[0].upper() + heat[1:]


def _concentration_text(value: float) -> str:
    """Two significant digits below 10 (``2.4``), whole numbers above (``285``)."""
    return f"{value:.2g}" if value < 10 else f"{value:.0f}"


def add_floor(scene: viser.SceneApi, left: float, right: float = FLOOR_RIGHT) -> viser.GridHandle:
    """The floor grid, from world x ``left`` to ``right``, entirely BEHIND the photo plane
    (z <= 0) at :data:`FLOOR_HEIGHT`.

    Seen from the framed camera (above the floor, in front of the photo), a floor reaching in
    front of the photo plane was drawn over the photo's bottom and across the colour bar (both
    in front of it in depth, under the floor's height on screen). Behind the plane, every
    floor line hidden by the opaque photo stays hidden, and the colour bar (lower than the
    floor, in front of the plane) is never crossed.

    Args:
        scene: the viser scene (``server.scene``).
        left, right: world x of the floor's ends, metres.
    """
    return scene.add_grid(
        "/floor",
        width=float(right - left),
        height=FLOOR_DEPTH,
        plane="xz",
        position=((left + right) / 2, FLOOR_HEIGHT, -FLOOR_DEPTH / 2),
        cell_color=(215, 215, 215),
        section_color=(180, 180, 180),
    )


def clip_segments(segments: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Clip 2D line segments to the photo rectangle (Liang-Barsky).

    Args:
        segments: ``(..., 2, 2)`` segment end points in photo pixels.
        size: ``(width, height)`` of the photo, pixels.

    Returns:
        ``(..., 2, 2)`` the parts inside ``[0, width] x [0, height]``; a segment entirely
        outside collapses to a point on the rectangle's border (drawn as nothing).
    """
    points = np.asarray(segments, dtype=np.float64)
    start, delta = points[..., 0, :], points[..., 1, :] - points[..., 0, :]
    bounds = np.array(size, dtype=np.float64)
    enter = np.zeros(start.shape[:-1])
    leave = np.ones(start.shape[:-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis in range(2):
            d, p = delta[..., axis], start[..., axis]
            low, high = (0.0 - p) / d, (bounds[axis] - p) / d
            near, far = np.minimum(low, high), np.maximum(low, high)
            parallel = d == 0
            inside = (p >= 0) & (p <= bounds[axis])
            near = np.where(parallel, np.where(inside, -np.inf, np.inf), near)
            far = np.where(parallel, np.where(inside, np.inf, -np.inf), far)
            enter, leave = np.maximum(enter, near), np.minimum(leave, far)
    leave = np.maximum(leave, enter)  # outside: both ends at one point
    clipped = np.stack([start + enter[..., None] * delta, start + leave[..., None] * delta], -2)
    return np.clip(clipped, 0.0, bounds)
