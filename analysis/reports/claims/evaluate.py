"""Judging declared claims (:class:`sweeps.claims.Claim`) on a results table.

``evaluate(claims, runs, factors, seed=0, with_power=True) -> list[ClaimOutcome]`` runs every leaf test
of every claim on ``runs`` (the ok runs; ``factors`` are the columns that identify a design point),
adjusts the p-values with Holm's method within each claim family (all leaf tests of all claims with
the same ``family``, NaN p-values left out), runs the power analysis of each leaf (:mod:`.power`, at
alpha / m, m the number of tests in the family: the strictest step of Holm's procedure, so the power
is a lower bound) and judges bottom-up:

A leaf test is

* **supported** when p (Holm) < alpha and the data go the claimed way;
* **not supported** when p (Holm) < alpha the other way, or when it is not significant although the
  test had at least the target power (default 0.8) to find the effect of interest;
* **inconclusive** when it is not significant and underpowered (the reason gives the power, the
  minimum detectable effect and the replicates per design point that would reach the target power),
  or when it cannot be tested (too few runs).

A ``zero`` sign test is a check: supported when every run is within ``tolerance`` of ``value``.

``all_of`` is supported when every part is, **partly supported** when some part is supported (or partly
supported), not supported when no part is and some part is not supported, else inconclusive.
``any_of`` is supported when some part is, partly supported when some part is partly supported, not
supported when every part is not supported, else inconclusive. The reason of a composition names each
part's verdict, so "partly supported" says which parts hold.

``leaf_table(outcomes)`` (one row per leaf test) and ``claim_table(outcomes)`` (one row per claim) are
the report's tables. The power simulation draws from ``sweeps.seeds.named_generator(seed,
Tag.CLAIM_POWER, test path)``, so the same seed gives the same numbers, claim by claim.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from flocksweep.sweeps.seeds import Tag, named_generator

from ..stats import holm
from .kinds import LeafData, LeafResult, leaf_data, leaf_result
from .power import Power, analyse

SUPPORTED, PARTLY, NOT, INCONCLUSIVE = "supported", "partly supported", "not supported", "inconclusive"
VERDICTS = (SUPPORTED, PARTLY, NOT, INCONCLUSIVE)


@dataclass
class Outcome:
    test: object                     # sweeps.claims.Test
    verdict: str = INCONCLUSIVE
    reason: str = ""
    parts: list = field(default_factory=list)
    data: LeafData | None = None
    result: LeafResult | None = None
    p_holm: float = float("nan")
    alpha: float = float("nan")
    power: Power | None = None

    def leaves(self) -> list:
        return [leaf for part in self.parts for leaf in part.leaves()] if self.parts else [self]


@dataclass
class ClaimOutcome:
    claim: object                    # sweeps.claims.Claim
    outcome: Outcome

    @property
    def verdict(self) -> str:
        return self.outcome.verdict


def _p(value: float) -> str:
    return "nan" if not math.isfinite(value) else f"{value:.2g}"


def _effect_text(power: Power) -> str:
    return f"{power.effect:.3g}" + (" (half the spread)" if power.effect_source != "declared" else "")


def judge_leaf(test, result: LeafResult, p_holm: float, alpha: float, power: Power | None, target: float):
    """(verdict, reason) of one leaf test (module docstring)."""
    if result.method == "check":
        if result.n == 0:
            return INCONCLUSIVE, "no runs meet the condition"
        return (SUPPORTED if result.statistic == 0 else NOT), result.detail
    if not math.isfinite(result.p):
        return INCONCLUSIVE, f"cannot be tested with these data (n = {result.n}): {result.detail}"
    stated = f"{result.detail}; p (Holm) = {_p(p_holm)}, n = {result.n}"
    if p_holm < alpha:
        if result.sign == test.claimed_sign:
            return SUPPORTED, stated
        return NOT, f"significant the other way: {stated}"
    if power is None:
        return INCONCLUSIVE, f"not significant: {stated}; too few values for a power analysis"
    if power.power >= target:
        return NOT, (f"not significant: {stated}; yet the test had power {power.power:.2f} to find an effect of "
                     f"{_effect_text(power)}")
    return INCONCLUSIVE, (f"not significant: {stated}; power only {power.power:.2f} for an effect of "
                          f"{_effect_text(power)}; the minimum detectable effect now is {power.mde:.3g}; "
                          + _needed(power))


def _needed(power: Power) -> str:
    if power.replicates is None:
        return f"more replicates per design point than the search cap would be needed for {power.target:.0%} power"
    return f"{power.replicates} replicates per design point would give {power.target:.0%} power"


def combine(kind: str, parts: list[Outcome]) -> tuple[str, str]:
    verdicts = [p.verdict for p in parts]
    reason = "; ".join(f"{p.test.label}: {p.verdict}" for p in parts)
    if kind == "all_of":
        if all(v == SUPPORTED for v in verdicts):
            return SUPPORTED, reason
        if any(v in (SUPPORTED, PARTLY) for v in verdicts):
            return PARTLY, reason
        return (NOT if NOT in verdicts else INCONCLUSIVE), reason
    if SUPPORTED in verdicts:
        return SUPPORTED, reason
    if PARTLY in verdicts:
        return PARTLY, reason
    return (NOT if all(v == NOT for v in verdicts) else INCONCLUSIVE), reason


def _tree(test, leaves: dict) -> Outcome:
    if not test.composite:
        return leaves[test.path]
    parts = [_tree(part, leaves) for part in test.parts]
    verdict, reason = combine(test.kind, parts)
    return Outcome(test, verdict, reason, parts)


def evaluate(claims, runs: pd.DataFrame, factors, seed: int = 0, with_power: bool = True) -> list[ClaimOutcome]:
    """Every claim judged on ``runs`` (module docstring)."""
    leaves: dict[str, Outcome] = {}
    owner: dict[str, object] = {}
    for claim in claims:
        for test in claim.test.leaves():
            data = leaf_data(test, runs, factors)
            leaves[test.path] = Outcome(test, data=data, result=leaf_result(test, data), alpha=claim.alpha)
            owner[test.path] = claim
    families: dict[str, list[str]] = {}
    for path, claim in owner.items():
        families.setdefault(claim.family, []).append(path)
    for paths in families.values():
        adjusted = holm(np.array([leaves[p].result.p for p in paths], dtype=float))
        tested = int(np.isfinite(adjusted).sum())
        for path, p_holm in zip(paths, adjusted):
            leaf, claim = leaves[path], owner[path]
            leaf.p_holm = float(p_holm)
            if with_power:
                settings = claim.power
                rng = named_generator(seed, Tag.CLAIM_POWER, path)
                leaf.power = analyse(leaf.test, leaf.data, claim.alpha / max(tested, 1), settings.target,
                                     leaf.test.effect, settings.simulations, settings.max_replicates, rng)
            leaf.verdict, leaf.reason = judge_leaf(leaf.test, leaf.result, leaf.p_holm, claim.alpha, leaf.power,
                                                   claim.power.target)
    return [ClaimOutcome(claim, _tree(claim.test, leaves)) for claim in claims]


def _condition_text(test) -> str:
    return " and ".join(c.text for c in test.conditions)


def leaf_table(outcomes: list[ClaimOutcome]) -> pd.DataFrame:
    rows = []
    for claim_outcome in outcomes:
        claim = claim_outcome.claim
        for leaf in claim_outcome.outcome.leaves():
            test, result, power = leaf.test, leaf.result, leaf.power
            groups = f"{test.lower.text} < {test.higher.text}" if test.kind == "compare" else ""
            rows.append({
                "claim": claim.id, "claim_verdict": claim_outcome.verdict, "test": test.path, "label": test.label,
                "verdict": leaf.verdict, "kind": test.kind, "method": result.method,
                "metric": test.metric.text, "factor": test.factor or "", "direction": test.direction or "",
                "groups": groups, "condition": _condition_text(test), "family": claim.family,
                "n": result.n, "n_missing": leaf.data.n_missing, "statistic": result.statistic, "p": result.p,
                "p_holm": leaf.p_holm, "alpha": claim.alpha, "estimate": result.estimate,
                "effect_of_interest": power.effect if power else float("nan"),
                "effect_source": power.effect_source if power else "",
                "power": power.power if power else float("nan"), "power_alpha": power.alpha if power else float("nan"),
                "mde": power.mde if power else float("nan"),
                "replicates_now": power.replicates_now if power else float("nan"),
                "replicates_needed": (power.replicates if power and power.replicates is not None else float("nan")),
                "design_points": power.points if power else float("nan"),
                "spread": power.spread if power else float("nan"), "power_model": power.model if power else "",
                "detail": result.detail, "reason": leaf.reason})
    return pd.DataFrame(rows)


def claim_table(outcomes: list[ClaimOutcome]) -> pd.DataFrame:
    rows = []
    for item in outcomes:
        claim = item.claim
        source = claim.source
        rows.append({"claim": claim.id, "verdict": item.verdict, "statement": claim.statement,
                     "source": (f"{source.paper}" + (f", {source.section}" if source.section else "")) if source else "",
                     "condition": _condition_text(claim.test), "family": claim.family, "alpha": claim.alpha,
                     "tests": len(item.outcome.leaves()), "reason": item.outcome.reason,
                     "origin": claim.origin})
    return pd.DataFrame(rows)
