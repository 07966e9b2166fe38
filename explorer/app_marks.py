"""The marks drawn over the photo beside the keypoints, as a mixin of
:class:`~hkpd.explorer.app.ExplorerApp`: BlazePose's hand and foot landmarks
(:class:`~hkpd.explorer.extremity_marks.ExtremityMarks`, the Photo tab's landmark switch) and
the second keypoint reader's keypoints (:class:`~hkpd.explorer.second_reader_marks.
SecondReaderMarks`, its checkbox). Each is made at first use and shown for every prediction
(:meth:`PhotoMarksActions._show_marks`)."""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

from hkpd.explorer.extremity_marks import ExtremityMarks
from hkpd.explorer.second_reader_marks import SecondReaderMarks

if TYPE_CHECKING:
    from hkpd.explorer.app import ExplorerApp

    _Base = ExplorerApp
else:
    _Base = object


class PhotoMarksActions(_Base):
    """The landmark and second-reader marks of the app (module docstring)."""

    @functools.cached_property
    def landmark_marks(self) -> ExtremityMarks:
        """The detected hand and foot landmarks on the photo (made at first use)."""
        return ExtremityMarks(self.scene)

    def show_landmarks(self, visible: bool) -> None:
        """Draw the detected hand and foot landmarks on the photo, or hide them."""
        self.landmark_marks.set_visible(visible)

    @functools.cached_property
    def second_reader_marks(self) -> SecondReaderMarks:
        """The second keypoint reader's keypoints on the photo (made at first use, hidden)."""
        return SecondReaderMarks(self.scene)

    def show_second_reader(self, visible: bool) -> None:
        """Draw the second keypoint reader's keypoints on the photo, or hide them."""
        self.second_reader_marks.set_visible(visible)

    def _show_marks(self, posterior: object | None) -> None:
        """Both marks of ``posterior``'s reading (None: clear them)."""
        self.landmark_marks.show(posterior)
        self.second_reader_marks.show(posterior)
