"""A calibration's report: ``report.html`` (self-contained) and ``report.md`` in its output folder, on the
report document machinery of :mod:`analysis.reports.document`.

``calibration_report(config, outcome, folder) -> dict`` (paths written) renders, from what the run wrote:
the verdicts first (converged or not, in plain words, with every warning: chain length, acceptance,
R-hat and ESS, unconstrained parameters, an emulator's box and confirmation, targets in the tail of
their predictive distribution, a flock statistic that disagrees with the observed flock, a known truth outside its 90% interval), then the settings (method,
seed, model, free parameters and priors, targets), the posterior table (emcee's tau and ESS next to
ArviZ's R-hat, bulk/tail ESS and MCSE), the trace, rank and corner plots, the posterior predictive
check, every flock statistic of the predictive runs against the observed flock (flagged when one
disagrees, target or not), the emulator's training set, refinement rounds and confirmation, an optimisation's optimum,
the provenance and the files.

``verdict_lines(outcome) -> list[str]``: the same verdicts as plain sentences, for the console (after a
refinement, with the last round's emulator share against ``refine.max_emulator_share``).

``outcome`` is :class:`analysis.calibration.outcome.CalibrationRun`-like: ``report`` (the convergence.json
dict), ``summary`` (posterior.csv's frame or None), ``predictive``, ``warnings``, and for the emulator
``confirm`` and ``refine``; ``optimum`` for optimisation.
"""
from __future__ import annotations

import math

import pandas as pd

from flocksweep.analysis.reports.document import Figure, Heading, Para, Table, to_html, to_markdown
from flocksweep.analysis.reports.labels import parameter_label
from flocksweep.simcore.schema import to_dict

from .accounting import lines
from .flock_check import flock_messages

P_TAIL = 0.05
CORNER_CAPTION = ("Pairwise posterior: 5%, 50% and 95% quantiles, contours holding 50% and 90% of the draws, "
                  "the truth in red when known.")


def _truth_lines(config, summary: pd.DataFrame | None) -> list[str]:
    truth = config.targets.truth
    if not truth or summary is None:
        return []
    out = []
    for name, value in truth.items():
        low, high = float(summary.loc[name, "q5"]), float(summary.loc[name, "q95"])
        inside = low <= value <= high
        out.append(f"truth {name} = {value:g} is {'inside' if inside else 'OUTSIDE'} the 90% interval "
                   f"[{low:.4g}, {high:.4g}] (posterior mean {float(summary.loc[name, 'mean']):.4g}, sd "
                   f"{float(summary.loc[name, 'sd']):.3g})")
    return out


def _share_lines(config, rounds) -> list[str]:
    """The emulator's share of the likelihood variance in the last refinement round, against its limit."""
    if rounds is None or not len(rounds) or "emulator_share" not in rounds:
        return []
    share, limit = float(rounds["emulator_share"].iloc[-1]), config.method.refine.max_emulator_share
    if share <= limit:
        return [f"  the emulator's own variance is {share:.2g} of the likelihood's over the posterior "
                f"(limit {limit:g}): it widens the posterior by at most about "
                f"{100 * (math.sqrt(1 + share) - 1):.0f} %"]
    return [f"  the emulator's own variance is still {share:.2g} of the likelihood's over the posterior (limit "
            f"{limit:g}): the posterior may be wider than the targets allow; more rounds would narrow it"]


def verdict_lines(config, outcome) -> list[str]:
    """Plain sentences: convergence, warnings, confirmation, predictive tails, the truth."""
    report = outcome.report
    lines = [report["verdict"]] if report.get("verdict") else []
    if report.get("no_posterior"):
        lines.append(f"no posterior: {report['no_posterior']}")
    convergence = report.get("convergence")
    if convergence:
        word = "converged" if convergence.get("converged") else "NOT converged"
        lines.append(f"verdict: {word}")
        lines += list(convergence.get("messages", []))
    lines += list(outcome.warnings or [])
    confirm = report.get("confirm")
    if confirm:
        word = "passed" if confirm.get("passed") else "FAILED"
        lines.append(f"confirmation with {confirm['count']} real runs at the posterior median: {word}")
        lines += [f"  {m}" for m in confirm.get("messages", [])]
    refine = report.get("refine")
    if refine:
        lines.append(f"refinement: {refine['rounds_run']} round(s), {refine['runs_added']} runs added to the sweep "
                     f"{refine['results']}; " + ("the confirmation passed" if refine["passed"] else
                                                  "the confirmation still fails after the last round"))
        lines += _share_lines(config, outcome.refine)
    if outcome.predictive is not None:
        for stat, row in outcome.predictive.iterrows():
            if math.isfinite(row["p"]) and row["p"] < P_TAIL:
                lines.append(f"{stat}: the observed value {row['observed']:.4g} lies in the tail of the posterior "
                             f"predictive distribution (p = {row['p']:.3g}): the model does not reproduce it well")
    lines += flock_messages(getattr(outcome, "flock", None))
    group = report.get("group_structure")
    if group:
        lines.append(group["message"])
    lines += [bound["message"] for bound in report.get("bounds", [])]
    lines += _truth_lines(config, outcome.summary)
    return lines


def _settings_tables(config) -> list:
    method = pd.DataFrame([{"setting": k, "value": str(v)} for k, v in to_dict(config.method).items()])
    rows = [{"setting": "seed", "value": config.seed}, {"setting": "model", "value": config.model_label}]
    if config.preset is not None:
        rows += [{"setting": "flock size N", "value": config.preset.init.n},
                 {"setting": "duration (s)", "value": config.preset.run.duration}]
    rows += [{"setting": "warm-up (s)", "value": config.metrics.warmup},
             {"setting": "observation", "value": config.observation.describe() if config.observation else "none "
                                                 "(the runs' own records)"},
             {"setting": "statistics' transforms", "value": config.transforms.describe() if config.transforms else "none"}]
    run = pd.DataFrame(rows)
    parameters = pd.DataFrame([{"parameter": p.name, "key": p.key, "meaning": parameter_label(p.key),
                                "prior": repr(p.prior), "bounds": f"[{p.bounds[0]:g}, {p.bounds[1]:g}]",
                                "truth": (config.targets.truth or {}).get(p.name, "")} for p in config.parameters])
    targets = config.targets
    rows = []
    for j, (stat, column) in enumerate(zip(targets.stats, targets.columns)):
        row = {"statistic": stat, "column": column, "observed (mean over rows)": float(targets.observed[:, j].mean())}
        if targets.cov is not None:
            row["measurement sd"] = float(targets.cov[j, j] ** 0.5)
        rows.append(row)
    return [Table(method, "Method settings"), Table(run, "Model and run"), Table(parameters, "Free parameters"),
            Table(pd.DataFrame(rows), f"Targets ({len(targets.observed)} observed row(s); summary "
                                      f"\"{targets.summary}\")")]


def _figure(folder, name: str, caption: str) -> list:
    path = folder.path(name)
    return [Figure(path, caption)] if path.exists() else []


def emulator_blocks(outcome, folder) -> list:
    """The emulator's training set, refinement rounds and confirmation."""
    report = outcome.report
    blocks = []
    info = report.get("emulator")
    if not info:
        return blocks
    blocks += [Heading("Emulator"), Para(f"Trained on {info['training_points']} parameter points "
                                         f"({info['training_runs']} runs) of `{info['results']}`; fixed factors "
                                         f"{info.get('fixed_factors') or 'none'}; surrogate fitted in "
                                         f"{info['fit_s']:.1f} s.")]
    if outcome.refine is not None and len(outcome.refine):
        blocks.append(Table(outcome.refine, "Refinement rounds: training set, posterior and confirmation per round"))
    if outcome.confirm:
        blocks.append(Table(outcome.confirm["comparison"].reset_index(),
                            "Confirmation: real runs at the posterior median against the emulator (z per statistic)"))
        blocks.append(Table(outcome.confirm["predictive"].reset_index(),
                            "Confirmation: the targets against the real runs at the posterior median"))
    return blocks


def _se(value) -> str:
    """A re-check's standard error; None (JSON's null for nan) when one batch cannot give one."""
    return "(no se: one batch)" if value is None or value != value else f"{value:.2g}"


def _cost_blocks(block: dict | None) -> list:
    """The simulations this run made, by phase, and its likelihood evaluations and time."""
    if not block:
        return []
    evaluations = block["likelihood_evaluations"]
    rows = [{"phase": phase, "simulations": count, "likelihood evaluations": evaluations.get(phase, 0)}
            for phase, count in block["simulations"].items() if phase != "total"]
    rows.append({"phase": "total", "simulations": block["simulations"]["total"],
                 "likelihood evaluations": block["likelihood_evaluations"]["total"]})
    return [Heading("Cost"), Table(pd.DataFrame(rows), "Simulations run by this calibration, by phase "
                                                       "(convergence.json / optimum.json: accounting)"),
            Para(" ".join(lines(block)))]


def npe_blocks(outcome, folder) -> list:
    """npe: the posterior of independent draws, the estimator and its held-out coverage."""
    info = outcome.report["npe"]
    trained = ("reused from " if info["reused"] else "trained and stored in ") + f"`{info['estimator']}`"
    blocks = [Heading("Posterior"),
              Para(f"{outcome.report.get('draws')} independent draws of the neural posterior estimator at the targets "
                   f"(split into 4 chains for ArviZ's r_hat and ESS); the estimator was {trained} (identity "
                   f"{info['identity']}, {info['training_simulations']} training simulations)."
                   f"{_learned_text(info.get('flow') or {})}"),
              Table(outcome.summary.reset_index(), "Posterior summary (posterior.csv)")]
    blocks += _figure(folder, "corner.png", CORNER_CAPTION)
    blocks += [Heading("Coverage on held-out simulations"),
               Table(pd.DataFrame(info["coverage"]["table"]), f"Share of {info['heldout_simulations']} held-out "
                                                               "truths inside the central intervals (coverage.csv)")]
    blocks += _figure(folder, "coverage_ranks.png", "SBC ranks of the held-out truths among 199 posterior draws: "
                                                    "flat when calibrated, U-shaped when over-confident.")
    return blocks


def _learned_text(flow: dict) -> str:
    """A sentence on npe's learned summary, when it has one (docs/calibration.md, "Learned summaries")."""
    summary, plan = flow.get("summary"), flow.get("layout")
    if not summary or summary.get("kind") != "learned" or not plan:
        return ""
    return (f" The flow is conditioned on the statistics and on a summary of {summary['size']} numbers it learned "
            f"jointly: a permutation-invariant embedding of every individual's {', '.join(plan['features'])} (up to "
            f"{plan['max_individuals']} individuals) and of the series {', '.join(plan['series'])} in "
            f"{plan['series_length']} bins of the window"
            + (f", of each of the {flow['flocks']} observed flocks, their summaries pooled by their mean (the same "
               "whatever the flocks' order)." if flow.get("flocks", 1) > 1 else "."))


def chain_blocks(outcome, folder) -> list:
    """A chain's posterior (emcee, the emulator): its summary, trace, rank and corner plots."""
    report = outcome.report
    blocks = [Heading("Posterior"),
              Para(f"{report.get('walkers')} walkers x {report.get('steps')} steps, burn-in {report.get('burn')} "
                   "steps (2 x the largest autocorrelation time). tau and ess: emcee's integrated "
                   "autocorrelation time and effective sample size; r_hat, ess_bulk, ess_tail, mcse: ArviZ's "
                   "(walkers as chains). The full posterior is `posterior.nc` (ArviZ InferenceData)."),
              Table(outcome.summary.reset_index(), "Posterior summary (posterior.csv)")]
    blocks += _figure(folder, "trace.png", "Walkers' traces; the burn-in is shaded.")
    blocks += _figure(folder, "rank.png", "Rank plots: per parameter, each walker's rank histogram; flat "
                                          "histograms mean the walkers sample the same distribution.")
    blocks += _figure(folder, "corner.png", CORNER_CAPTION)
    return blocks


def draws_blocks(outcome, folder) -> list:
    """A posterior of independent draws (a method's default section): its summary and corner plot."""
    blocks = [Heading("Posterior"),
              Para(f"{outcome.report.get('draws')} independent posterior draws (split into 4 chains for ArviZ's "
                   "r_hat and ESS). The full posterior is `posterior.nc` (ArviZ InferenceData)."),
              Table(outcome.summary.reset_index(), "Posterior summary (posterior.csv)")]
    return blocks + _figure(folder, "corner.png", CORNER_CAPTION)


def optimum_blocks(outcome) -> list:
    """An optimisation's optimum and its objective."""
    optimum = pd.DataFrame([{"parameter": k, "optimum": v} for k, v in outcome.optimum["theta"].items()])
    return [Heading("Optimum"), Table(optimum, "Optimum (optimum.json)"),
            Para(f"Objective {outcome.optimum['objective_common_seeds']:.4g} with the search's common seeds, "
                 f"{outcome.optimum['objective_recheck']:.4g} +- {_se(outcome.optimum['recheck_se'])} "
                 "re-checked with fresh seeds.")]


def calibration_report(config, outcome, folder, method_blocks=()) -> dict:
    """Write report.html and report.md (see the module docstring); ``method_blocks``: the method's own
    section (its posterior or optimum, :meth:`~analysis.calibration.methods.base.CalibrationMethod.report_blocks`),
    placed after the verdicts."""
    report = outcome.report
    verdicts = verdict_lines(config, outcome)
    blocks = [Heading(f"Calibration report: {config.name}", 1)]
    if config.description:
        blocks.append(Para(config.description))
    blocks += [Heading("Verdicts")] + [Para(line) for line in verdicts]
    blocks += list(method_blocks)
    if outcome.predictive is not None:
        blocks += [Heading("Posterior predictive check"),
                   Table(outcome.predictive.reset_index(), "Each target against its predictive distribution (p: "
                                                           "two-sided tail probability)")]
        blocks += _figure(folder, "predictive.png", "Predictive distribution of each target, the observed value in red.")
    flock = getattr(outcome, "flock", None)
    if flock is not None:
        blocks += [Heading("The flock in the predictive runs"),
                   Table(flock.reset_index().rename(columns={"index": "statistic"}),
                         "Every flock statistic of the posterior predictive runs, targets or not, against the observed "
                         "flock where known (flock_check.csv; disagrees: outside the central 95% of the runs)")]
    blocks += _tracks_blocks(report.get("tracks"))
    blocks += _cost_blocks(report.get("accounting"))
    blocks += [Heading("Settings")] + _settings_tables(config)
    provenance = pd.DataFrame([{"item": "git revision", "value": report.get("git_revision")},
                               {"item": "model version", "value": report.get("model_version")},
                               {"item": "wall time (s)", "value": report.get("wall_s")},
                               {"item": "executor", "value": report.get("executor")},
                               {"item": "packages", "value": ", ".join(f"{k} {v}" for k, v in
                                                                      report.get("packages", {}).items() if v)}])
    blocks += [Heading("Provenance"), Table(provenance, "Provenance")]
    files = sorted({p.name for p in folder.root.iterdir() if p.is_file() and not p.name.startswith(".")}
                   | {"report.html", "report.md"})
    blocks += [Heading("Files"), Para(", ".join(f"`{name}`" for name in files))]
    written = {"md": folder.write_text("report.md", to_markdown(blocks, folder.root)),
               "html": folder.write_text("report.html", to_html(blocks, f"flocksweep calibration: {config.name}"))}
    return written


def _tracks_blocks(record: dict | None) -> list:
    """The tracks the targets were measured from: file, format, flocks, checks, and every unit and scale
    with its source (convergence.json's ``tracks``)."""
    if not record:
        return []
    scales = pd.DataFrame([{"unit or scale": name, "value": entry.get("value"), "from": entry.get("from")}
                           for name, entry in record.get("scales", {}).items()])
    checks = record.get("checks", {})
    return [Heading("The tracks"),
            Para(f"Targets measured from `{record.get('file')}` ({record.get('format')}, {record.get('dims')}-D, "
                 f"{len(record.get('flocks', []))} flocks); the checks found {checks.get('errors', 0)} errors and "
                 f"{checks.get('warnings', 0)} warnings (`flocksweep measure {record.get('file')}` lists them)."),
            Table(scales, "Every unit and scale used, and where it came from")]
