"""The distribution tab's "Concentration" folder: factors on every joint's concentration (one
control per joint, grouped by limb), on all joints, and on the shape spread.

Each control is a :class:`~hkpd.explorer.panels.factor_control.FactorControl`: a number box
holding the factor (typing 2 means 2×) over a log10 track (0.1× .. 10×)."""

from __future__ import annotations

from dataclasses import dataclass

import viser

from hkpd.explorer.panels.actions import StateActions
from hkpd.explorer.panels.factor_control import FactorControl
from hkpd.explorer.state import CONCENTRATION_EXPONENT_RANGE, LIMB_GROUPS

FACTOR_HINT = (
    "The box is the factor (2 = 2×, 0.5 = 0.5×, from 0.1 to 10); the track under it moves the "
    "same factor on a log scale. Each joint's factor multiplies the All-joints one."
)
GLOBAL_NAME, SHAPE_NAME = "All joints", "Shape spread"


@dataclass(frozen=True)
class ConcentrationSection:
    """Handles of the concentration controls (each a factor box over a log10 track).

    Attributes:
        global_factor: "All joints ×".
        shape_factor: "Shape spread ×".
        joints: one control per body joint, by joint name.
        reset_button: "Reset concentrations".
    """

    global_factor: FactorControl
    shape_factor: FactorControl
    joints: dict[str, FactorControl]
    reset_button: viser.GuiButtonHandle

    def reset(self) -> None:
        """Every control back to 1× (their callbacks find the state already reset)."""
        for control in (self.global_factor, self.shape_factor, *self.joints.values()):
            control.set_exponent(0.0)


def build_concentration_section(gui: viser.GuiApi, actions: StateActions) -> ConcentrationSection:
    """The "Concentration" folder, wired to ``actions``."""
    state = actions.state
    with gui.add_folder("Concentration"):
        global_factor = _control(gui, GLOBAL_NAME)
        shape_factor = _control(gui, SHAPE_NAME)
        joints: dict[str, FactorControl] = {}
        for group, names in LIMB_GROUPS.items():
            with gui.add_folder(group, expand_by_default=False):
                for joint in names:
                    joints[joint] = _control(gui, joint.replace("_", " "))
        reset = gui.add_button("Reset concentrations", icon=viser.Icon.REFRESH)
    section = ConcentrationSection(global_factor, shape_factor, joints, reset)
    global_factor.on_change(lambda e: actions.sampling_changed(state.set_global_exponent(e)))
    shape_factor.on_change(lambda e: actions.sampling_changed(state.set_shape_std_exponent(e)))
    for joint, control in joints.items():
        control.on_change(_joint_listener(actions, joint))
    reset.on_click(lambda _: _reset(section, actions))
    return section


def _control(gui: viser.GuiApi, name: str) -> FactorControl:
    return FactorControl(gui, name, CONCENTRATION_EXPONENT_RANGE, FACTOR_HINT)


def _joint_listener(actions: StateActions, joint: str):
    def listener(exponent: float) -> None:
        actions.sampling_changed(actions.state.set_joint_exponent(joint, exponent))

    return listener


def _reset(section: ConcentrationSection, actions: StateActions) -> None:
    changed = actions.state.reset_concentrations()
    section.reset()
    actions.sampling_changed(changed)
