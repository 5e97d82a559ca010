"""``flocksweep run --until-claims``: add replicates where a claim's test is still undecided.

``claims_rule(claims, factors, seed=0)`` is a rule for :func:`sweeps.runner.run_until`: after each
round it judges the claims on the ok runs (:func:`.evaluate.evaluate`, with power) and, for every leaf
test that is inconclusive, asks the design points that test used for the replicates its power analysis
says would find the effect of interest with the target power (at least one more; the runner caps the
count at ``--max-replicates``). A test that cannot be analysed yet (too few values) asks for one more
replicate. Decided tests (supported or not supported) ask for nothing, so the loop ends when every
claim is decided or every undecided test's points are at the cap.
"""
from __future__ import annotations

import pandas as pd

from .evaluate import INCONCLUSIVE, evaluate


def undecided_points(outcomes, runs: pd.DataFrame, have: dict) -> dict:
    """{point index: replicates wanted} for the points of the inconclusive leaf tests."""
    wanted: dict[int, int] = {}
    for item in outcomes:
        for leaf in item.outcome.leaves():
            if leaf.verdict != INCONCLUSIVE or leaf.data is None or not len(leaf.data.rows):
                continue
            points = set(runs.loc[leaf.data.rows, "point_index"].astype(int))
            power = leaf.power
            for point in points:
                if power is None:
                    target = have.get(point, 1) + 1
                elif power.replicates is not None:
                    target = power.replicates
                else:
                    target = 10 ** 9   # beyond the power search's cap: as many as the runner allows
                wanted[point] = max(wanted.get(point, 0), target)
    return wanted


def claims_rule(claims, factors, seed: int = 0):
    """The rule (module docstring); ``factors`` are the sweep's factor columns (``sweeps.claims.sweep_columns``)."""
    def grow(table: pd.DataFrame, have: dict) -> tuple[dict, str]:
        runs = table[table["status"] == "ok"]
        outcomes = evaluate(claims, runs, [f for f in factors if f in runs.columns], seed=seed)
        verdicts = ", ".join(f"({o.claim.id}) {o.verdict}" for o in outcomes)
        return undecided_points(outcomes, runs, have), f"claims {verdicts}"
    return grow
