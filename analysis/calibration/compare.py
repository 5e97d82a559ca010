"""Model comparison: which of several models best explains the targets, by a classifier trained on
simulated statistics (the ABC model choice of Pudlo et al. 2016, with scikit-learn's histogram gradient
boosting in place of their random forest), its probabilities checked on held-out simulations whose true
model is known.

A comparison file (``flocksweep compare FILE``)::

    name = "compare_perception"
    seed = 1
    simulations = 1000          # per model: the classifier's training simulations (prior draws)
    heldout = 200               # per model: more, never trained on: the confusion matrix
    tracker_statistics = true   # optional: refuse statistics no tracker measures (visible_mean, visible_sd,
                                # binocular_share, the leadership statistics): a comparison of tracked flocks
    [models]                    # name = a calibration file: its [model], [run] and [parameters] (priors);
    metric = "recover_holland.toml"                  # its own [targets] and [method] are not used
    topological = "recover_holland_topological.toml"
    [run]                       # optional: keys set in every model's [run], for the data every model is
    duration = 30.0             # compared on (how long and how often the flock was observed, its size, ...)
    [targets]                   # as a calibration's: the statistics every model is compared on, observed values

Shapes: M models, N training and H held-out simulations per model, k statistics.

Contract
--------
``load_comparison(path, overrides=()) -> Comparison``: the file validated (errors name the key: the file's
own, or ``models.<name>.<key>`` for a model file's); each model is that calibration file with the
comparison's ``[targets]``, seed and ``[run]`` keys (set over the model file's), so it has every check of a
calibration (priors, keys, statistics). With ``tracker_statistics = true`` a statistic no tracker
measures (:data:`UNOBSERVABLE`: what a simulated boid perceives, the leadership statistics) is refused;
``Comparison.unobservable`` lists those a comparison uses (recorded in ``compare.json`` and the report).

``simulate_model(comparison, m, folder, ...) -> (theta (N + H, d_m), x (N + H, k), computed)``: model m's
prior draws ``[seed, Tag.COMPARE, DESIGN, m]`` run as a sweep into ``<out>/models/<name>`` (the npe
training sweep: content-addressed, resumable, every executor), the targets' measurement noise from
``[seed, Tag.COMPARE, NOISE, m]`` added (the data model of every method).

``fit_classifier(x (M N, k), labels, seed) -> classifier``: ``HistGradientBoostingClassifier`` with early
stopping on a 10 % validation share, random state from ``[seed, Tag.COMPARE, CLASSIFIER]``.

``model_choice(classifier, x_held, labels_held, observed (m, k), names) -> dict``: ``probabilities``
(m, M) the posterior model probabilities of each observed row (equal prior probabilities: the classes
are balanced), ``confusion`` (M, M) counts of held-out sets by true model (rows) and most probable model
(columns), ``confident`` (M,) the share of each model's held-out sets whose true model gets a probability
above ``CONFIDENT`` (0.9), ``accuracy``, and ``messages``.

``run_comparison(comparison, out, executor, workers, scheduler, progress) -> dict``: the whole command;
writes ``compare.json`` (everything above, simulations counted), ``confusion.csv``,
``model_probabilities.csv``, ``heldout_probabilities.csv``, ``report.md`` / ``report.html``.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from flocksweep.simcore.schema import ConfigError, build, check_at_least, read_config, read_toml, resolve_path
from flocksweep.sweeps.config import check_name
from flocksweep.sweeps.files import json_ready
from flocksweep.sweeps.seeds import CompareStream, Tag, generator
from flocksweep.sweeps.store import OutputFolder

from .config import CalibrationConfig, calibration_from_dict
from .simulator import summary_simulator
from .tracks_targets import UNOBSERVABLE

CONFIDENT = 0.9


@dataclass(frozen=True)
class CompareFile:
    name: str = field(metadata={"expected": "a non-empty string naming the comparison"})
    models: dict = field(metadata={"expected": 'a table of at least two models: [models] name = "calibration.toml"'})
    targets: dict = field(metadata={"expected": "a table: [targets] stats and mean/sd (as a calibration's)"})
    description: str = ""
    seed: int = 0
    simulations: int = 1000
    heldout: int = 200
    tracker_statistics: bool = False
    run: dict = field(default_factory=dict, metadata={"expected": "a table of [run] keys set in every model"})

    def __post_init__(self):
        check_name(self.name, "the comparison")
        check_at_least("seed", self.seed, 0)
        check_at_least("simulations", self.simulations, 20)
        check_at_least("heldout", self.heldout, 10)


@dataclass(frozen=True)
class Comparison:
    name: str
    description: str
    seed: int
    simulations: int
    heldout: int
    models: tuple                  # ((name, CalibrationConfig), ...)
    tracker_statistics: bool = False

    @property
    def names(self) -> list[str]:
        return [name for name, _ in self.models]

    @property
    def unobservable(self) -> list[str]:
        """The comparison's statistics that no tracker measures (none in a comparison of tracked flocks)."""
        return [stat for stat in self.targets.stats if stat in UNOBSERVABLE]

    @property
    def targets(self):
        return self.models[0][1].targets


def _model(name: str, value, table: CompareFile, base: Path) -> CalibrationConfig:
    if not isinstance(value, str):
        raise ConfigError(f"models.{name}", f"got {value!r}; expected the path of a calibration file")
    path = resolve_path(value, base, f"models.{name}", "calibration file")
    data = read_toml(path, "calibration file")
    run = data.get("run", {})
    data.update(name=f"{table.name}-{name}", seed=table.seed, targets=table.targets,
                method={"kind": "npe", "simulations": table.simulations, "heldout": table.heldout},
                run={**(run if isinstance(run, dict) else {}), **table.run})
    try:
        return calibration_from_dict(data, path.parent)
    except ConfigError as err:
        if err.key.startswith("run.") and err.key[4:].split(".")[0] in table.run:   # the comparison's own key
            raise ConfigError(err.key, f"(in model {name}, {path.name}) {err.detail}") from None
        raise ConfigError(f"models.{name}.{err.key}", f"({path.name}) {err.detail}") from None


def load_comparison(path, overrides=(), yes: bool = False) -> Comparison:
    """A comparison file, validated (module docstring); its simulations counted before any model is read
    (more than ``feasibility.MAX_SIMULATIONS`` need ``yes``, ``--yes``)."""
    from .feasibility import check_simulation_count

    path = Path(path)
    table = build(CompareFile, read_config(path, "comparison file", overrides))
    if isinstance(table.models, dict) and len(table.models) >= 2:
        count = len(table.models) * (table.simulations + table.heldout)
        check_simulation_count("simulations", count, yes, given=f"got {table.simulations:,}: {len(table.models)} models "
                               f"x ({table.simulations:,} + {table.heldout:,} held out) = ")
    if not isinstance(table.run, dict):
        raise ConfigError("run", f"got {table.run!r}; expected a table of [run] keys (duration = 30.0, ...)")
    if not isinstance(table.models, dict) or len(table.models) < 2:
        raise ConfigError("models", f"got {len(table.models) if isinstance(table.models, dict) else table.models!r} "
                                    "model(s); a comparison needs at least two: [models] name = \"calibration.toml\"")
    models = tuple((name, _model(name, value, table, path.resolve().parent)) for name, value in table.models.items())
    comparison = Comparison(table.name, table.description, table.seed, table.simulations, table.heldout, models,
                            table.tracker_statistics)
    if table.tracker_statistics and comparison.unobservable:
        raise ConfigError("targets.stats", f"{comparison.unobservable[0]!r} is not measured by a tracker (what a "
                                           "simulated boid perceives, or a leadership statistic), and this "
                                           "comparison has tracker_statistics = true: choose statistics of "
                                           "positions and velocities")
    return comparison


def simulate_model(comparison: Comparison, m: int, folder: Path, executor: str = "local", workers=None,
                   scheduler=None, progress: bool = False):
    """Model m's simulations (module docstring)."""
    from flocksweep.sweeps.runner import run_sweep

    name, config = comparison.models[m]
    count = comparison.simulations + comparison.heldout
    draws = config.prior.sample(generator(comparison.seed, Tag.COMPARE, int(CompareStream.DESIGN), m), count)
    theta = np.asarray(draws, dtype=float).reshape(count, -1)
    result = run_sweep(training_sweep(config, theta), None, Path(folder), executor=executor, workers=workers,
                       scheduler=scheduler, progress=progress)
    noise = generator(comparison.seed, Tag.COMPARE, int(CompareStream.NOISE), m)
    return theta, simulated_rows(config, theta, result.table, noise), len(result.plan.todo)


def training_sweep(config, theta: np.ndarray):
    """A model's prior draws as a sweep (one zipped axis over the free parameters' keys, one replicate, the
    model file's ``[model]`` (with the tank tracks declare, :func:`.tracks_targets.shared_tank`), ``[run]`` and
    seed; an integer key's values rounded, as the calibration's simulator rounds them): content-addressed, resumable runs on the sweep machinery."""
    from flocksweep.sweeps.config import SweepConfig

    source = config.source
    integer = summary_simulator(config, n_sim=1).integer_keys   # an integer key (init.n, neighbours) runs rounded
    rows = [[int(round(v)) if whole else float(v) for v, whole in zip(row, integer)] for row in theta]
    if any(integer) and len({tuple(row) for row in rows}) < len(rows):
        raise ConfigError("parameters", "rounded to integers, the prior draws repeat (a sweep runs each point once): "
                                        "an integer parameter needs a continuous one beside it for compare")
    values = rows if config.dim > 1 else [row[0] for row in rows]
    axis = {"keys": list(config.keys)} if config.dim > 1 else {"key": config.keys[0]}
    axis.update(name="prior_draw", values=values)
    model_set = dict(source.get("model", {}).get("set", {}))
    if config.targets.tank is not None:     # the tank the tracks declare, which the calibration put the model in
        model_set.update({f"arena.{k}": v for k, v in (config.preset_data.get("arena") or {}).items()
                          if f"arena.{k}" not in model_set})
    data = {"name": f"{config.name}-npe-training", "seed": int(config.seed), "replicates": 1,
            "model": {"preset": str(config.preset_path), "set": model_set},
            "run": dict(source.get("run", {})), "axes": [axis]}
    return SweepConfig.from_dict(data, config.preset_path.parent)


def simulated_rows(config, theta: np.ndarray, table: pd.DataFrame, noise: np.random.Generator) -> np.ndarray:
    """The runs table's target columns in design order (a failed run's row is NaN), plus, for mean/sd
    targets, the targets' measurement noise N(0, cov) from ``noise``."""
    columns = list(config.targets.columns)
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ConfigError("targets.stats", f"the training runs have no column {missing[0]!r}")
    rows = np.full((len(theta), len(columns)), np.nan)
    ok = table[table["status"] == "ok"]
    rows[ok["point_index"].to_numpy(dtype=int)] = ok[columns].to_numpy(dtype=float)
    cov = config.targets.cov
    if cov is not None:
        rows = rows + noise.multivariate_normal(np.zeros(len(cov)), cov, size=len(rows))
    return rows


def fit_classifier(x, labels, seed: int):
    from sklearn.ensemble import HistGradientBoostingClassifier

    state = int(generator(seed, Tag.COMPARE, int(CompareStream.CLASSIFIER)).integers(0, 2 ** 31 - 1))
    return HistGradientBoostingClassifier(early_stopping=True, validation_fraction=0.1, random_state=state).fit(x, labels)


def model_choice(classifier, x_held, labels_held, observed, names) -> dict:
    """Posterior model probabilities at the targets and the classifier's check on held-out sets."""
    held = classifier.predict_proba(np.asarray(x_held, dtype=float))
    labels_held = np.asarray(labels_held)
    size = len(names)
    confusion = np.zeros((size, size), dtype=int)
    np.add.at(confusion, (labels_held, held.argmax(axis=1)), 1)
    truth_probability = held[np.arange(len(labels_held)), labels_held]
    confident = np.array([np.mean(truth_probability[labels_held == m] > CONFIDENT) for m in range(size)])
    probabilities = classifier.predict_proba(np.atleast_2d(np.asarray(observed, dtype=float)))
    messages = [f"{names[m]}: the true model gets probability > {CONFIDENT} on {confident[m]:.1%} of its "
                f"{int((labels_held == m).sum())} held-out simulated sets" for m in range(size)]
    best = probabilities.mean(axis=0).argmax()
    messages.insert(0, f"the targets are best explained by {names[best]} (posterior model probability "
                       f"{probabilities[:, best].mean():.3f}" + (f", mean over {len(probabilities)} observed rows)"
                                                                 if len(probabilities) > 1 else ")"))
    return {"probabilities": probabilities, "confusion": confusion, "confident": confident,
            "accuracy": float(np.trace(confusion) / confusion.sum()), "heldout": held, "messages": messages}


def _log(progress: bool, message: str) -> None:
    if progress:
        print(message, file=sys.stderr)


def run_comparison(comparison: Comparison, out=None, executor: str = "local", workers=None, scheduler=None,
                   progress: bool = True) -> dict:
    """Simulate every model, train the classifier, check it, write the outputs (module docstring)."""
    folder = OutputFolder(Path(out) if out else Path("results") / "calibration" / comparison.name)
    n = comparison.simulations
    train_x, train_y, held_x, held_y, computed = [], [], [], [], {}
    with folder.lock():
        for m, name in enumerate(comparison.names):
            _log(progress, f"{comparison.name}: simulating model {name}")
            _, x, computed[name] = simulate_model(comparison, m, folder.path("models") / name, executor, workers,
                                                  scheduler, progress)
            usable = np.isfinite(x).all(axis=1)
            train, held = usable & (np.arange(len(x)) < n), usable & (np.arange(len(x)) >= n)
            train_x.append(x[train]), train_y.append(np.full(train.sum(), m))
            held_x.append(x[held]), held_y.append(np.full(held.sum(), m))
        _log(progress, f"{comparison.name}: training the classifier on {sum(map(len, train_x))} simulations")
        classifier = fit_classifier(np.vstack(train_x), np.concatenate(train_y), comparison.seed)
        choice = model_choice(classifier, np.vstack(held_x), np.concatenate(held_y), comparison.targets.observed,
                              comparison.names)
        _write(folder, comparison, choice, computed, np.concatenate(held_y))
    return {"folder": folder.root, **choice, "simulations": computed}


def _write(folder: OutputFolder, comparison: Comparison, choice: dict, computed: dict, held_labels) -> None:
    from flocksweep.analysis.reports.document import Heading, Para, Table, to_html, to_markdown

    names = comparison.names
    confusion = pd.DataFrame(choice["confusion"], index=pd.Index(names, name="true model"), columns=names)
    probabilities = pd.DataFrame(choice["probabilities"], columns=names)
    held = pd.DataFrame(choice["heldout"], columns=names).assign(true_model=[names[m] for m in held_labels])
    folder.write_csv("confusion.csv", confusion)
    folder.write_csv("model_probabilities.csv", probabilities, index=False)
    folder.write_csv("heldout_probabilities.csv", held, index=False)
    record = {"name": comparison.name, "seed": comparison.seed, "models": names,
              "statistics": list(comparison.targets.columns),
              "tracker_observable": not comparison.unobservable, "unobservable": comparison.unobservable,
              "probabilities": choice["probabilities"].tolist(), "confusion": choice["confusion"].tolist(),
              "confident_share": dict(zip(names, choice["confident"].tolist())), "confident_threshold": CONFIDENT,
              "accuracy": choice["accuracy"], "messages": choice["messages"],
              "simulations": {"per_model": comparison.simulations + comparison.heldout, "computed": computed,
                              "total_computed": int(sum(computed.values()))},
              **folder.provenance()}
    folder.write_json("compare.json", json_ready(record))
    share = pd.DataFrame({"model": names, f"share of held-out sets with true-model probability > {CONFIDENT}":
                          choice["confident"]})
    blocks = [Heading(f"Model comparison: {comparison.name}", 1)]
    if comparison.description:
        blocks.append(Para(comparison.description))
    blocks += [Heading("Verdicts")] + [Para(line) for line in choice["messages"]]
    blocks += [Heading("Posterior model probabilities of the targets"),
               Table(probabilities.reset_index(names="observed row"), "Equal prior probabilities "
                                                                       "(model_probabilities.csv)"),
               Heading("The classifier on held-out simulations"),
               Table(confusion.reset_index(), f"Confusion matrix: {comparison.heldout} held-out simulated sets per "
                                              f"model by true model (rows) and most probable model (columns); "
                                              f"accuracy {choice['accuracy']:.3f} (confusion.csv)"),
               Table(share, "How often the true model is named with confidence (heldout_probabilities.csv)"),
               Para(("Every statistic is measured by a tracker (positions and velocities only). " if not
                     comparison.unobservable else f"Not measured by a tracker: {', '.join(comparison.unobservable)} "
                     "(what a simulated boid perceives or a leadership statistic): this comparison cannot be made "
                     "from tracks. ") +
                    f"Statistics: {', '.join(comparison.targets.columns)}; {comparison.simulations} training and "
                    f"{comparison.heldout} held-out prior draws per model, each model's own priors; "
                    f"{int(sum(computed.values()))} simulations run by this invocation.")]
    folder.write_text("report.md", to_markdown(blocks, folder.root))
    folder.write_text("report.html", to_html(blocks, f"flocksweep comparison: {comparison.name}"))
