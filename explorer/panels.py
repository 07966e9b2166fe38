"""The explorer's GUI panel (viser's global GUI: every tab sees and drives the same controls).

Callbacks here only touch the state and ask the app for work; nothing heavy runs in them.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Protocol

import numpy as np
import torch
import viser

from hkpd.explorer.colour_map import DEFAULT_MAX_CM, legend_image
from hkpd.explorer.state import (
    CONCENTRATION_EXPONENT_RANGE,
    LIMB_GROUPS,
    MAX_DISPLAYED_SAMPLES,
    MAX_SAMPLES,
    Occluder,
)
from hkpd.kinematic_tree import BODY_JOINT_NAMES

if TYPE_CHECKING:
    from hkpd.explorer.state import ExplorerState


class PanelActions(Protocol):
    """What the panel may ask of the app (``ExplorerApp`` implements it): change the state, then
    say what became stale; nothing else of the app is reachable from a callback."""

    state: ExplorerState

    def occluders_changed(self, changed: bool) -> bool: ...
    def sampling_changed(self, changed: bool) -> None: ...
    def clear_occluders(self) -> None: ...
    def set_plain_drag_draws(self, enabled: bool) -> None: ...
    def set_evidence(self, enabled: bool) -> None: ...
    def set_person_box(self, box: tuple[float, float, float, float] | None) -> bool: ...
    def select_person(self, index: int) -> bool: ...
    def pick_person_next(self, enabled: bool = True) -> None: ...
    def show_fit(self, visible: bool, opacity: float) -> None: ...
    def set_display_options(
        self, samples: bool, heatmap: bool, reprojection: bool, heatmap_max_cm: float
    ) -> bool: ...
    def load_upload(self, name: str, content: bytes, client: viser.ClientHandle | None) -> None: ...
    def add_same_person_upload(
        self, name: str, content: bytes, client: viser.ClientHandle | None
    ) -> None: ...
    def clear_same_person(self) -> None: ...
    def request_export(self, file_format: str, client: viser.ClientHandle) -> None: ...
    def request_screenshot(self, client: viser.ClientHandle) -> None: ...


NO_PERSON_CHOICE = "(one person)"


def _person_choice(index: int, count: int) -> str:
    """The dropdown label of person ``index`` (0-based) of ``count``."""
    return f"Person {index + 1} of {count}" + (" (the detector's best)" if index == 0 else "")


EXPONENT_MARKS = ((-1.0, "0.1×"), (0.0, "1×"), (1.0, "10×"))

EXPLANATION = """\
**What you are looking at.** The photo (left) goes through the network, which predicts a
*probability distribution* over 3D bodies, not one body. By default that distribution is then
*conditioned on the 2D keypoints* the detector found (white dots): the network's distribution
is the prior, the keypoints are the evidence. The solid body is the most likely one (the mode);
the ghosts are samples from the distribution; the body on the right is coloured by how far its
vertices move across 100 samples (dark purple: certain, yellow: uncertain; the colour bar gives
centimetres).

**Try it.** Shift + drag on the photo to hide part of the person behind a box: the keypoints
under it stop counting as evidence, the joints that moved the hidden part fall back to the
network's (wider) prior, and their limb spreads out and turns yellow. Untick *Condition on 2D
keypoints* to see the network alone. The sliders scale each joint's *concentration* by hand.

**The maths.** Each joint's rotation relative to its parent follows a matrix-Fisher
distribution with parameter F = U S V&#x1D40;. The arrows at the selected joint are its principal
axes; the numbers are the concentrations s&#x2C7C; + s&#x2096; for rotations about each axis:
large means confident. Conditioning adds the keypoints' evidence to the network's F (Teaching:
*network* vs *with evidence*).
"""


class ExplorerPanels:
    """Builds the panel and keeps its dynamic parts (occluder list, teaching info) current."""

    def __init__(self, server: viser.ViserServer, app: PanelActions) -> None:
        self.server = server
        self.app = app
        self._lock = threading.RLock()  # the occluder list is rebuilt from several threads
        gui = server.gui
        state = app.state
        gui.configure_theme(control_width="large", show_logo=False, show_share_button=False)
        self.status = gui.add_markdown("Starting…")
        self.source = gui.add_markdown("")

        with gui.add_folder("Photo and occluders"):
            self.upload = gui.add_upload_button(
                "Load a photo",
                icon=viser.Icon.UPLOAD,
                mime_type="image/*",
                hint="JPEG/PNG/WebP/BMP/TIFF up to 25 MiB",
            )
            self.upload.on_upload(self._on_upload)
            self.evidence = gui.add_checkbox(
                "Condition on 2D keypoints",
                state.evidence,
                hint="On: the network's distribution updated by the detected keypoints (default). "
                "Off: the network alone (the paper's method).",
            )
            self.evidence.on_update(lambda _: app.set_evidence(self.evidence.value))
            self.pick = gui.add_button(
                "Pick the person",
                icon=viser.Icon.USER,
                hint="Then drag a box around the person on the photo (Shift + drag)",
            )
            self.pick.on_click(lambda _: self._start_picking())
            forget = gui.add_button("Forget the person box", icon=viser.Icon.X)
            forget.on_click(lambda _: app.set_person_box(None))
            self.people = gui.add_dropdown(
                "Person",
                (NO_PERSON_CHOICE,),
                visible=False,
                hint="Several people were found: choose whose body to estimate",
            )
            self.people.on_update(lambda _: self._on_person_chosen())
            gui.add_markdown("*Shift + drag on the photo draws an occluder.*")
            self.draw_mode = gui.add_checkbox(
                "Plain drag draws",
                False,
                hint="Draw occluders without holding Shift (the view stops orbiting)",
            )
            self.draw_mode.on_update(lambda _: app.set_plain_drag_draws(self.draw_mode.value))
            clear = gui.add_button("Remove all occluders", icon=viser.Icon.TRASH)
            clear.on_click(lambda _: app.clear_occluders())
            self.occluder_folder = gui.add_folder("Occluders", expand_by_default=True)
            self._occluder_handles: list[viser.GuiFolderHandle] = []
            self._occluder_signature: tuple = ()

        with gui.add_folder("Same person, more photos", expand_by_default=False):
            gui.add_markdown(
                "*More photos of the person in the current photo sharpen their shape: the "
                "shape distributions are multiplied (right-most body, T-pose, coloured by "
                "shape uncertainty).*"
            )
            self.same_person_upload = gui.add_upload_button(
                "Add a photo of the same person",
                icon=viser.Icon.USER_PLUS,
                mime_type="image/*",
                hint="Only its shape is used; the current photo stays on screen",
            )
            self.same_person_upload.on_upload(self._on_same_person_upload)
            self.same_person_text = gui.add_markdown("*Only the current photo so far.*")
            clear_same = gui.add_button("Forget the added photos", icon=viser.Icon.TRASH)
            clear_same.on_click(lambda _: app.clear_same_person())

        with gui.add_folder("Concentration"):
            low, high = CONCENTRATION_EXPONENT_RANGE
            self.global_slider = gui.add_slider(
                "All joints (log10)", low, high, 0.05, 0.0, marks=EXPONENT_MARKS
            )
            self.global_slider.on_update(
                lambda _: app.sampling_changed(state.set_global_exponent(self.global_slider.value))
            )
            self.shape_slider = gui.add_slider(
                "Shape spread (log10)", low, high, 0.05, 0.0, marks=EXPONENT_MARKS
            )
            self.shape_slider.on_update(
                lambda _: app.sampling_changed(
                    state.set_shape_std_exponent(self.shape_slider.value)
                )
            )
            self.joint_sliders: dict[str, viser.GuiSliderHandle] = {}
            for group, joints in LIMB_GROUPS.items():
                with gui.add_folder(group, expand_by_default=False):
                    for joint in joints:
                        slider = gui.add_slider(
                            joint.replace("_", " "), low, high, 0.05, 0.0, marks=EXPONENT_MARKS
                        )
                        slider.on_update(self._joint_callback(joint, slider))
                        self.joint_sliders[joint] = slider
            reset = gui.add_button("Reset concentrations", icon=viser.Icon.REFRESH)
            reset.on_click(lambda _: self._reset_concentrations())

        with gui.add_folder("Samples"):
            self.num_samples = gui.add_slider(
                "Samples for heatmap",
                min(10, state.num_samples),
                MAX_SAMPLES,
                1,
                state.num_samples,
            )
            self.num_samples.on_update(
                lambda _: app.sampling_changed(state.set_num_samples(self.num_samples.value))
            )
            self.num_displayed = gui.add_slider(
                "Sample meshes shown", 0, MAX_DISPLAYED_SAMPLES, 1, state.num_displayed
            )
            self.num_displayed.on_update(
                lambda _: app.sampling_changed(state.set_num_displayed(self.num_displayed.value))
            )
            self.seed = gui.add_number("Seed", state.seed, min=0, step=1)
            self.seed.on_update(lambda _: app.sampling_changed(state.set_seed(self.seed.value)))
            resample = gui.add_button("Resample", icon=viser.Icon.DICE)
            resample.on_click(lambda _: self._resample())
            self.show_samples = gui.add_checkbox("Show sample meshes", True)
            self.show_heatmap = gui.add_checkbox("Show uncertainty body", True)
            self.show_reprojection = gui.add_checkbox("Show 2D reprojection", True)
            self.show_fit = gui.add_checkbox(
                "Show the fit on the photo",
                True,
                hint="The most likely body drawn over the person with the predicted camera",
            )
            self.fit_opacity = gui.add_slider("Fit opacity", 0.0, 1.0, 0.05, 0.55)
            for control in (self.show_fit, self.fit_opacity):
                control.on_update(
                    lambda _: app.show_fit(self.show_fit.value, self.fit_opacity.value)
                )
            for box in (self.show_samples, self.show_heatmap, self.show_reprojection):
                box.on_update(lambda _: self._display_options())
            self.heat_max = gui.add_slider("Colour scale top (cm)", 2.0, 40.0, 1.0, DEFAULT_MAX_CM)
            self.heat_max.on_update(lambda _: self._display_options())
            self.legend = gui.add_image(legend_image(DEFAULT_MAX_CM), label="Uncertainty")

        with gui.add_folder("Teaching"):
            self.joint = gui.add_dropdown(
                "Joint", BODY_JOINT_NAMES, initial_value=state.selected_joint
            )
            self.joint.on_update(
                lambda _: app.sampling_changed(state.select_joint(self.joint.value))
            )
            self.axes_text = gui.add_markdown("")
            self.proxy_edges = gui.add_image(np.zeros((64, 64, 3), np.uint8), label="Edges")
            self.proxy_heat = gui.add_image(np.zeros((64, 64, 3), np.uint8), label="Heatmaps")
            with gui.add_folder("What am I looking at?", expand_by_default=False):
                gui.add_markdown(EXPLANATION)

        with gui.add_folder("Export", expand_by_default=False):
            for file_format in ("glb", "ply"):
                button = gui.add_button(f"Meshes ({file_format.upper()})", icon=viser.Icon.DOWNLOAD)
                button.on_click(self._export_callback(file_format))
            shot = gui.add_button("Screenshot (PNG)", icon=viser.Icon.CAMERA)
            shot.on_click(lambda event: app.request_screenshot(event.client))

    # ------------------------------------------------------------------ callbacks
    def _joint_callback(self, joint: str, slider: viser.GuiSliderHandle):
        def callback(_event) -> None:
            self.app.sampling_changed(self.app.state.set_joint_exponent(joint, slider.value))

        return callback

    def _export_callback(self, file_format: str):
        def callback(event) -> None:
            self.app.request_export(file_format, event.client)

        return callback

    def _on_upload(self, event) -> None:
        uploaded = self.upload.value
        self.app.load_upload(uploaded.name, uploaded.content, event.client)

    def _on_same_person_upload(self, event) -> None:
        uploaded = self.same_person_upload.value
        self.app.add_same_person_upload(uploaded.name, uploaded.content, event.client)

    def show_same_person(self, text: str) -> None:
        """What the combined shape is made of (photos, std) or that there is none."""
        self.same_person_text.content = text

    def show_people(self, count: int) -> None:
        """Offer a choice of person when the photo shows several (hidden otherwise)."""
        choices = tuple(_person_choice(i, count) for i in range(count)) or (NO_PERSON_CHOICE,)
        self._showing_people = True  # setting the options is not the user's choice
        try:
            self.people.options = choices
            self.people.value = NO_PERSON_CHOICE if count < 2 else choices[0]
            self.people.visible = count >= 2
        finally:
            self._showing_people = False

    def _on_person_chosen(self) -> None:
        if getattr(self, "_showing_people", False) or self.people.value == NO_PERSON_CHOICE:
            return
        self.app.select_person(int(self.people.value.split()[1]) - 1)

    def _start_picking(self) -> None:
        self.app.pick_person_next(True)
        self.show_picking(True)

    def show_picking(self, picking: bool) -> None:
        """Say in the status line that the next drag picks the person."""
        if picking:
            self.status.content = "**Drag a box around the person** (Shift + drag on the photo)."

    def show_busy(self, busy: bool) -> None:
        """Say that a prediction is running (it can take a second on a CPU)."""
        if busy:
            self.status.content = "⏳ *Predicting…*"

    def show_source(self, posterior) -> None:
        """Which distribution is shown, and why when the evidence fit fell back."""
        self.source.content = source_text(posterior)

    def _reset_concentrations(self) -> None:
        changed = self.app.state.reset_concentrations()
        for slider in (self.global_slider, self.shape_slider, *self.joint_sliders.values()):
            slider.value = 0.0
        self.app.sampling_changed(changed)

    def _resample(self) -> None:
        seed = self.app.state.next_seed()
        self.seed.value = seed
        self.app.sampling_changed(True)

    def _display_options(self) -> None:
        rescaled = self.app.set_display_options(
            self.show_samples.value,
            self.show_heatmap.value,
            self.show_reprojection.value,
            float(self.heat_max.value),
        )
        if rescaled:
            self.legend.image = legend_image(float(self.heat_max.value))

    # ------------------------------------------------------------------ dynamic parts
    def show_occluders(self, occluders: tuple[Occluder, ...], image_size: tuple[int, int]) -> None:
        """Rebuild the occluder list when occluders were added, deleted or toggled elsewhere."""
        with self._lock:
            self._show_occluders(occluders, image_size)

    def _show_occluders(self, occluders: tuple[Occluder, ...], image_size: tuple[int, int]) -> None:
        signature = (*((o.ident, o.enabled) for o in occluders), image_size)
        if signature == self._occluder_signature:
            self._sync_sliders(occluders)
            return
        self._occluder_signature = signature
        for handle in self._occluder_handles:
            handle.remove()
        self._occluder_handles = []
        self._box_sliders: dict[int, list[viser.GuiSliderHandle]] = {}
        width, height = image_size
        with self.occluder_folder:
            if not occluders:
                self._occluder_handles.append(self.server.gui.add_folder("(none yet)"))
            for occluder in occluders:
                folder = self.server.gui.add_folder(f"Occluder #{occluder.ident}")
                self._occluder_handles.append(folder)
                with folder:
                    enabled = self.server.gui.add_checkbox("On", occluder.enabled)
                    enabled.on_update(self._toggle_callback(occluder.ident, enabled))
                    sliders = []
                    for k, label in enumerate(("x0", "y0", "x1", "y1")):
                        limit = width if k % 2 == 0 else height
                        sliders.append(
                            self.server.gui.add_slider(
                                label, 0.0, float(limit), 1.0, float(occluder.box[k])
                            )
                        )
                    for slider in sliders:
                        slider.on_update(self._move_callback(occluder.ident, sliders))
                    self._box_sliders[occluder.ident] = sliders
                    delete = self.server.gui.add_button(
                        "Delete", color="red", icon=viser.Icon.TRASH
                    )
                    delete.on_click(self._delete_callback(occluder.ident))

    def _sync_sliders(self, occluders: tuple[Occluder, ...]) -> None:
        for occluder in occluders:
            for slider, value in zip(
                self._box_sliders.get(occluder.ident, []), occluder.box, strict=False
            ):
                if abs(slider.value - value) > 0.5:
                    slider.value = round(value)

    def _toggle_callback(self, ident: int, checkbox: viser.GuiCheckboxHandle):
        def callback(_event) -> None:
            self.app.occluders_changed(self.app.state.set_occluder_enabled(ident, checkbox.value))

        return callback

    def _move_callback(self, ident: int, sliders: list[viser.GuiSliderHandle]):
        def callback(_event) -> None:
            box = tuple(float(s.value) for s in sliders)
            self.app.occluders_changed(self.app.state.move_occluder(ident, box))

        return callback

    def _delete_callback(self, ident: int):
        def callback(_event) -> None:
            self.app.occluders_changed(self.app.state.delete_occluder(ident))

        return callback

    def show_teaching(
        self,
        joint: str,
        concentrations: np.ndarray,
        factor: float,
        prior_concentrations: np.ndarray | torch.Tensor | None = None,
    ) -> None:
        """Numbers for the selected joint's principal axes (and the network's own, when the
        distribution is conditioned on the keypoints, so a class sees what the evidence adds).
        """
        names = ("red", "green", "blue")
        title = f"**{joint.replace('_', ' ')}** (factor {factor:.2g}×): concentration "
        title += "s&#x2C7C; + s&#x2096; about each principal axis"
        if prior_concentrations is None:
            rows = "\n".join(
                f"| {name} | {value:,.1f} |"
                for name, value in zip(names, concentrations, strict=True)
            )
            table = f"| axis | concentration |\n|---|---|\n{rows}"
        else:
            prior = sorted(np.asarray(prior_concentrations, dtype=float).tolist())
            rows = "\n".join(
                f"| {name} | {value:,.1f} | {base:,.1f} |"
                for name, value, base in zip(names, concentrations, prior, strict=True)
            )
            table = f"| axis | with evidence | network (sorted) |\n|---|---|---|\n{rows}"
        self.axes_text.content = f"{title}\n\n{table}"

    def show_proxy(self, proxy: torch.Tensor | None) -> None:
        """The proxy representation the network saw: the edge image and the heatmaps."""
        if proxy is None:
            self.proxy_edges.visible = False
            self.proxy_heat.visible = False
            return
        array = proxy.detach().float().cpu().numpy()
        edges = (np.clip(array[0], 0, 1) * 255).astype(np.uint8)
        self.proxy_edges.image = np.repeat(edges[:, :, None], 3, axis=2)
        heat = np.clip(array[1:].max(axis=0), 0, 1)
        colour = np.stack([heat * 255, heat * 170, 40 + heat * 0], axis=-1)
        background = np.repeat(edges[:, :, None] * 0.35, 3, axis=2)
        self.proxy_heat.image = np.clip(np.maximum(colour, background), 0, 255).astype(np.uint8)
        self.proxy_edges.visible = True
        self.proxy_heat.visible = True

    def show_status(self, text: str) -> None:
        self.status.content = text


def source_text(posterior) -> str:
    """The status line for a posterior: which distribution is shown, why when the evidence fit
    fell back, and whether the network read a copy of the crop turned upright or mirrored."""
    reason = getattr(posterior, "fallback_reason", None)
    if reason:
        text = f"Network only: {reason}."
    elif getattr(posterior, "conditioned", False):
        fit = posterior.evidence_fit
        text = f"Conditioned on {fit.evidence_count} keypoints (fit {fit.seconds * 1000:.0f} ms)."
    else:
        text = "Network only."
    tilt = getattr(posterior, "upright_tilt_degrees", None)
    if tilt is not None:
        text += f" The person leans {abs(tilt):.0f}°: read from a copy turned upright."
    if getattr(posterior, "mirror_read", False):
        text += " Read from the mirror image (its body fits the keypoints better)."
    return f"*{text}*"
