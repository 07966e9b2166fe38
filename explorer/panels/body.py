"""The photo tab's "Body" folder: the drawn body's sex with its probability and a menu to state
it, its six measurements with ± beside fields to state them, and how the body looks.

On the shipped model the sex read from keypoints is close to a coin flip, so the folder says
plainly when it is not sure and asks for the sex. The menu applies at once; the fields apply
with *Use these values* (typing a number never predicts half of it), *Clear stated values*
forgets them. Bad input leaves everything as it was (the fields keep the text, to be fixed)
and says what is wrong. What is stated belongs to the person on the photo: a new photo starts
with nothing stated (as it starts without occluders).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import viser

from hkpd.explorer.body_settings import (
    FIELD_UNITS,
    LABELS,
    NOTHING_STATED,
    BodyStatement,
    entry_text,
    parse_fields,
)
from hkpd.explorer.body_text import measurement_markdown, measurements_of, sex_markdown
from hkpd.explorer.panels.actions import StateActions

SEX_CHOICES: dict[str | None, str] = {
    None: "Automatic (from the photo)",
    "female": "Female",
    "male": "Male",
}
"""The sex menu: stated sex (None: let the photo decide) -> its label."""

LOOKS: dict[str, str] = {"clay": "Clay (a mannequin)", "skin": "Skin tone"}
"""How the most likely body is drawn: look -> its label (colours in the scene)."""

MAIN_FIELDS = ("height_m", "mass_kg")
"""The fields shown at once; the other measurements are in a collapsed folder."""

STATED_RULE = (
    "*Stated values condition the body (with Condition on 2D keypoints on). They belong to "
    "the person on this photo: a new photo starts with nothing stated.*"
)


class BodyActions(StateActions, Protocol):
    """What the Body section asks of the app."""

    def body_changed(self, changed: bool) -> None:
        """The stated sex or measurements changed: predict again when ``changed``."""
        ...

    def set_look(self, look: str) -> None:
        """Draw the most likely body in ``look`` (a key of :data:`LOOKS`)."""
        ...


@dataclass
class BodySection:
    """Handles of the Body folder.

    Attributes:
        sex_text: the drawn body's sex with its probability (or why there is none).
        sex: the sex menu (labels of :data:`SEX_CHOICES`).
        measurements: the measurements table (mean ± std beside what was stated).
        fields: one text field per measurement name (cm, kg; empty: not stated).
        apply: "Use these values".
        clear: "Clear stated values".
        message: what was wrong with the last entry ("" when nothing).
        look: how the most likely body is drawn (labels of :data:`LOOKS`).
    """

    sex_text: viser.GuiMarkdownHandle
    sex: viser.GuiDropdownHandle[str]
    measurements: viser.GuiMarkdownHandle
    fields: dict[str, viser.GuiTextHandle]
    apply: viser.GuiButtonHandle
    clear: viser.GuiButtonHandle
    message: viser.GuiMarkdownHandle
    look: viser.GuiDropdownHandle[str]
    shown: list[BodyStatement] = field(default_factory=lambda: [NOTHING_STATED])
    """The statement the controls last showed (a field is rewritten only when it changes)."""

    @property
    def chosen_sex(self) -> str | None:
        """The sex the menu states (None: automatic)."""
        return next(sex for sex, label in SEX_CHOICES.items() if label == self.sex.value)

    @property
    def chosen_look(self) -> str:
        """The look the menu picks (a key of :data:`LOOKS`)."""
        return next(look for look, label in LOOKS.items() if label == self.look.value)

    def texts(self) -> dict[str, str]:
        """What each measurement field holds."""
        return {name: handle.value for name, handle in self.fields.items()}

    def show(
        self, posterior: object | None, stated: BodyStatement, evidence: bool, can_state: bool
    ) -> None:
        """The drawn body of ``posterior`` (None: nobody found) and the ``stated`` values;
        ``can_state``: the provider takes stated values (else the controls are disabled)."""
        self.sex_text.content = sex_markdown(posterior, evidence, can_state)
        measurements = None if posterior is None else measurements_of(posterior)
        self.measurements.content = measurement_markdown(measurements, stated)
        for control in (self.sex, self.apply, self.clear, *self.fields.values()):
            control.disabled = not can_state
        self.show_stated(stated)

    def show_stated(self, stated: BodyStatement, force: bool = False) -> None:
        """Set the menu and the fields to ``stated`` when it differs from what they last
        showed, or when ``force`` (so that a prediction finishing never overwrites a field
        being typed in)."""
        if stated == self.shown[0] and not force:
            return
        self.shown[0] = stated
        self.sex.value = SEX_CHOICES[stated.sex]
        values = stated.values()
        for name, handle in self.fields.items():
            handle.value = entry_text(name, *values[name]) if name in values else ""


def build_body_section(gui: viser.GuiApi, actions: BodyActions) -> BodySection:
    """The "Body" folder, wired to ``actions``."""
    with gui.add_folder("Body"):
        sex_text = gui.add_markdown("**Sex:** no person yet.")
        sex = gui.add_dropdown(
            "Sex",
            tuple(SEX_CHOICES.values()),
            initial_value=SEX_CHOICES[None],
            hint="Automatic: the photo decides (weakly); Female / Male: draw that sex's body",
        )
        measurements = gui.add_markdown("")
        fields = {name: _field(gui, name) for name in MAIN_FIELDS}
        with gui.add_folder("More measurements", expand_by_default=False):
            for name in LABELS:
                if name not in MAIN_FIELDS:
                    fields[name] = _field(gui, name)
        apply = gui.add_button("Use these values", icon=viser.Icon.CHECK)
        clear = gui.add_button("Clear stated values", icon=viser.Icon.ERASER)
        message = gui.add_markdown("")
        gui.add_markdown(STATED_RULE)
        look = gui.add_dropdown(
            "Look",
            tuple(LOOKS.values()),
            initial_value=LOOKS["clay"],
            hint="How the most likely body is drawn (the samples and the heat map keep "
            "their colours)",
        )
    section = BodySection(sex_text, sex, measurements, fields, apply, clear, message, look)
    _wire(section, actions)
    return section


def _field(gui: viser.GuiApi, name: str) -> viser.GuiTextHandle:
    unit = FIELD_UNITS[name][0]
    return gui.add_text(
        f"{LABELS[name]} ({unit})",
        "",
        hint=f"Empty: from the photo. A number in {unit}, optionally ± its std "
        "(e.g. 175 or 175 ± 2; metres read as metres: 1.75 or 1.75 m); then Use these values",
    )


def _wire(section: BodySection, actions: BodyActions) -> None:
    """Connect the section's controls to ``actions``."""
    section.sex.on_update(lambda _: _state_sex(section, actions))
    section.apply.on_click(lambda _: _state_fields(section, actions))
    section.clear.on_click(lambda _: _clear(section, actions))
    section.look.on_update(lambda _: actions.set_look(section.chosen_look))


def _state_sex(section: BodySection, actions: BodyActions) -> None:
    """The menu applies at once, with the measurements stated so far."""
    stated = actions.state.stated.with_sex(section.chosen_sex)
    section.shown[0] = stated
    actions.body_changed(actions.state.set_stated(stated))


def _state_fields(section: BodySection, actions: BodyActions) -> None:
    """State what the fields hold (with the menu's sex); bad input changes nothing."""
    try:
        stated = parse_fields(section.chosen_sex, section.texts())
    except ValueError as error:
        lines = str(error).splitlines()
        section.message.content = "**Not stated** (nothing changed): " + " ".join(
            f"{line}." for line in lines
        )
        return
    section.message.content = (
        f"Stated: {stated.summary()}." if not stated.empty else "Nothing stated."
    )
    section.shown[0] = stated
    actions.body_changed(actions.state.set_stated(stated))


def _clear(section: BodySection, actions: BodyActions) -> None:
    """Forget every stated value: the photo decides again."""
    section.message.content = ""
    changed = actions.state.set_stated(NOTHING_STATED)
    section.show_stated(NOTHING_STATED, force=True)
    actions.body_changed(changed)
