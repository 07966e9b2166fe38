"""The photo tab's main section: load a photo, evidence on/off (keypoints, person mask), choose
the person, draw and list occluders."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import viser

from hkpd.explorer.panels.occluder_list import OccluderActions, OccluderList

NO_PERSON_CHOICE = "(one person)"
PICKED_CHOICE = "Your box (picked on the photo)"
"""The Person menu's entry while the person box is one the user dragged, not a listed person."""


class PhotoActions(OccluderActions, Protocol):
    """What the photo section asks of the app."""

    def load_upload(self, name: str, content: bytes, client: viser.ClientHandle | None) -> None:
        """Check an uploaded photo and predict on it."""
        ...

    def set_evidence(self, enabled: bool) -> None:
        """Condition on the 2D keypoints, or show the network alone."""
        ...

    def set_silhouette(self, enabled: bool) -> None:
        """Fit the person mask as well as the keypoints, or the keypoints alone."""
        ...

    def pick_person_next(self, enabled: bool = True) -> None:
        """The next box dragged on the photo picks the person."""
        ...

    def set_person_box(self, box: tuple[float, float, float, float] | None) -> bool:
        """Look for the person only inside ``box`` (None: anywhere)."""
        ...

    def select_person(self, index: int) -> bool:
        """Predict for the ``index``-th person found in the photo."""
        ...

    def set_plain_drag_draws(self, enabled: bool) -> None:
        """Also draw occluders with a plain left drag."""
        ...

    def clear_occluders(self) -> None:
        """Remove every occluder."""
        ...


def person_choice(index: int, count: int, place: str = "") -> str:
    """The dropdown label of person ``index`` (0-based) of ``count``, with where they are
    (``place``, e.g. "left, small": :func:`hkpd.explorer.people_menu.person_places`)."""
    return f"Person {index + 1} of {count}" + (f" — {place}" if place else "")


@dataclass
class PhotoSection:
    """Handles of the "Photo and occluders" folder.

    Attributes:
        upload: "Load a photo".
        evidence: "Condition on 2D keypoints".
        silhouette: "Fit the person mask" (hidden when the provider cannot; disabled while the
            keypoints are off).
        pick: "Pick the person" (the next drag picks the person).
        forget: "Forget the person box".
        people: the person menu (hidden unless the photo shows several people).
        draw_mode: "Plain drag draws".
        clear: "Remove all occluders".
        occluders: the list of occluders.
    """

    upload: viser.GuiUploadButtonHandle
    evidence: viser.GuiCheckboxHandle
    silhouette: viser.GuiCheckboxHandle
    pick: viser.GuiButtonHandle
    forget: viser.GuiButtonHandle
    people: viser.GuiDropdownHandle[str]
    draw_mode: viser.GuiCheckboxHandle
    clear: viser.GuiButtonHandle
    occluders: OccluderList
    _offering: bool = field(default=False, repr=False)
    """True while :meth:`show_people` sets the menu (that is not the user's choice)."""
    _offered: str = field(default=NO_PERSON_CHOICE, repr=False)
    """The entry :meth:`show_people` last set: what the menu goes back to when a value arrives
    that the menu does not offer (a browser's late echo of an older menu)."""

    def show_people(self, count: int, choice: int | None = 0, places: tuple[str, ...] = ()) -> None:
        """Offer a choice of person when the photo shows several (hidden otherwise).

        Args:
            count: the people listed.
            choice: the 0-based person whose body is shown, or None while the person box is
                one the user picked (the menu then says :data:`PICKED_CHOICE`, and is shown
                when at least one person is listed, to go back to them).
            places: where each person is, in words (none: the entries say only "Person k").
        """
        places = places or ("",) * count
        choices = tuple(person_choice(i, count, places[i]) for i in range(count))
        if choice is None:
            choices += (PICKED_CHOICE,)
            value = PICKED_CHOICE
        elif count >= 2 and 0 <= choice < count:
            value = choices[choice]
        else:  # one person or none, shown as found: the (hidden) menu offers just that
            choices, value = (NO_PERSON_CHOICE,), NO_PERSON_CHOICE
        self._offer(choices, value)
        self.people.visible = count >= 2 or (choice is None and count >= 1)

    def _offer(self, choices: tuple[str, ...], value: str) -> None:
        """Set the menu's entries and its value (always one of them), as the app's doing."""
        self._offering = True
        try:
            self.people.options = choices
            self.people.value = self._offered = value
        finally:
            self._offering = False

    def restore_if_not_offered(self) -> bool:
        """Put the menu back to what :meth:`show_people` last set when its value is not one
        of its entries (a late echo from a browser of an older menu); True when it did."""
        if self._offering or self.people.value in self.people.options:
            return False
        self._offer(tuple(self.people.options), self._offered)
        return True

    def chosen_person(self) -> int | None:
        """The 0-based person the user chose in the menu, or None (no choice, or the app set
        the menu)."""
        if self._offering or self.people.value in (NO_PERSON_CHOICE, PICKED_CHOICE):
            return None
        return int(self.people.value.split()[1]) - 1


def build_photo_section(gui: viser.GuiApi, actions: PhotoActions) -> PhotoSection:
    """The "Photo and occluders" folder, wired to ``actions``."""
    with gui.add_folder("Photo and occluders"):
        upload = gui.add_upload_button(
            "Load a photo",
            icon=viser.Icon.UPLOAD,
            mime_type="image/*",
            hint="JPEG/PNG/WebP/BMP/TIFF up to 25 MiB",
        )
        evidence = gui.add_checkbox(
            "Condition on 2D keypoints",
            actions.state.evidence,
            hint="On: the network's distribution updated by the detected keypoints (default). "
            "Off: the network alone (the paper's method).",
        )
        silhouette = gui.add_checkbox(
            "Fit the person mask",
            actions.state.silhouette,
            disabled=not actions.state.evidence,
            hint="Also fit the body's outline to BlazePose's person mask (the Teaching tab "
            "shows the mask). Best for one person in close-fitting clothes; loose clothes, hair "
            "or a second person in the mask make the body wider. About 0.3 s more per update.",
        )
        pick = gui.add_button(
            "Pick the person",
            icon=viser.Icon.USER,
            hint="Then drag a box around the person on the photo (Shift + drag)",
        )
        forget = gui.add_button("Forget the person box", icon=viser.Icon.X)
        people = gui.add_dropdown(
            "Person",
            (NO_PERSON_CHOICE,),
            visible=False,
            hint="The people found in the photo: choose whose body to estimate (a box you "
            "pick with 'Pick the person' is listed as 'Your box')",
        )
        gui.add_markdown("*Shift + drag on the photo draws an occluder.*")
        draw_mode = gui.add_checkbox(
            "Plain drag draws",
            False,
            hint="Draw occluders without holding Shift (the view stops orbiting)",
        )
        clear = gui.add_button("Remove all occluders", icon=viser.Icon.TRASH)
        folder = gui.add_folder("Occluders", expand_by_default=True)
    occluders = OccluderList(gui, folder, actions)
    section = PhotoSection(
        upload, evidence, silhouette, pick, forget, people, draw_mode, clear, occluders
    )
    upload.on_upload(
        lambda event: actions.load_upload(upload.value.name, upload.value.content, event.client)
    )
    evidence.on_update(lambda _: actions.set_evidence(evidence.value))
    silhouette.on_update(lambda _: actions.set_silhouette(silhouette.value))
    pick.on_click(lambda _: actions.pick_person_next(True))
    forget.on_click(lambda _: actions.set_person_box(None))
    people.on_update(lambda _: _select_chosen_person(section, actions))
    draw_mode.on_update(lambda _: actions.set_plain_drag_draws(draw_mode.value))
    clear.on_click(lambda _: actions.clear_occluders())
    return section


def _select_chosen_person(section: PhotoSection, actions: PhotoActions) -> None:
    if section.restore_if_not_offered():
        return
    index = section.chosen_person()
    if index is not None:
        actions.select_person(index)
