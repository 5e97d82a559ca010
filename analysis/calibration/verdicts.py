"""The verdicts every fit gets, whatever its method: posterior mass piled against a prior bound, the flock's
group structure, and one line that says whether the fit is credible and why not.

Shapes: S posterior draws, d parameters, P predictive runs.

Contract
--------
``bound_verdicts(config, draws (S, d)) -> list[dict]``: for each parameter and each bound of its prior, the
share of draws within :data:`BOUND_BAND` (2 %) of the prior's width from that bound; one entry (parameter,
bound "lower"/"upper", value, share, message) for each share above :data:`BOUND_SHARE` (10 %, five times
what a flat posterior puts there), e.g. "field: 38% of draws within 2% of the upper bound 300: widen the
prior or the model cannot reach the data". One draw (an optimum) is flagged when it lies in the band.

``group_verdict(config, table) -> dict | None``: from ``flock_check.csv``'s table
(:func:`analysis.calibration.flock_check.flock_check`, which carries ``fragmented``'s predictive mean, the
share of predictive runs that split): when the observed flock is one group (its ``fragmented`` is 0, or
its ``n_groups`` at most :data:`ONE_GROUP` on average; from tracks or from ``[targets] flock``), a fit whose
predictive runs fragment in more than :data:`MAX_FRAGMENTED` (10 %) fails, whatever the tail
probabilities: {observed_one_group, predictive_fragmented, passed, message}; None when the observed
group structure is not known.

``credibility(config, outcome) -> dict``: ``credible`` (bool), ``verdict`` (one line: "credible: ..." or
"NOT credible: reason; reason"), ``reasons``: the sampler or the estimator not converged (the method's
``convergence.converged``: chain verdicts, npe's held-out coverage), a failed emulator confirmation, an
optimum re-checked far worse than found (more than 3 standard errors), most predictive runs without
the targets' statistics (``predictive_runs`` against the predictive table's ``n_pred``), a target in the tail of its
predictive distribution (p below 0.05 / k, Bonferroni over the k targets), a flock statistic that
disagrees with the observed flock, a failed group structure, mass against a prior bound, no posterior.
"""
from __future__ import annotations

import math

import numpy as np

BOUND_BAND = 0.02
BOUND_SHARE = 0.10
MAX_FRAGMENTED = 0.10
ONE_GROUP = 1.05
P_TARGETS = 0.05
RECHECK_Z = 3.0


def bound_verdicts(config, draws) -> list[dict]:
    """Parameters with posterior mass against a prior bound (module docstring)."""
    draws = np.atleast_2d(np.asarray(draws, dtype=float))
    draws = draws[np.isfinite(draws).all(axis=1)]
    out = []
    if not len(draws):
        return out
    for j, (name, (low, high)) in enumerate(zip(config.names, config.prior.bounds)):
        if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
            continue
        band = BOUND_BAND * (high - low)
        for bound, value, near in (("lower", low, draws[:, j] <= low + band), ("upper", high, draws[:, j] >= high - band)):
            share = float(near.mean())
            if (len(draws) == 1 and share == 1.0) or (len(draws) > 1 and share > BOUND_SHARE):
                what = "the optimum lies" if len(draws) == 1 else f"{share:.0%} of draws lie"
                out.append({"parameter": name, "bound": bound, "value": float(value), "share": share,
                            "message": f"{name}: {what} within {BOUND_BAND:.0%} of the {bound} bound {value:g}: "
                                       "widen the prior, or the model cannot reach the data"})
    return out


def _observed(table, stat: str):
    rows = [c for c in table.index if c == stat or c.startswith(f"{stat}_")]
    for column in rows:
        value = table.loc[column, "observed"]
        if value == value:     # not NaN
            return column, float(value)
    return None, None


def group_verdict(config, table) -> dict | None:
    """The group structure of the predictive runs against the observed flock's (module docstring)."""
    if table is None or not len(table):
        return None
    fragmented_column, observed_fragmented = _observed(table, "fragmented")
    groups_column, observed_groups = _observed(table, "n_groups")
    if observed_fragmented is not None:
        one_group = observed_fragmented == 0
    elif observed_groups is not None:
        one_group = observed_groups <= ONE_GROUP
    else:
        return None
    if "fragmented" not in table.index:
        return None
    share = float(table.loc["fragmented", "pred_mean"])
    passed = not (one_group and share > MAX_FRAGMENTED)
    if one_group:
        message = (f"group structure: the observed flock is one group and {share:.0%} of the predictive flocks "
                   f"split ({'at most' if passed else 'more than'} {MAX_FRAGMENTED:.0%} allowed)"
                   + ("" if passed else ": the fitted model does not hold the flock together, whatever the "
                                        "targets' tail probabilities"))
    else:
        message = f"group structure: the observed flock split, and {share:.0%} of the predictive flocks split"
    return {"observed_one_group": bool(one_group), "predictive_fragmented": share, "passed": bool(passed),
            "message": message}


def _failed_predictive(outcome) -> list[str]:
    """A reason when most posterior predictive runs gave no statistics (the fit's flocks are undefined)."""
    runs = outcome.report.get("predictive_runs")
    table = outcome.predictive
    if not runs or table is None or not len(table):
        return []
    got = int(table["n_pred"].min())
    if got >= 0.5 * runs:
        return []
    return [f"{runs - got} of {runs} posterior predictive runs gave no finite value of the targets' statistics"]


def _target_tails(outcome) -> list[str]:
    table = outcome.predictive
    if table is None or not len(table):
        return []
    limit = P_TARGETS / len(table)
    return [f"{stat} lies in the tail of its predictive distribution (p = {row['p']:.2g} < {limit:.2g})"
            for stat, row in table.iterrows() if math.isfinite(row["p"]) and row["p"] < limit]


def _flock_disagreements(outcome) -> list[str]:
    table = getattr(outcome, "flock", None)
    if table is None:
        return []
    return [f"the observed flock's {column} ({row['observed']:.3g}) is outside the predictive runs' (mean "
            f"{row['pred_mean']:.3g}, p = {row['p']:.2g})" for column, row in table.iterrows()
            if row["disagrees"] and not row["target"]]


def credibility(config, outcome) -> dict:
    """The one-line verdict of a fit (module docstring)."""
    report = outcome.report
    reasons = []
    if report.get("no_posterior"):
        reasons.append(report["no_posterior"])
    convergence = report.get("convergence") or {}
    if convergence and not convergence.get("converged", True):
        word = ("the estimator failed its held-out coverage check" if convergence.get("coverage_ok") is False
                else "the sampler has not converged")
        reasons.append(word)
    confirm = report.get("confirm")
    if confirm and not confirm.get("passed", True):
        reasons.append("the real runs at the posterior median do not confirm the emulator")
    optimum = outcome.optimum
    if optimum and optimum.get("recheck_se"):
        gap = (optimum["objective_recheck"] - optimum["objective_common_seeds"]) / optimum["recheck_se"]
        if gap > RECHECK_Z:
            reasons.append(f"the optimum re-checked with fresh seeds is {gap:.1f} standard errors worse than found "
                           "(it fits the search's seeds, not the data)")
    reasons += _failed_predictive(outcome)
    reasons += _target_tails(outcome)
    reasons += _flock_disagreements(outcome)
    group = report.get("group_structure")
    if group and not group["passed"]:
        reasons.append(f"{group['predictive_fragmented']:.0%} of the predictive flocks split while the observed "
                       "flock is one group")
    reasons += [b["message"] for b in report.get("bounds", [])]
    credible = not reasons
    if credible:
        checks = ["converged" if convergence else "optimised",
                  "every target and known flock statistic within its predictive spread"]
        if group:
            checks.append("the group structure as observed")
        line = "credible: " + ", ".join(checks)
    else:
        line = "NOT credible: " + "; ".join(reasons)
    return {"credible": credible, "verdict": line, "reasons": reasons}
