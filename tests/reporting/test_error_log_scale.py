"""The navigation error figure and the error CDFs turn to log scales when the error spans decades
(a start from a kilometre-wide prior, then metres), and stay linear otherwise."""

from __future__ import annotations

import numpy as np

from testbench.reporting.figures_common import new_figure
from testbench.reporting.figures_nav import _cdf_axes, _spans_decades


def test_an_error_from_a_kilometre_down_to_metres_spans_decades():
    err = np.r_[np.full(30, 900.0), np.full(2970, 0.4)]
    assert _spans_decades(err)


def test_a_drift_of_metres_does_not():
    assert not _spans_decades(np.linspace(0.2, 12.0, 3000))
    assert not _spans_decades(np.array([np.nan, np.nan]))


def test_the_cdf_takes_a_log_x_only_when_the_errors_span_decades():
    cold = np.r_[np.full(30, 900.0), np.full(2970, 0.4)]
    warm = np.linspace(0.2, 12.0, 3000)
    a, b = new_figure().subplots(1, 2)
    assert _cdf_axes(a, cold, [("all", np.ones(cold.size, bool))], "error (m)")
    assert not _cdf_axes(b, warm, [("all", np.ones(warm.size, bool))], "error (m)")
    assert (a.get_xscale(), b.get_xscale()) == ("log", "linear")
