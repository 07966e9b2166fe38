"""The distribution tab's "Concentration" folder: log-scale factors on every joint's
concentration (one slider per joint, grouped by limb), on all joints, and on the shape spread."""

from __future__ import annotations

from dataclasses import dataclass

import viser

from hkpd.explorer.panels.actions import StateActions
from hkpd.explorer.state import CONCENTRATION_EXPONENT_RANGE, LIMB_GROUPS

EXPONENT_MARKS = ((-1.0, "0.1×"), (0.0, "1×"), (1.0, "10×"))
EXPONENT_STEP = 0.05
"""Slider step on log10 of a factor."""


@dataclass(frozen=True)
class ConcentrationSection:
    """Handles of the concentration sliders (values: log10 of the factor, 0 = 1x).

    Attributes:
        global_slider: "All joints (log10)".
        shape_slider: "Shape spread (log10)".
        joint_sliders: one slider per body joint, by joint name.
        reset_button: "Reset concentrations".
    """

    global_slider: viser.GuiSliderHandle
    shape_slider: viser.GuiSliderHandle
    joint_sliders: dict[str, viser.GuiSliderHandle]
    reset_button: viser.GuiButtonHandle

    def reset(self) -> None:
        """Every slider back to 1x (their callbacks find the state already reset)."""
        for slider in (self.global_slider, self.shape_slider, *self.joint_sliders.values()):
            slider.value = 0.0


def build_concentration_section(gui: viser.GuiApi, actions: StateActions) -> ConcentrationSection:
    """The "Concentration" folder, wired to ``actions``."""
    state = actions.state
    with gui.add_folder("Concentration"):
        global_slider = _exponent_slider(gui, "All joints (log10)")
        shape_slider = _exponent_slider(gui, "Shape spread (log10)")
        joint_sliders: dict[str, viser.GuiSliderHandle] = {}
        for group, joints in LIMB_GROUPS.items():
            with gui.add_folder(group, expand_by_default=False):
                for joint in joints:
                    joint_sliders[joint] = _exponent_slider(gui, joint.replace("_", " "))
        reset = gui.add_button("Reset concentrations", icon=viser.Icon.REFRESH)
    section = ConcentrationSection(global_slider, shape_slider, joint_sliders, reset)
    global_slider.on_update(
        lambda _: actions.sampling_changed(state.set_global_exponent(global_slider.value))
    )
    shape_slider.on_update(
        lambda _: actions.sampling_changed(state.set_shape_std_exponent(shape_slider.value))
    )
    for joint, slider in joint_sliders.items():
        slider.on_update(_joint_callback(actions, joint, slider))
    reset.on_click(lambda _: _reset(section, actions))
    return section


def _exponent_slider(gui: viser.GuiApi, label: str) -> viser.GuiSliderHandle:
    low, high = CONCENTRATION_EXPONENT_RANGE
    return gui.add_slider(label, low, high, EXPONENT_STEP, 0.0, marks=EXPONENT_MARKS)


def _joint_callback(actions: StateActions, joint: str, slider: viser.GuiSliderHandle):
    def callback(_event: viser.GuiEvent) -> None:
        actions.sampling_changed(actions.state.set_joint_exponent(joint, slider.value))

    return callback


def _reset(section: ConcentrationSection, actions: StateActions) -> None:
    changed = actions.state.reset_concentrations()
    section.reset()
    actions.sampling_changed(changed)
