"""The report's "Claims, tested" section: a summary table, then per claim its statement, source and
condition, the verdict with the verdict of every part, the evidence figure (:mod:`.figures`) and a table
of its tests (statistic, estimate, p, p (Holm), n, power, minimum detectable effect, replicates needed).

``claims_section(outcomes, fig_dir, seed) -> (blocks, tables)``: ``blocks`` for
:mod:`analysis.reports.document` (figures are written into ``fig_dir`` as ``claim_<id>.png``), and
``tables`` {"claims": one row per claim, "claim_tests": one row per leaf test} for ``tables/*.csv``.
"""
from __future__ import annotations

from pathlib import Path

from ..document import Figure, Heading, Para, Table
from .evaluate import claim_table, leaf_table
from .figures import claim_figure

INTRO = ("Each claim is declared in the sweep file or a claims file it includes (docs/claims.md) and is tested "
         "only on the runs its condition selects. Every test is two-sided; p-values are Holm-adjusted within "
         "the claim's family. A part is **supported** when p (Holm) < alpha in the claimed direction, "
         "**not supported** when it is significant the other way or, not significant, the test had at least "
         "80% power to find the effect of interest, and **inconclusive** when it is not significant with less "
         "power than that. Power comes from simulations that keep the observed spread and plant an effect (at "
         "alpha / tests in the family); MDE is the smallest effect found with 80% power at this n; "
         "'replicates needed' is per design point for 80% power at the effect of interest. A claim of several "
         "parts is **partly supported** when some parts hold and others do not.")

SHOWN = ["test", "verdict", "kind", "method", "n", "statistic", "estimate", "p", "p_holm", "effect_of_interest",
         "power", "mde", "replicates_needed"]


def _source(claim) -> str:
    source = claim.source
    if source is None:
        return ""
    text = source.paper + (f", {source.section}" if source.section else "")
    return f"Source: {text}" + (f': "{source.quote}"' if source.quote else "") + "."


def claims_section(outcomes, fig_dir, seed: int = 0) -> tuple[list, dict]:
    if not outcomes:
        return [], {}
    claims, tests = claim_table(outcomes), leaf_table(outcomes)
    blocks = [Heading("Claims, tested"), Para(INTRO),
              Table(claims[["claim", "verdict", "statement", "condition", "family"]], "Verdicts")]
    for item in outcomes:
        claim = item.claim
        blocks.append(Heading(f"({claim.id}) {claim.statement}", 3))
        where = " and ".join(c.text for c in claim.test.conditions)
        blocks.append(Para(" ".join(part for part in (
            _source(claim), f"Tested where `{where}`." if where else "Tested on every run.",
            f"Family `{claim.family}`, alpha = {claim.alpha:g}.") if part)))
        verdict = f"Verdict: [{item.verdict}]."
        if item.outcome.parts:
            verdict += " " + "; ".join(f"{p.test.label}: [{p.verdict}]" for p in item.outcome.parts) + "."
        blocks.append(Para(verdict))
        path = claim_figure(item, Path(fig_dir) / f"claim_{claim.id}.png", seed)
        blocks.append(Figure(path, f"Claim ({claim.id}): the metric of each test against its factor or groups, "
                                   "on the runs the test used (means with 95% bootstrap CIs; runs as dots)."))
        rows = tests[tests["claim"] == claim.id]
        blocks.append(Table(rows[SHOWN], f"The tests of claim ({claim.id})"))
        for leaf in item.outcome.leaves():
            blocks.append(Para(f"`{leaf.test.path}` ({leaf.test.label}): [{leaf.verdict}]: {leaf.reason}."))
    return blocks, {"claims": claims, "claim_tests": tests}
