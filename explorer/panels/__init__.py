"""The explorer's GUI panel (viser's global GUI: every tab sees and drives the same controls).

One builder per section: each section module has a ``build_*_section(gui, actions)`` that lays
out its folder, wires its callbacks to a small *actions* protocol (what the callbacks may ask
of the app) and returns a dataclass of the handles the app updates later (viser's own
examples do the same). :func:`build_panels` is the one place where sections are registered: it
puts the status lines on top and the sections into tabs.

Callbacks only change the state and ask the app for work; nothing heavy runs in them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

from hkpd.explorer.panels.body import BodyActions, BodySection, build_body_section
from hkpd.explorer.panels.compare import CompareActions, CompareSection, build_compare_section
from hkpd.explorer.panels.concentration import ConcentrationSection, build_concentration_section
from hkpd.explorer.panels.export import ExportActions, ExportSection, build_export_section
from hkpd.explorer.panels.keep import KeepActions, KeepSection, build_keep_section
from hkpd.explorer.panels.landmarks import LandmarkActions, build_landmark_section
from hkpd.explorer.panels.photo import PhotoActions, PhotoSection, build_photo_section
from hkpd.explorer.panels.same_person import (
    SamePersonActions,
    SamePersonSection,
    build_same_person_section,
)
from hkpd.explorer.panels.samples import SamplesActions, SamplesSection, build_samples_section
from hkpd.explorer.panels.second_reader import SecondReaderActions, build_second_reader_section
from hkpd.explorer.panels.status import StatusSection, build_status_section
from hkpd.explorer.panels.teaching import TeachingSection, build_teaching_section
from hkpd.explorer.panels.turn import TurnActions, TurnSection, build_turn_section


class PanelActions(
    PhotoActions,
    SamePersonActions,
    SamplesActions,
    ExportActions,
    KeepActions,
    CompareActions,
    BodyActions,
    LandmarkActions,
    SecondReaderActions,
    TurnActions,
    Protocol,
):
    """Everything the panel may ask of the app (``ExplorerApp`` implements it): the union of
    the sections' actions. Change the state, then say what became stale; nothing else of the
    app is reachable from a callback."""


@dataclass(frozen=True)
class ExplorerPanels:
    """The handles of every section, for the app to show results in."""

    status: StatusSection
    photo: PhotoSection
    same_person: SamePersonSection
    concentration: ConcentrationSection
    samples: SamplesSection
    export: ExportSection
    teaching: TeachingSection
    keep: KeepSection
    compare: CompareSection
    body: BodySection
    turn: TurnSection


def build_panels(server: viser.ViserServer, actions: PanelActions) -> ExplorerPanels:
    """Build the whole panel: the status lines, then a tab per task ("Photo": what goes in,
    "Distribution": what comes out and how it is drawn, "Teaching": what it means).

    A new section: a module with its builder, handles and actions; one line here, one field in
    :class:`ExplorerPanels`, its actions among the bases of :class:`PanelActions`.
    """
    gui = server.gui
    gui.configure_theme(control_width="large", show_logo=False, show_share_button=False)
    status = build_status_section(gui)
    tabs = gui.add_tab_group()
    with tabs.add_tab("Photo", viser.Icon.PHOTO):
        photo = build_photo_section(gui, actions)
        build_landmark_section(gui, actions)  # only calls actions.show_landmarks
        build_second_reader_section(gui, actions)  # only calls actions.show_second_reader
        turn = build_turn_section(gui, actions)
        body = build_body_section(gui, actions)
        same_person = build_same_person_section(gui, actions)
        keep = build_keep_section(gui, actions)  # last: "Load a photo" stays the first upload
    with tabs.add_tab("Distribution", viser.Icon.ADJUSTMENTS):
        concentration = build_concentration_section(gui, actions)
        samples = build_samples_section(gui, actions)
        compare = build_compare_section(gui, actions)
        export = build_export_section(gui, actions)
    with tabs.add_tab("Teaching", viser.Icon.SCHOOL):
        teaching = build_teaching_section(gui, actions)
    return ExplorerPanels(
        status, photo, same_person, concentration, samples, export, teaching, keep, compare,
        body, turn,
    )  # fmt: skip


__all__ = ["ExplorerPanels", "PanelActions", "build_panels"]
