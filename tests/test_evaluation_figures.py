"""The mode-vs-samples bar chart of hkpd-eval --figure."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from hkpd.evaluation.figures import plot_2d_errors


def test_bar_chart_is_written_and_bad_rows_are_refused(tmp_path) -> None:
    rows = {
        "runs/a_b.pt": {"joint_error_2d_mode": 10.0, "joint_error_2d_samples": 15.0},
        "runs/c.pt": {"joint_error_2d_mode": 9.0, "joint_error_2d_samples": 9.5},
    }
    path = plot_2d_errors(rows, tmp_path / "figs" / "bars.png")
    picture = np.asarray(Image.open(path).convert("RGB"))
    assert picture.shape[0] > 200 and picture.std() > 20
    with pytest.raises(ValueError, match="joint_error_2d_samples"):
        plot_2d_errors({"x.pt": {"joint_error_2d_mode": 1.0}}, tmp_path / "bad.png")
    with pytest.raises(ValueError, match="nothing to plot"):
        plot_2d_errors({}, tmp_path / "empty.png")
