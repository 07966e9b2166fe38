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
EXPONENT_HINT = (
    "The slider moves log10 of the factor (-1 = 0.1×, 0 = 1×, 1 = 10×); the label shows the "
    "factor. Each joint's factor multiplies the All-joints one."
)


@dataclass(frozen=True)
class ConcentrationSection:
    """Handles of the concentration sliders (values: log10 of the factor, 0 = 1x; labels: the
    name and the factor, "left elbow · 0.5×").

    Attributes:
        global_slider: "All joints · 1×".
        shape_slider: "Shape spread · 1×".
        joint_sliders: one slider per body joint, by joint name.
        reset_button: "Reset concentrations".
    """

    global_slider: viser.GuiSliderHandle
    shape_slider: viser.GuiSliderHandle
    joint_sliders: dict[str, viser.GuiSliderHandle]
    reset_button: viser.GuiButtonHandle

    def reset(self) -> None:
        """Every slider back to 1x (their callbacks find the state already reset)."""
        named = {GLOBAL_NAME: self.global_slider, SHAPE_NAME: self.shape_slider}
        named |= {joint.replace("_", " "): s for joint, s in self.joint_sliders.items()}
        for name, slider in named.items():
            slider.value = 0.0
            _show_factor(slider, name)


def build_concentration_section(gui: viser.GuiApi, actions: StateActions) -> ConcentrationSection:
    """The "Concentration" folder, wired to ``actions``."""
    state = actions.state
    with gui.add_folder("Concentration"):
        global_slider = _exponent_slider(gui, GLOBAL_NAME)
        shape_slider = _exponent_slider(gui, SHAPE_NAME)
        joint_sliders: dict[str, viser.GuiSliderHandle] = {}
        for group, joints in LIMB_GROUPS.items():
            with gui.add_folder(group, expand_by_default=False):
                for joint in joints:
                    joint_sliders[joint] = _exponent_slider(gui, joint.replace("_", " "))
        reset = gui.add_button("Reset concentrations", icon=viser.Icon.REFRESH)
    section = ConcentrationSection(global_slider, shape_slider, joint_sliders, reset)
    global_slider.on_update(
        lambda _: actions.sampling_changed(
            state.set_global_exponent(_show_factor(global_slider, GLOBAL_NAME).value)
        )
    )
    shape_slider.on_update(
        lambda _: actions.sampling_changed(
            state.set_shape_std_exponent(_show_factor(shape_slider, SHAPE_NAME).value)
        )
    )
    for joint, slider in joint_sliders.items():
        slider.on_update(_joint_callback(actions, joint, slider))
    reset.on_click(lambda _: _reset(section, actions))
    return section


GLOBAL_NAME, SHAPE_NAME = "All joints", "Shape spread"


def _exponent_slider(gui: viser.GuiApi, name: str) -> viser.GuiSliderHandle:
    low, high = CONCENTRATION_EXPONENT_RANGE
    slider = gui.add_slider(
        factor_label(name, 0.0), low, high, EXPONENT_STEP, 0.0, marks=EXPONENT_MARKS,
        hint=EXPONENT_HINT,
    )  # fmt: skip
    return slider


def factor_label(name: str, exponent: float) -> str:
    """A slider's label: its name and the factor ``10 ** exponent`` ("left elbow · 0.5×")."""
    factor = 10.0 ** float(exponent)
    text = f"{factor:.2g}" if factor < 10 else f"{factor:.0f}"
    return f"{name} · {text}×"


def _show_factor(slider: viser.GuiSliderHandle, name: str) -> viser.GuiSliderHandle:
    """Relabel ``slider`` (named ``name``) with the factor its value stands for; returns it."""
    slider.label = factor_label(name, slider.value)
    return slider


def _joint_callback(actions: StateActions, joint: str, slider: viser.GuiSliderHandle):
    def callback(_event: viser.GuiEvent) -> None:
        _show_factor(slider, joint.replace("_", " "))
        actions.sampling_changed(actions.state.set_joint_exponent(joint, slider.value))

    return callback


def _reset(section: ConcentrationSection, actions: StateActions) -> None:
    changed = actions.state.reset_concentrations()
    section.reset()
    actions.sampling_changed(changed)
