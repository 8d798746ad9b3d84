"""The navigation error figure turns to log scales when the error spans decades (a start from
a kilometre-wide prior, then metres), and stays linear otherwise."""

from __future__ import annotations

import numpy as np

from testbench.reporting.figures_nav import _spans_decades


def test_an_error_from_a_kilometre_down_to_metres_spans_decades():
    err = np.r_[np.full(30, 900.0), np.full(2970, 0.4)]
    assert _spans_decades(err)


def test_a_drift_of_metres_does_not():
    assert not _spans_decades(np.linspace(0.2, 12.0, 3000))
    assert not _spans_decades(np.array([np.nan, np.nan]))
