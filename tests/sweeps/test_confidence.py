"""The one CI half-width rule: Student t over the replicates, +inf below two values, used alike by the
sweep's --until-ci rounds and the report's cell summaries."""
import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from flocksweep.analysis.reports.stats import cell_summary
from flocksweep.sweeps.confidence import ci_halfwidth
from flocksweep.sweeps.runner import halfwidths


def test_the_half_width_is_student_t_and_infinite_below_two_values():
    n = np.array([0, 1, 2, 5])
    sd = np.array([np.nan, np.nan, 1.5, 0.25])
    width = ci_halfwidth(n, sd, 0.9)
    assert width[0] == np.inf and width[1] == np.inf
    assert width[2] == pytest.approx(sps.t.ppf(0.95, 1) * 1.5 / np.sqrt(2), rel=1e-14)
    assert width[3] == pytest.approx(sps.t.ppf(0.95, 4) * 0.25 / np.sqrt(5), rel=1e-14)
    assert np.isnan(ci_halfwidth(3, np.nan))   # enough values but no spread known: undefined, not infinite


def test_until_ci_and_the_report_give_the_same_half_widths():
    table = pd.DataFrame({"point_index": [0, 0, 0, 1, 2, 2], "status": ["ok"] * 6,
                          "m": [1.0, 2.0, 4.0, 3.0, 2.0, 6.0]})
    sweep = halfwidths(table, "m")["halfwidth"].to_numpy()
    report = cell_summary(table, "point_index", "m")["ci_halfwidth"].to_numpy()
    np.testing.assert_array_equal(sweep, report)
    assert sweep[1] == np.inf
