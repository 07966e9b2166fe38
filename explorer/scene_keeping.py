"""Keeping scenes in the running explorer: the current scene as a :class:`SceneFile`, a scene
applied to the app (its controls are set, so every tab's panel shows it), the line that lists
what differs from the defaults, "Reset everything", and undo/redo of the last edits.

A scene is applied by setting the panel's controls: viser runs their callbacks, which change
the state and ask for new samples exactly as a user's clicks do (one path for both).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import replace
from typing import TYPE_CHECKING

from hkpd.explorer.body_settings import BodyStatement
from hkpd.explorer.colour_map import COLOURINGS
from hkpd.explorer.compare import parse_compare
from hkpd.explorer.panels.teaching import joint_label
from hkpd.explorer.scene_file import (
    DisplaySettings,
    OccluderEntry,
    PhotoRef,
    SceneFile,
)
from hkpd.kinematic_tree import BODY_JOINT_NAMES

if TYPE_CHECKING:
    from hkpd.explorer.app import ExplorerApp

HISTORY_LENGTH = 30
"""Edits kept for undo."""
EDIT_PAUSE_S = 1.0
"""Views closer together than this (a slider being dragged) are one edit for undo."""
SETTLE_S = 5.0
"""Longest time the edits an undo sets off are not recorded as new edits."""
DEFAULT_PHOTO = PhotoRef("the photo", demo="synthetic")
"""Stands in for the photo in scenes compared without it (history, differences)."""


class SceneKeeper:
    """The app's scene bookkeeping (see the module docstring).

    Attributes:
        photo: where the current photo comes from (None: only its pixels are known).
        model: the checkpoint path of the app's model (None: the shipped one).
        source: the scene file the app opened ("" when none), named in saved pages.
    """

    def __init__(self, app: ExplorerApp) -> None:
        self.app = app
        self.photo: PhotoRef | None = None
        self.model: str | None = None
        self.source = ""
        self._lock = threading.Lock()
        self._history: list[SceneFile] = []
        self._index = -1
        self._settling: tuple[SceneFile, float] | None = None
        self._recorded_at = -math.inf

    # ------------------------------------------------------------------ reading
    def settings(self) -> SceneFile:
        """The current scene without its photo (:data:`DEFAULT_PHOTO` stands in)."""
        app, snapshot = self.app, self.app.state.snapshot()
        panel = app.panels.samples
        global_factor = 10.0**snapshot.global_exponent
        joint_factors = {
            name: round(10.0**exponent, 9)
            for name, exponent in zip(BODY_JOINT_NAMES, snapshot.joint_exponents, strict=True)
            if exponent != 0.0
        }
        setting = app.compare.setting
        return SceneFile(
            photo=DEFAULT_PHOTO,
            person_box=snapshot.person_box,
            occluders=tuple(OccluderEntry(o.box, o.enabled) for o in snapshot.occluders),
            joint_factors=joint_factors,
            all_joints_factor=round(global_factor, 9),
            shape_spread_factor=round(snapshot.shape_std_factor, 9),
            evidence=snapshot.evidence,
            person_mask=snapshot.silhouette,
            display=DisplaySettings(
                colouring=panel.scale.kind,
                linear_top_cm=float(panel.heat_max.value),
                num_samples=snapshot.num_samples,
                num_displayed=snapshot.num_displayed,
                show_samples=bool(panel.show_samples.value),
                show_uncertainty_body=bool(panel.show_heatmap.value),
                show_reprojection=bool(panel.show_reprojection.value),
                show_fit=bool(panel.show_fit.value),
                fit_opacity=float(panel.fit_opacity.value),
                selected_joint=snapshot.selected_joint,
            ),
            seed=snapshot.seed,
            model=self.model,
            compare=None if setting is None else setting.text,
            sex=snapshot.stated.sex,
            measurements={name: [v, s] for name, (v, s) in snapshot.stated.values().items()},
            turned_around=snapshot.turned_around,
        )

    def scene(self) -> SceneFile:
        """The current scene with its photo (an uploaded photo is embedded).

        Raises:
            RuntimeError: the photo's source is unknown.
        """
        if self.photo is None:
            raise RuntimeError("this photo's file is unknown: load it from a file first")
        return self.settings().with_photo(self.photo)

    def differences(self) -> str:
        """What differs from the defaults, in words ("" when nothing does)."""
        return ", ".join(describe_differences(self.settings()))

    # ------------------------------------------------------------------ applying
    def apply(self, scene: SceneFile) -> None:
        """Set every control to ``scene``'s settings (its photo must be the app's already):
        one edit for undo (the views in between are not kept)."""
        with self._lock:
            target = replace(scene, photo=DEFAULT_PHOTO, model=self.model)
            self._settling, self._recorded_at = (target, time.monotonic()), -math.inf
        app = self.app
        photo, samples = app.panels.photo, app.panels.samples
        photo.evidence.value = scene.evidence
        if app.fits_person_mask:
            photo.silhouette.value = scene.person_mask
        app.set_person_box(scene.person_box)
        state = app.state
        current = tuple(OccluderEntry(o.box, o.enabled) for o in state.snapshot().occluders)
        if current != scene.occluders:
            _apply_occluders(app, scene)
        _apply_concentrations(app, scene)
        display = scene.display
        samples.num_samples.value = display.num_samples
        samples.num_displayed.value = display.num_displayed
        samples.seed.value = scene.seed
        samples.fit_opacity.value = display.fit_opacity
        samples.show_fit.value = display.show_fit
        samples.heat_max.value = display.linear_top_cm
        samples.show_samples.value = display.show_samples
        samples.show_heatmap.value = display.show_uncertainty_body
        samples.show_reprojection.value = display.show_reprojection
        samples.colouring.value = COLOURINGS[display.colouring]
        app.panels.teaching.joint.value = joint_label(display.selected_joint)
        app.set_compare(None if scene.compare is None else parse_compare(scene.compare))
        if app.states_body:
            app.state_body(BodyStatement.from_stated(scene.stated()))
        app.set_turned_around(scene.turned_around)

    def reset(self) -> None:
        """Every setting back to its default (the photo stays; its boxes go)."""
        self.apply(SceneFile(photo=DEFAULT_PHOTO, model=self.model))

    # ------------------------------------------------------------------ undo
    def record(self) -> None:
        """Keep the current settings as the newest edit (after each view; repeated and
        in-between states an undo sets off are not kept)."""
        current = self.settings()
        with self._lock:
            if self._settling is not None:
                target, since = self._settling
                if current != target and time.monotonic() - since < SETTLE_S:
                    return
                self._settling = None
            if self._history and self._history[self._index] == current:
                return
            now, last = time.monotonic(), self._recorded_at
            self._recorded_at = now
            del self._history[self._index + 1 :]
            if self._index > 0 and now - last < EDIT_PAUSE_S:
                before, latest = self._history[self._index - 1], self._history[self._index]
                if changed_controls(before, latest) == changed_controls(latest, current):
                    self._history[self._index] = current  # still the same drag
                    return
            self._history.append(current)
            del self._history[:-HISTORY_LENGTH]
            self._index = len(self._history) - 1

    def forget_history(self) -> None:
        """A new photo: its edits start afresh."""
        with self._lock:
            self._history, self._index, self._settling = [], -1, None
            self._recorded_at = -math.inf

    def undo(self) -> bool:
        """Back to the edit before; False when there is none."""
        return self._step(-1)

    def redo(self) -> bool:
        """Forward to the edit undone last; False when there is none."""
        return self._step(+1)

    def _step(self, direction: int) -> bool:
        with self._lock:
            index = self._index + direction
            if not 0 <= index < len(self._history):
                return False
            self._index = index
            target = self._history[index]
        self.apply(replace(target, model=self.model))
        return True


def _apply_occluders(app: ExplorerApp, scene: SceneFile) -> None:
    state = app.state
    state.clear_occluders()
    for entry in scene.occluders:
        added = state.add_occluder(entry.box)
        if added is not None and not entry.enabled:
            state.set_occluder_enabled(added.ident, False)
    app.occluders_changed(True)


def _apply_concentrations(app: ExplorerApp, scene: SceneFile) -> None:
    section = app.panels.concentration
    exponents = scene.joint_exponents()
    for name, exponent in zip(BODY_JOINT_NAMES, exponents, strict=True):
        section.joints[name].set_exponent(exponent)
    section.global_factor.set_factor(scene.all_joints_factor)
    section.shape_factor.set_factor(scene.shape_spread_factor)


DISPLAY_WORDS = {
    "colouring": lambda v: f"colouring {v}",
    "linear_top_cm": lambda v: f"linear scale top {v:g} cm",
    "num_samples": lambda v: f"{v} samples",
    "num_displayed": lambda v: f"{v} sample meshes",
    "show_samples": lambda v: "sample meshes hidden",
    "show_uncertainty_body": lambda v: "uncertainty body hidden",
    "show_reprojection": lambda v: "2D reprojection hidden",
    "show_fit": lambda v: "fit on the photo hidden",
    "fit_opacity": lambda v: f"fit opacity {v:g}",
    "selected_joint": lambda v: f"arrows at the {v.replace('_', ' ')}",
}
"""How each display setting that differs from its default is named in the scene line."""


def changed_controls(old: SceneFile, new: SceneFile) -> set[str]:
    """The names of the settings that differ between two scenes (one per joint factor and
    display setting)."""
    names = {
        name
        for name in SceneFile.__dataclass_fields__
        if name not in ("display", "joint_factors") and getattr(old, name) != getattr(new, name)
    }
    names |= {
        f"display.{name}"
        for name, value in vars(new.display).items()
        if getattr(old.display, name) != value
    }
    joints = set(old.joint_factors) | set(new.joint_factors)
    return names | {
        f"joint.{joint}"
        for joint in joints
        if old.joint_factors.get(joint) != new.joint_factors.get(joint)
    }


def describe_differences(scene: SceneFile) -> list[str]:
    """Each way ``scene``'s settings differ from the defaults, in a few words."""
    defaults, found = SceneFile(photo=scene.photo), []
    if scene.person_box is not None:
        found.append("person box {:.0f} {:.0f} {:.0f} {:.0f}".format(*scene.person_box))
    if scene.occluders:
        found.append(f"{len(scene.occluders)} occluder(s)")
    found += [f"{name.replace('_', ' ')} {f:.2g}×" for name, f in scene.joint_factors.items()]
    if scene.all_joints_factor != 1.0:
        found.append(f"all joints {scene.all_joints_factor:.2g}×")
    if scene.shape_spread_factor != 1.0:
        found.append(f"shape spread {scene.shape_spread_factor:.2g}×")
    if not scene.evidence:
        found.append("network only")
    if scene.person_mask:
        found.append("person mask fitted")
    for name, value in vars(scene.display).items():
        if value != getattr(defaults.display, name):
            found.append(DISPLAY_WORDS[name](value))
    if scene.seed != defaults.seed:
        found.append(f"seed {scene.seed}")
    if scene.compare is not None:
        found.append(f"compare: {parse_compare(scene.compare).label}")
    stated = BodyStatement.from_stated(scene.stated())
    if not stated.empty:
        found.append(f"stated: {stated.summary()}")
    if scene.turned_around:
        found.append("turned around")
    return found
