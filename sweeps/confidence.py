"""The confidence interval of a mean over replicates: one rule for the sweep's ``--until-ci`` rounds and
the report's replicate-adequacy tables.

``ci_halfwidth(n, sd, confidence=0.95)`` is the Student-t half-width t_{(1+c)/2, n-1} sd / sqrt(n) of the
CI of a mean over ``n`` values with sample standard deviation ``sd`` (ddof 1), elementwise over arrays.

With fewer than two values (n < 2) there is no estimate of the spread, so the interval has no finite
bound: its half-width is **+inf** (not NaN). An infinite width compares as wider than any target, so a
point with one replicate always asks for more (``--until-ci``), and tables say "no CI yet" with a value
that sorts and compares; NaN would silently pass every "is it wide?" test. ``n >= 2`` with ``sd`` NaN
(a column of missing values) stays NaN.
"""
from __future__ import annotations

import numpy as np


def ci_halfwidth(n, sd, confidence: float = 0.95) -> np.ndarray:
    """Student-t CI half-width of a mean of ``n`` values with standard deviation ``sd`` (+inf for n < 2)."""
    from scipy import stats  # imported here: scipy.stats takes most of a second to import

    n = np.asarray(n, dtype=np.float64)
    sd = np.asarray(sd, dtype=np.float64)
    enough = n >= 2
    with np.errstate(invalid="ignore", divide="ignore"):
        t = stats.t.ppf(0.5 + confidence / 2.0, np.where(enough, n - 1, 1.0))
        return np.where(enough, t * sd / np.sqrt(np.where(enough, n, 1.0)), np.inf)
