"""The app's actions for the Body section (stated sex and measurements, the look of the drawn
body), as a mixin of :class:`~hkpd.explorer.app.ExplorerApp`, so that the app's own module
keeps only the wiring.

A change of what is stated predicts again in the app's worker (lane ``"predict"``), like the
evidence switch: the stated values are part of the state's snapshot and of the key each
posterior is kept under, so posteriors of different stated bodies never mix.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hkpd.explorer.body_settings import BodyStatement
from hkpd.explorer.panels.body import LOOKS
from hkpd.explorer.provider import body_arguments
from hkpd.explorer.scene import LOOK_COLOURS

if TYPE_CHECKING:
    from hkpd.explorer.app import ExplorerApp

    _Base = ExplorerApp
else:
    _Base = object


class BodyAppActions(_Base):
    """Stated sex and measurements, and the look, for :class:`ExplorerApp`."""

    @property
    def states_body(self) -> bool:
        """The provider takes a stated sex and measurements
        (:class:`~hkpd.explorer.provider.BodyStatingProvider`)."""
        return bool(getattr(self.provider, "states_body", False))

    def body_changed(self, changed: bool) -> None:
        """Predict again with the stated values when they ``changed``."""
        if changed:
            self.worker.submit("predict", self._predict_job)

    def state_body(self, stated: BodyStatement) -> bool:
        """State ``stated`` (as the Body section does) and predict again; False if unchanged."""
        changed = self.state.set_stated(stated)
        self.panels.body.show_stated(self.state.stated)
        self.body_changed(changed)
        return changed

    def set_look(self, look: str) -> None:
        """Draw the most likely body in ``look`` (a key of
        :data:`~hkpd.explorer.panels.body.LOOKS`: clay, skin)."""
        if look not in LOOKS:
            raise ValueError(f"look must be one of {', '.join(LOOKS)}, got {look!r}")
        self.scene.set_mode_colour(LOOK_COLOURS[look])

    def _body_arguments(self, stated: BodyStatement | None, evidence: bool) -> dict[str, object]:
        """The provider's keyword arguments for ``stated`` (None: the state's current)."""
        body = self.state.stated if stated is None else stated
        return body_arguments(self.provider, body, evidence)

    def _show_body(self, posterior: object | None) -> None:
        """The Body section for ``posterior`` (None: nobody found) and the stated values."""
        snapshot = self.state.snapshot()
        self.panels.body.show(posterior, snapshot.stated, snapshot.evidence, self.states_body)
