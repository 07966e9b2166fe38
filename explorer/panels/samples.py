"""The distribution tab's "Samples" folder: how many samples and meshes, the seed, what is
drawn, and how the uncertainty body is coloured (absolute on a log or linear scale, or the
change against the same photo without occluders)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

from hkpd.explorer.colour_map import COLOURINGS, DEFAULT_MAX_CM, HeatmapScale
from hkpd.explorer.panels.actions import StateActions
from hkpd.explorer.state import MAX_DISPLAYED_SAMPLES, MAX_SAMPLES

DEFAULT_FIT_OPACITY = 0.55


class SamplesActions(StateActions, Protocol):
    """What the samples section asks of the app."""

    def show_fit(self, visible: bool, opacity: float) -> None:
        """Show (or hide) the mode over the photo at ``opacity``."""
        ...

    def set_display_options(
        self,
        samples: bool,
        heatmap: bool,
        reprojection: bool,
        heatmap_max_cm: float,
        colouring: str = "log",
    ) -> bool:
        """Which parts are drawn, the colouring (a key of :data:`COLOURINGS`) and the linear
        scale's top; True if the colour scale changed."""
        ...


@dataclass(frozen=True)
class SamplesSection:
    """Handles of the samples and display controls.

    Attributes:
        num_samples: samples for the heatmap.
        num_displayed: sample meshes shown.
        seed: the draw's seed.
        resample: "Resample" (moves the seed on).
        show_samples, show_heatmap, show_reprojection, show_fit: display switches.
        fit_opacity: opacity of the fit over the photo.
        colouring: how the uncertainty body is coloured (labels of :data:`COLOURINGS`).
        heat_max: top of the linear colour scale, centimetres.
        legend: the colour bar.
    """

    num_samples: viser.GuiSliderHandle
    num_displayed: viser.GuiSliderHandle
    seed: viser.GuiNumberHandle
    resample: viser.GuiButtonHandle
    show_samples: viser.GuiCheckboxHandle
    show_heatmap: viser.GuiCheckboxHandle
    show_reprojection: viser.GuiCheckboxHandle
    show_fit: viser.GuiCheckboxHandle
    fit_opacity: viser.GuiSliderHandle
    colouring: viser.GuiDropdownHandle[str]
    heat_max: viser.GuiSliderHandle
    legend: viser.GuiImageHandle

    @property
    def scale(self) -> HeatmapScale:
        """The colouring chosen in the panel."""
        kind = next(k for k, label in COLOURINGS.items() if label == self.colouring.value)
        return HeatmapScale(kind, float(self.heat_max.value))


def build_samples_section(gui: viser.GuiApi, actions: SamplesActions) -> SamplesSection:
    """The "Samples" folder, wired to ``actions``."""
    state = actions.state
    with gui.add_folder("Samples"):
        num_samples = gui.add_slider(
            "Samples for heatmap", min(10, state.num_samples), MAX_SAMPLES, 1, state.num_samples
        )
        num_displayed = gui.add_slider(
            "Sample meshes shown", 0, MAX_DISPLAYED_SAMPLES, 1, state.num_displayed
        )
        seed = gui.add_number("Seed", state.seed, min=0, step=1)
        resample = gui.add_button("Resample", icon=viser.Icon.DICE)
        switches = [
            gui.add_checkbox(label, True)
            for label in ("Show sample meshes", "Show uncertainty body", "Show 2D reprojection")
        ]
        show_fit = gui.add_checkbox(
            "Show the fit on the photo",
            True,
            hint="The most likely body drawn over the person with the predicted camera",
        )
        fit_opacity = gui.add_slider("Fit opacity", 0.0, 1.0, 0.05, DEFAULT_FIT_OPACITY)
        colouring = gui.add_dropdown(
            "Colouring",
            tuple(COLOURINGS.values()),
            initial_value=COLOURINGS["log"],
            hint="Change: each vertex's uncertainty divided by its uncertainty on the same "
            "photo without occluders and with default concentrations (red: more uncertain)",
        )
        heat_max = gui.add_slider(
            "Linear scale top (cm)", 2.0, 40.0, 1.0, DEFAULT_MAX_CM, visible=False
        )
        legend = gui.add_image(HeatmapScale().legend(), label="Colour bar")
    section = SamplesSection(
        num_samples, num_displayed, seed, resample, *switches, show_fit, fit_opacity, colouring,
        heat_max, legend,
    )  # fmt: skip
    _wire(section, actions)
    return section


def _wire(section: SamplesSection, actions: SamplesActions) -> None:
    """Connect the section's controls to ``actions``."""
    state = actions.state
    section.num_samples.on_update(
        lambda _: actions.sampling_changed(state.set_num_samples(section.num_samples.value))
    )
    section.num_displayed.on_update(
        lambda _: actions.sampling_changed(state.set_num_displayed(section.num_displayed.value))
    )
    section.seed.on_update(lambda _: actions.sampling_changed(state.set_seed(section.seed.value)))
    section.resample.on_click(lambda _: _resample(section, actions))
    for control in (section.show_fit, section.fit_opacity):
        control.on_update(
            lambda _: actions.show_fit(section.show_fit.value, section.fit_opacity.value)
        )
    for control in (
        section.show_samples, section.show_heatmap, section.show_reprojection, section.colouring,
        section.heat_max,
    ):  # fmt: skip
        control.on_update(lambda _: _display_options(section, actions))


def _resample(section: SamplesSection, actions: SamplesActions) -> None:
    section.seed.value = actions.state.next_seed()
    actions.sampling_changed(True)


def _display_options(section: SamplesSection, actions: SamplesActions) -> None:
    scale = section.scale
    section.heat_max.visible = scale.kind == "linear"
    rescaled = actions.set_display_options(
        section.show_samples.value, section.show_heatmap.value, section.show_reprojection.value,
        scale.max_cm, scale.kind,
    )  # fmt: skip
    if rescaled:
        section.legend.image = scale.legend()
