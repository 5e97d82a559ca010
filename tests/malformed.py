"""A catalogue of malformed inputs to the ``flocksweep`` command, each with the exit status and the words
its one-line message must contain (docs/errors.md). Used by tests/sweeps/test_faults.py and by
bench/fault_battery.py, which runs them all and counts those refused cleanly before any write.

A case is ``Case(name, argv, files, code, expect)``: ``files`` are written into an empty folder
(``{d}`` in argv and file texts is that folder, ``{holland}`` the shipped Holland preset), and ``links``
(name -> target) made there as symbolic links; ``argv`` runs there. A clean refusal: the exit status ``code``, stderr holding ``expect`` (case-insensitive) and no
traceback, and no file written (the folder holds exactly ``files`` afterwards).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from faults import FAULTY_PRESET   # the fault battery's plug-in preset (tests/faults.py)
from paths import ROOT

HOLLAND = str(ROOT / "configs" / "models" / "holland.toml")


@dataclass(frozen=True)
class Case:
    name: str
    argv: tuple
    files: dict = field(default_factory=dict)
    code: int = 2
    expect: str = ""
    may_write: str = ""   # a folder the refusal may write its report into (measure's validation.csv)
    links: dict = field(default_factory=dict)   # symbolic links made in the folder: name -> target
    specials: dict = field(default_factory=dict)  # special files made in the folder: name -> "fifo" or "socket"
    prepare: object = None   # called with the folder after the files are written (an estimator folder made)


SWEEP = """name = "tiny"
seed = 3
replicates = 1
{top}
[model]
preset = "{holland}"
{model}
[run]
n = 8
duration = 1.0
record_interval = 0.5
warmup = 0.5
{run}
{axes}
"""


def sweep_text(top="", model="", run="", axes='[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 180]\n'):
    return SWEEP.format(top=top, model=model, run=run, axes=axes, holland="{holland}")


def run_case(name, expect, code=2, *, top="", model="", run="", axes=None, args=(), text=None) -> Case:
    body = text if text is not None else sweep_text(top, model, run, axes if axes is not None else
                                                   '[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 180]\n')
    return Case(f"run: {name}", ("run", "{d}/s.toml", "--out", "{d}/out", "--executor", "serial", "--no-progress",
                                 *args), {"s.toml": body}, code, expect)


CALIBRATION = """name = "cal"
seed = 1
[model]
preset = "{holland}"
[run]
n = 8
duration = 1.0
record_interval = 0.5
warmup = 0.5
{run}
[parameters.field]
key = "{key}"
prior = {prior}
{extra_parameter}
[targets]
stats = {stats}
mean = {mean}
sd = {sd}
[method]
kind = "{kind}"
n_sim = {n_sim}
walkers = {walkers}
steps = {steps}
"""


def calibration_text(run="", key="perception.field_deg", prior='{ dist = "uniform", low = 60, high = 300 }',
                     extra_parameter="", stats='["cohesion", "polarization"]', mean="[0.9, 0.8]",
                     sd="[0.05, 0.05]", kind="emcee", n_sim=5, walkers=4, steps=3):
    return CALIBRATION.format(run=run, key=key, prior=prior, extra_parameter=extra_parameter, stats=stats,
                              mean=mean, sd=sd, kind=kind, n_sim=n_sim, walkers=walkers, steps=steps,
                              holland="{holland}")


def cal_case(name, expect, code=2, args=(), **changes) -> Case:
    return Case(f"calibrate: {name}", ("calibrate", "{d}/c.toml", "--out", "{d}/out", "--no-progress", *args),
                {"c.toml": calibration_text(**changes)}, code, expect)


def cli_case(name, argv, expect, code=2, files=None) -> Case:
    return Case(name, tuple(argv), dict(files or {}), code, expect)


GOOD_SWEEP = {"s.toml": sweep_text()}
GOOD_CAL = {"c.toml": calibration_text()}
RUN = ("run", "{d}/s.toml", "--out", "{d}/out", "--executor", "serial", "--no-progress")
AXIS = '[[axes]]\nkey = "{key}"\nvalues = {values}\n'

SWEEP_FILES = [
    Case("run: not UTF-8", RUN, {"s.toml": b'name = "t\xff"\n'}, 2, "not utf-8"),
    Case("run: latin-1 comment", RUN, {"s.toml": sweep_text().encode() + b"# caf\xe9\n"}, 2, "not utf-8"),
    Case("run: date value", RUN, {"s.toml": sweep_text(top="when = 1979-05-27")}, 2, "date"),
    Case("run: datetime value", RUN, {"s.toml": sweep_text(top="description = 1979-05-27T07:32:00Z")}, 2, "date"),
    Case("run: time in a list", RUN, {"s.toml": sweep_text(axes=AXIS.format(key="perception.field_deg",
                                                                              values="[07:32:00]"))}, 2, "date"),
    Case("run: broken TOML", RUN, {"s.toml": 'name = "x"\n[model\n'}, 2, "not valid toml"),
    Case("run: unterminated string", RUN, {"s.toml": 'name = "x\n'}, 2, "not valid toml"),
    Case("run: duplicate key", RUN, {"s.toml": 'name = "a"\nname = "b"\n'}, 2, "not valid toml"),
    Case("run: empty file", RUN, {"s.toml": ""}, 2, "name"),
    Case("run: missing file", ("run", "{d}/absent.toml", "--out", "{d}/out"), {}, 2, "not found"),
    Case("run: a folder as sweep file", ("run", "{d}", "--out", "{d}/out"), {}, 2, "is a folder"),
    Case("run: deeply nested arrays", RUN, {"s.toml": "a = " + "[" * 5000 + "]" * 5000 + "\n"}, 2, "toml"),
]

SWEEP_VALUES = [
    run_case("NUL in name", "name", top="", text=sweep_text().replace('name = "tiny"', 'name = "a\\u0000b"')),
    run_case("slash in name", "name", text=sweep_text().replace('name = "tiny"', 'name = "a/b"')),
    run_case("backslash in name", "name", text=sweep_text().replace('name = "tiny"', 'name = "a\\\\b"')),
    run_case("leading dot name", "name", text=sweep_text().replace('name = "tiny"', 'name = ".hidden"')),
    run_case("empty name", "name", text=sweep_text().replace('name = "tiny"', 'name = ""')),
    run_case("newline in name", "name", text=sweep_text().replace('name = "tiny"', 'name = "a\\nb"')),
    run_case("very long name", "name", text=sweep_text().replace('name = "tiny"', f'name = "{"x" * 300}"')),
    run_case("name a number", "name", text=sweep_text().replace('name = "tiny"', "name = 5")),
    run_case("typo top-level key", "did you mean", top='descripton = "x"'),
    run_case("seed a string", "seed", text=sweep_text().replace("seed = 3", 'seed = "a"')),
    run_case("seed negative", "seed", text=sweep_text().replace("seed = 3", "seed = -1")),
    run_case("replicates zero", "replicates", text=sweep_text().replace("replicates = 1", "replicates = 0")),
    run_case("replicates fractional", "replicates", text=sweep_text().replace("replicates = 1", "replicates = 1.5")),
    run_case("common_random_numbers a string", "common_random_numbers", top='common_random_numbers = "yes"'),
    run_case("no model table", "model", text=sweep_text().replace("[model]", "[modle]")),
    run_case("preset missing", "model.preset", text=sweep_text().replace("{holland}", "{d}/absent.toml")),
    run_case("preset path with NUL", "nul", text=sweep_text().replace("{holland}", "a\\u0000b.toml")),
    run_case("preset a folder", "model.preset", text=sweep_text().replace("{holland}", "{d}")),
    run_case("preset a number", "model.preset", text=sweep_text().replace('"{holland}"', "5")),
    run_case("model.set unknown key", "perception.fov", model='set = { "perception.fov" = 90 }'),
    run_case("model.set value out of range", "perception.field_deg", model='set = { "perception.field_deg" = 400 }'),
    run_case("model.set wrong type", "perception.range", model='set = { "perception.range" = "far" }'),
    run_case("model.set a list", "model.set", model="set = [1, 2]"),
    run_case("unknown [run] key", "did you mean", run="durration = 2.0"),
    run_case("run.n zero", "init.n", text=sweep_text().replace("n = 8", "n = 0")),
    run_case("run.n negative", "init.n", text=sweep_text().replace("n = 8", "n = -5")),
    run_case("run.n 9e18", "memory", text=sweep_text().replace("n = 8", "n = 9000000000000000000")),
    run_case("run.n 1e12", "memory", text=sweep_text().replace("n = 8", "n = 1000000000000")),
    run_case("run.n fractional", "n", text=sweep_text().replace("n = 8", "n = 8.5")),
    run_case("run.n a string", "n", text=sweep_text().replace("n = 8", 'n = "eight"')),
    run_case("duration zero", "run.duration", text=sweep_text().replace("duration = 1.0", "duration = 0.0")),
    run_case("duration negative", "run.duration", text=sweep_text().replace("duration = 1.0", "duration = -1.0")),
    run_case("duration nan", "run.duration", text=sweep_text().replace("duration = 1.0", "duration = nan")),
    run_case("duration inf", "run.duration", text=sweep_text().replace("duration = 1.0", "duration = inf")),
    run_case("duration not whole steps", "run.duration", text=sweep_text().replace("duration = 1.0", "duration = 1.001")),
    run_case("dt zero", "run.dt", run="dt = 0.0"),
    run_case("dt negative", "run.dt", run="dt = -0.01"),
    run_case("record_interval not a multiple of dt", "run.record_interval",
             text=sweep_text().replace("record_interval = 0.5", "record_interval = 0.51")),
    run_case("record_interval beyond duration", "run.record_interval",
             text=sweep_text().replace("record_interval = 0.5", "record_interval = 2.0")),
    run_case("warmup equals duration", "run.warmup", text=sweep_text().replace("warmup = 0.5", "warmup = 1.0")),
    run_case("warmup beyond duration", "run.warmup", text=sweep_text().replace("warmup = 0.5", "warmup = 5.0")),
    run_case("warmup negative", "warmup", text=sweep_text().replace("warmup = 0.5", "warmup = -1.0")),
    run_case("group_radius a word", "group_radius", run='group_radius = "wide"'),
    run_case("group_radius negative", "group_radius", run="group_radius = -2"),
    run_case("fragmentation_cohesion a string", "fragmentation_cohesion", run='fragmentation_cohesion = "half"'),
    run_case("keep unknown", "keep", run='keep = "everything"'),
    run_case("trajectory_every zero", "trajectory_every", run="trajectory_every = 0"),
    run_case("leadership_metrics unknown", "leadership_metrics", run='leadership_metrics = "sometimes"'),
    run_case("axis without key", "axes[0]", axes="[[axes]]\nvalues = [1, 2]\n"),
    run_case("axis key and keys", "axes[0]", axes='[[axes]]\nkey = "n"\nkeys = ["n", "n"]\nvalues = [1]\n'),
    run_case("axis empty values", "axes[0].values", axes=AXIS.format(key="perception.field_deg", values="[]")),
    run_case("axis values not a list", "axes[0]", axes=AXIS.format(key="perception.field_deg", values="60")),
    run_case("axis value out of range", "perception.field_deg", axes=AXIS.format(key="perception.field_deg",
                                                                                 values="[60, 400]")),
    run_case("axis value wrong type", "perception.field_deg", axes=AXIS.format(key="perception.field_deg",
                                                                               values='["wide"]')),
    run_case("axis values repeat", "repeat", axes=AXIS.format(key="perception.field_deg", values="[60, 60]")),
    run_case("axis values resolve equal", "same parameters", axes=AXIS.format(key="perception.field_deg",
                                                                              values="[60, 60.0]")),
    run_case("axis unknown key", "perception.fov", axes=AXIS.format(key="perception.fov", values="[1, 2]")),
    run_case("axis key a number", "axes[0].key", axes="[[axes]]\nkey = 5\nvalues = [1, 2]\n"),
    run_case("axis key of another perception kind", "perception.radius",
             axes=AXIS.format(key="perception.radius", values="[5, 6]")),
    run_case("zipped axis with one key", "axes[0].keys",
             axes='[[axes]]\nkeys = ["perception.field_deg"]\nvalues = [[60]]\n'),
    run_case("zipped axis wrong arity", "axes[0].values[0]",
             axes='[[axes]]\nkeys = ["perception.field_deg", "perception.range"]\nvalues = [[60]]\n'),
    run_case("labels count mismatch", "axes[0].labels",
             axes='[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 180]\nlabels = ["a"]\n'),
    run_case("linspace num zero", "num", axes='[[axes]]\nkey = "perception.field_deg"\nlinspace = { start = 60, stop = 180, num = 0 }\n'),
    run_case("linspace start nan", "start", axes='[[axes]]\nkey = "perception.field_deg"\nlinspace = { start = nan, stop = 180, num = 3 }\n'),
    run_case("range negative step", "range", axes='[[axes]]\nkey = "perception.field_deg"\nrange = { start = 60, stop = 180, step = -10 }\n'),
    run_case("values and linspace", "axes[0]", axes='[[axes]]\nkey = "perception.field_deg"\nvalues = [60]\nlinspace = { start = 60, stop = 180, num = 3 }\n'),
    run_case("reserved axis name", "axes[0].name", axes='[[axes]]\nname = "status"\nkey = "perception.field_deg"\nvalues = [60, 180]\n'),
    run_case("key swept twice", "swept twice", axes=AXIS.format(key="perception.field_deg", values="[60, 180]") * 2),
    run_case("axis n of 1e12 boids", "memory", axes=AXIS.format(key="init.n", values="[10, 1000000000000]")),
    run_case("axis n of 1e6 boids", "memory", axes=AXIS.format(key="init.n", values="[10, 1000000]")),
    run_case("design of 1e9 runs", "split it", axes=AXIS.format(key="perception.field_deg", values=str(list(range(1, 361))))
             + AXIS.format(key="perception.range", values=str(list(range(1, 1001))))
             + AXIS.format(key="perception.direction_deg", values=str(list(range(0, 90))))
             + AXIS.format(key="steering.cohesion_weight", values=str(list(range(1, 31))))),
    run_case("design of 200000 runs", "--yes", text=sweep_text().replace("replicates = 1", "replicates = 100000")),
    run_case("axis duration below warmup", "run.warmup", axes=AXIS.format(key="run.duration", values="[0.5, 1.0]")),
    run_case("sample method unknown", "sample.method", top="", axes='[sample]\nmethod = "grid"\nn = 4\nbounds = { "perception.field_deg" = [30, 360] }\n'),
    run_case("sample n zero", "sample.n", axes='[sample]\nn = 0\nbounds = { "perception.field_deg" = [30, 360] }\n'),
    run_case("sample without bounds", "sample.bounds", axes="[sample]\nn = 4\n"),
    run_case("sample bounds reversed", "sample.bounds", axes='[sample]\nn = 4\nbounds = { "perception.field_deg" = [360, 30] }\n'),
    run_case("sample bounds not numbers", "sample.bounds", axes='[sample]\nn = 4\nbounds = { "perception.field_deg" = ["a", "b"] }\n'),
    run_case("sample bounds outside the range", "perception.field_deg", axes='[sample]\nn = 4\nbounds = { "perception.field_deg" = [30, 720] }\n'),
    run_case("report not a table", "report", top="report = 5"),
]

RUN_FLAGS = [
    cli_case("run: --workers 0", RUN + ("--workers", "0"), "--workers", files=GOOD_SWEEP),
    cli_case("run: --workers -1", RUN + ("--workers", "-1"), "--workers", files=GOOD_SWEEP),
    cli_case("run: --workers 100000", ("run", "{d}/s.toml", "--out", "{d}/out", "--workers", "100000"), "--workers",
             files=GOOD_SWEEP),
    cli_case("run: --replicates 0", RUN + ("--replicates", "0"), "--replicates", files=GOOD_SWEEP),
    cli_case("run: --replicates -3", RUN + ("--replicates", "-3"), "--replicates", files=GOOD_SWEEP),
    cli_case("run: --replicates 1e9", RUN + ("--replicates", "1000000000"), "split it", files=GOOD_SWEEP),
    cli_case("run: --replicates 60000", RUN + ("--replicates", "60000"), "--yes", files=GOOD_SWEEP),
    cli_case("run: --dry-run --replicates 60000", RUN + ("--replicates", "60000", "--dry-run"), "--yes",
             files=GOOD_SWEEP),
    cli_case("run: --batch-size 0", RUN + ("--batch-size", "0"), "--batch-size", files=GOOD_SWEEP),
    cli_case("run: --batch-size -1", RUN + ("--batch-size", "-1"), "--batch-size", files=GOOD_SWEEP),
    cli_case("run: --max-replicates 0", RUN + ("--until-ci", "cohesion=0.05", "--max-replicates", "0"),
             "--max-replicates", files=GOOD_SWEEP),
    cli_case("run: --max-replicates below replicates", RUN + ("--until-ci", "cohesion=0.05", "--max-replicates", "1",
                                                             "--replicates", "2"), "--max-replicates", files=GOOD_SWEEP),
    cli_case("run: --until-ci without =", RUN + ("--until-ci", "cohesion"), "--until-ci", files=GOOD_SWEEP),
    cli_case("run: --until-ci not a number", RUN + ("--until-ci", "cohesion=abc"), "--until-ci", files=GOOD_SWEEP),
    cli_case("run: --until-ci negative", RUN + ("--until-ci", "cohesion=-0.1"), "--until-ci", files=GOOD_SWEEP),
    cli_case("run: --until-ci infinite", RUN + ("--until-ci", "cohesion=inf"), "--until-ci", files=GOOD_SWEEP),
    cli_case("run: --until-ci misspelt metric", RUN + ("--until-ci", "cohesoin=0.05"), "did you mean",
             files=GOOD_SWEEP),
    cli_case("run: --until-ci with --dry-run", RUN + ("--until-ci", "cohesion=0.05", "--dry-run"), "--dry-run",
             files=GOOD_SWEEP),
    cli_case("run: --scheduler without dask", RUN + ("--scheduler", "tcp://127.0.0.1:1"), "--scheduler",
             files=GOOD_SWEEP),
    cli_case("run: --scheduler empty", ("run", "{d}/s.toml", "--out", "{d}/out", "--executor", "dask", "--scheduler",
                                        " "), "--scheduler", files=GOOD_SWEEP),
    cli_case("run: --scheduler not an address", ("run", "{d}/s.toml", "--out", "{d}/out", "--executor", "dask",
                                                 "--scheduler", "nonsense"), "not a dask address", files=GOOD_SWEEP),
    cli_case("run: --scheduler where nobody listens", ("run", "{d}/s.toml", "--out", "{d}/out", "--executor", "dask",
                                                       "--scheduler", "tcp://127.0.0.1:9"), "no dask scheduler answered",
             files=GOOD_SWEEP),
    cli_case("run: --set without =", RUN + ("--set", "seed"), "key=value", files=GOOD_SWEEP),
    cli_case("run: --set unknown key", RUN + ("--set", "sede=3"), "did you mean", files=GOOD_SWEEP),
    cli_case("run: --set a date", RUN + ("--set", "description=2024-01-01"), "date", files=GOOD_SWEEP),
    cli_case("run: --set bad value", RUN + ("--set", "run.duration=-1"), "run.duration", files=GOOD_SWEEP),
    cli_case("run: --set model key out of range", RUN + ("--set", "model.perception.field_deg=999"),
             "perception.field_deg", files=GOOD_SWEEP),
    cli_case("run: --set empty key part", RUN + ("--set", "run..duration=2"), "dotted", files=GOOD_SWEEP),
    cli_case("run: --out an existing file", ("run", "{d}/s.toml", "--out", "{d}/s.toml"), "--out", files=GOOD_SWEEP),
    cli_case("run: --out below a file", ("run", "{d}/s.toml", "--out", "{d}/s.toml/sub"), "--out", files=GOOD_SWEEP),
    cli_case("run: --out with NUL", ("run", "{d}/s.toml", "--out", "{d}/a\0b"), "--out", files=GOOD_SWEEP),
    cli_case("run: --dry-run of 1e12 boids", RUN + ("--dry-run", "--set", "run.n=1000000000000"), "memory",
             files=GOOD_SWEEP),
    cli_case("run: --workers beyond memory", ("run", "{d}/s.toml", "--out", "{d}/out", "--workers", "16", "--set",
                                             "run.n=40000", "--set", "run.duration=0.5", "--set", "run.warmup=0.1"),
             "memory", files=GOOD_SWEEP),
]

SIMULATE = ("simulate", HOLLAND, "--out", "{d}/out")
SIMULATE_FLAGS = [
    cli_case("simulate: --seed -1", SIMULATE + ("--seed", "-1"), "--seed"),
    cli_case("simulate: --record-every 0", SIMULATE + ("--record-every", "0"), "--record-every"),
    cli_case("simulate: --n 0", SIMULATE + ("--n", "0"), "init.n"),
    cli_case("simulate: --n -3", SIMULATE + ("--n", "-3"), "init.n"),
    cli_case("simulate: --n 9e18", SIMULATE + ("--n", "9000000000000000000"), "memory"),
    cli_case("simulate: --duration nan", SIMULATE + ("--duration", "nan"), "run.duration"),
    cli_case("simulate: --duration 0", SIMULATE + ("--duration", "0"), "run.duration"),
    cli_case("simulate: --duration -5", SIMULATE + ("--duration", "-5"), "run.duration"),
    cli_case("simulate: --dt 0", SIMULATE + ("--dt", "0"), "run.dt"),
    cli_case("simulate: --dt inf", SIMULATE + ("--dt", "inf"), "run.dt"),
    cli_case("simulate: --set unknown", SIMULATE + ("--set", "perception.fov=3"), "perception.fov"),
    cli_case("simulate: --set a date", SIMULATE + ("--set", "description=2024-01-01"), "date"),
    cli_case("simulate: --out an existing file", ("simulate", HOLLAND, "--out", "{d}/f.txt"), "--out",
             files={"f.txt": "mine"}),
    cli_case("simulate: model not UTF-8", ("simulate", "{d}/m.toml", "--out", "{d}/out"), "utf-8",
             files={"m.toml": b'name = "\xfe"\n'}),
    cli_case("simulate: model with a date", ("simulate", "{d}/m.toml", "--out", "{d}/out"), "date",
             files={"m.toml": 'name = "m"\ndescription = 2020-02-02\n'}),
    cli_case("simulate: model missing", ("simulate", "{d}/m.toml", "--out", "{d}/out"), "not found"),
    cli_case("simulate: model unknown key", ("simulate", "{d}/m.toml", "--out", "{d}/out"), "did you mean",
             files={"m.toml": 'name = "m"\ndynamic = "opensteer"\n'}),
    cli_case("simulate: model kind mismatch", ("simulate", "{d}/m.toml", "--out", "{d}/out"), "perception.kind",
             files={"m.toml": 'dynamics = "hartman_benes"\n[perception]\nkind = "binocular"\n'}),
    cli_case("simulate: 1e6 boids for 10^4 steps", SIMULATE + ("--n", "1000000", "--duration", "200"), "memory"),
]

CALIBRATE = [
    cal_case("prior beyond the range", "parameters.field.prior", prior='{ dist = "uniform", low = 30, high = 400 }'),
    cal_case("prior below zero", "parameters.field.prior", prior='{ dist = "uniform", low = -10, high = 300 }'),
    cal_case("bounds beyond the range", "parameters.field.bounds",
             prior='{ dist = "normal", mean = 100, sd = 50 }\nbounds = [10, 500]'),
    cal_case("integer prior reaching 0", "parameters.size.prior", key="init.n",
             prior='{ dist = "uniform", low = 0, high = 30 }'),
    cal_case("range prior below 0", "parameters.field.prior", key="perception.range",
             prior='{ dist = "uniform", low = -5, high = 30 }'),
    cal_case("n prior of 1e12 boids", "memory", key="init.n",
             prior='{ dist = "uniform", low = 5, high = 1000000000000 }'),
    cal_case("parameter key unknown", "parameters.field.key", key="perception.fov"),
    cal_case("parameter key not numeric", "parameters.field.key", key="perception.kind"),
    cal_case("normal prior without bounds", "parameters.field.bounds", prior='{ dist = "normal", mean = 100, sd = 50 }'),
    cal_case("prior unknown family", "parameters.field.prior", prior='{ dist = "cauchy", low = 1, high = 2 }'),
    cal_case("prior low above high", "parameters.field.prior", prior='{ dist = "uniform", low = 300, high = 60 }'),
    cal_case("unknown stat", "targets.stats", stats='["cohesoin", "polarization"]'),
    cal_case("stat twice", "targets.stats", stats='["cohesion", "cohesion"]'),
    cal_case("mean of the wrong length", "targets.mean", mean="[0.9]"),
    cal_case("negative sd", "targets.sd", sd="[-0.05, 0.05]"),
    cal_case("sd a string", "targets.sd", sd='"small"'),
    cal_case("mean with nan", "targets.mean", mean="[nan, 0.8]"),
    cal_case("method kind unknown", "method.kind", kind="mcmc"),
    cal_case("n_sim too small", "method.n_sim", n_sim=2),
    cal_case("walkers odd", "method.walkers", walkers=5),
    cal_case("walkers too few", "method.walkers", walkers=0),
    cal_case("steps zero", "steps", steps=0),
    Case("calibrate: warmup at duration", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text().replace("warmup = 0.5", "warmup = 1.0")}, 2, "run.warmup"),
    Case("calibrate: record_interval beyond duration", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text().replace("record_interval = 0.5", "record_interval = 2.0")}, 2,
         "run.record_interval"),
    cal_case("--workers 0", "--workers", args=("--workers", "0")),
    cal_case("--workers 10^5", "--workers", args=("--executor", "local", "--workers", "100000")),
    cal_case("--scheduler without dask", "--scheduler", args=("--scheduler", "tcp://x:1")),
    cal_case("--set unknown key", "did you mean", args=("--set", "method.stpes=3")),
    cal_case("--scheduler not an address", "not a dask address", args=("--executor", "dask", "--scheduler", "x:y:z")),
    cal_case("--set date", "date", args=("--set", "description=1999-01-01")),
    cal_case("date in the file", "date", run="when = 1999-01-01"),
]
CALIBRATE += [
    Case("calibrate: not UTF-8", ("calibrate", "{d}/c.toml", "--out", "{d}/out"), {"c.toml": b"name = \"\xc3\x28\"\n"},
         2, "not utf-8"),
    Case("calibrate: NUL in name", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text().replace('name = "cal"', 'name = "c\\u0000"')}, 2, "name"),
    Case("calibrate: --out an existing file", ("calibrate", "{d}/c.toml", "--out", "{d}/c.toml"), GOOD_CAL, 2, "--out"),
    Case("calibrate: samples file missing", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text().replace("mean = [0.9, 0.8]\nsd = [0.05, 0.05]", 'samples = "obs.csv"')},
         2, "targets.samples"),
    Case("calibrate: samples not numeric", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text().replace("mean = [0.9, 0.8]\nsd = [0.05, 0.05]", 'samples = "obs.csv"'),
          "obs.csv": "cohesion,polarization\nhigh,low\n"}, 2, "targets.samples"),
    Case("calibrate: cov not positive definite", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text().replace("sd = [0.05, 0.05]", "cov = [[1, 2], [2, 1]]")}, 2, "targets.cov"),
    Case("calibrate: same key twice", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text(extra_parameter='[parameters.other]\nkey = "perception.field_deg"\n'
                                                     'prior = { dist = "uniform", low = 60, high = 300 }')},
         2, "parameters.other.key"),
]
# "integer prior reaching 0" names its parameter "size": rename the table in its file
_size = [i for i, c in enumerate(CALIBRATE) if c.name == "calibrate: integer prior reaching 0"][0]
CALIBRATE[_size] = Case(CALIBRATE[_size].name, CALIBRATE[_size].argv,
                        {"c.toml": CALIBRATE[_size].files["c.toml"].replace("[parameters.field]", "[parameters.size]")},
                        2, "parameters.size.prior")

TARGETS = ("targets", "{d}/c.toml", "--truth", "field=150")
TARGETS_FLAGS = [
    cli_case("targets: --sd not numbers", TARGETS + ("--sd", "a,b"), "--sd", files=GOOD_CAL),
    cli_case("targets: --sd wrong count", TARGETS + ("--sd", "0.1"), "--sd", files=GOOD_CAL),
    cli_case("targets: --sd negative", TARGETS + ("--sd", "-1,2"), "--sd", files=GOOD_CAL),
    cli_case("targets: --sd empty item", TARGETS + ("--sd", "0.1,"), "--sd", files=GOOD_CAL),
    cli_case("targets: --truth not a number", ("targets", "{d}/c.toml", "--truth", "field=abc"), "--truth",
             files=GOOD_CAL),
    cli_case("targets: --truth unknown name", ("targets", "{d}/c.toml", "--truth", "feild=150"), "did you mean",
             files=GOOD_CAL),
    cli_case("targets: --truth without =", ("targets", "{d}/c.toml", "--truth", "field"), "--truth", files=GOOD_CAL),
    cli_case("targets: --truth nan", ("targets", "{d}/c.toml", "--truth", "field=nan"), "--truth", files=GOOD_CAL),
    cli_case("targets: --truth out of range", ("targets", "{d}/c.toml", "--truth", "field=999"),
             "--truth", files=GOOD_CAL),
    cli_case("targets: --replicates 0", TARGETS + ("--replicates", "0"), "--replicates", files=GOOD_CAL),
    cli_case("targets: --seed -1", TARGETS + ("--seed", "-1"), "--seed", files=GOOD_CAL),
]

SBC = ("sbc", "{d}/c.toml", "--out", "{d}/out", "--no-progress")
SBC_FLAGS = [
    cli_case("sbc: --datasets 0", SBC + ("--datasets", "0"), "--datasets", files=GOOD_CAL),
    cli_case("sbc: --draws 0", SBC + ("--draws", "0"), "--draws", files=GOOD_CAL),
    cli_case("sbc: --workers 0", SBC + ("--workers", "0"), "--workers", files=GOOD_CAL),
    cli_case("sbc: --steps 0", SBC + ("--steps", "0"), "--steps", files=GOOD_CAL),
    cli_case("sbc: --walkers 1", SBC + ("--walkers", "1"), "--walkers", files=GOOD_CAL),
    cli_case("sbc: --out a file", ("sbc", "{d}/c.toml", "--out", "{d}/c.toml"), "--out", files=GOOD_CAL),
    cli_case("sbc: optimize method", SBC, "method.kind",
             files={"c.toml": calibration_text(kind="optimize").replace("walkers = 4\nsteps = 3\n", "")}),
]

READERS = [
    cli_case("status: no such folder", ("status", "{d}/nothing"), "no sweep"),
    cli_case("status: a folder without a sweep", ("status", "{d}"), "no sweep", files={"x.txt": "x"}),
    cli_case("status: garbage design", ("status", "{d}"), "design.parquet", files={"design.parquet": b"garbage"}),
    cli_case("report: no such folder", ("report", "{d}/nothing"), "design.parquet"),
    cli_case("report: garbage design", ("report", "{d}"), "design.parquet", files={"design.parquet": b"\x00" * 64}),
    cli_case("report: --seed -1", ("report", "{d}", "--seed", "-1"), "--seed"),
    cli_case("report: --out a file", ("report", "{d}", "--out", "{d}/x.txt"), "--out", files={"x.txt": "mine"}),
    cli_case("view: no such source", ("view", "{d}/nothing.toml"), "no such file"),
    cli_case("view: a sweep file", ("view", "{d}/s.toml"), "sweep file", files=GOOD_SWEEP),
    cli_case("view: --replicate -1", ("view", HOLLAND, "--replicate", "-1"), "only applies"),
    cli_case("view: bad --size", ("view", HOLLAND, "--size", "big", "--out", "{d}/p.html"), "--size"),
    cli_case("view: --size 100000x100000", ("view", HOLLAND, "--size", "100000x100000", "--animate", "{d}/a.gif",
                                            "--no-page"), "--size: got '100000x100000'; each side must be from 16 to 3840"),
    cli_case("view: --size 8x8", ("view", HOLLAND, "--size", "8x8", "--animate", "{d}/a.gif", "--no-page"),
             "from 16 to 3840"),
    cli_case("view: --seed -1", ("view", HOLLAND, "--seed", "-1", "--out", "{d}/p.html"), "--seed"),
    cli_case("view: --trail -2", ("view", HOLLAND, "--trail", "-2", "--out", "{d}/p.html"), "--trail"),
    cli_case("view: --n 1e12", ("view", HOLLAND, "--n", "1000000000000", "--out", "{d}/p.html"), "memory"),
    cli_case("sbc: other settings in the folder", SBC, "--out", files={
        **GOOD_CAL, "out/settings.json": '{"method": "sbc", "seed": 99}'}),
]

LINSPACE = '[[axes]]\nkey = "perception.field_deg"\nlinspace = {{ start = 1, stop = 360, num = {num} }}\n'
SALTELLI = ('[design]\nkind = "saltelli"\nn = {n}\nbounds = {{ "perception.field_deg" = [60, 300], '
            '"perception.range" = [5, 20] }}\n')

# sizes: counted before anything is allocated (numbers), special and oversized files (paths)
SIZES = [
    run_case("linspace of 1e9 values", "split it", axes=LINSPACE.format(num=1000000000)),
    run_case("linspace of 2^63 values", "split it", axes=LINSPACE.format(num=2 ** 63 - 1)),
    run_case("range with a step of 1e-9", "split it",
             axes='[[axes]]\nkey = "perception.field_deg"\nrange = { start = 1, stop = 360, step = 1e-9 }\n'),
    cli_case("run: --axis linspace of 1e9 values", ("run", "--model", HOLLAND, "--axis",
                                                    "perception.field_deg=linspace(1,360,1000000000)", "--out",
                                                    "{d}/out", "--no-progress"), "split it"),
    run_case("saltelli n of 2^40", "design.n", axes=SALTELLI.format(n=2 ** 40)),
    cal_case("10^7 walkers without --yes", "--yes", walkers=10_000_000),
    Case("calibrate: npe of 3e7 simulations without --yes", ("calibrate", "{d}/c.toml", "--out", "{d}/out"),
         {"c.toml": calibration_text().split("[method]")[0] + '[method]\nkind = "npe"\n[method.npe]\n'
                                                             'simulations = 30000000\n'}, 2, "--yes"),
]

SPECIAL_FILES = [
    Case("run: /dev/zero as sweep file", ("run", "/dev/zero", "--out", "{d}/out"), {}, 2, "not a regular file"),
    Case("run: a missing sweep file is not blamed on NUL", ("run", "{d}/absent.toml", "--out", "{d}/out"), {}, 2,
         "sweep file not found: "),
    run_case("init.from_file /dev/zero", "not a regular file", model='set = { "init.from_file" = "/dev/zero" }'),
    run_case("init.from_file a folder", "is a folder", model='set = { "init.from_file" = "{d}" }'),
    cli_case("simulate: --init-state /dev/zero", ("simulate", HOLLAND, "--init-state", "/dev/zero", "--out",
                                                  "{d}/out"), "not a regular file"),
    cli_case("simulate: --init-state a folder", ("simulate", HOLLAND, "--init-state", "{d}", "--out", "{d}/out"),
             "is a folder"),
    cli_case("report: --claims /dev/zero", ("report", "{d}", "--claims", "/dev/zero"), "design.parquet"),
]

# numbers that overflow, tables and expressions nested or sized beyond reason (each once caught as a traceback)
NUMBERS = [
    run_case("--set run.duration=1e308", "run.duration", args=("--set", "run.duration=1e308")),
    run_case("--set model.run.dt=1e-300", "run.dt", args=("--set", "model.run.dt=1e-300")),
    run_case("duration 1e308 in the file", "run.duration", text=sweep_text().replace("duration = 1.0",
                                                                                      "duration = 1e308")),
    cli_case("simulate: --record-every 1e20", SIMULATE + ("--record-every", "100000000000000000000"),
             "--record-every"),
    cli_case("simulate: --duration 1e-9", SIMULATE + ("--duration", "1e-9"), "run.duration"),
]

TABLES = [
    run_case("an axis named like a metric column", "axes[0].name",
             axes='[[axes]]\nname = "cohesion_mean"\nkey = "perception.field_deg"\nvalues = [60, 180]\n'),
    run_case("an axis named like a report statistic", "axes[0].name",
             axes='[[axes]]\nname = "mean"\nkey = "perception.field_deg"\nvalues = [60, 180]\n'),
    run_case("an axis named ''", "axes[0].name",
             axes='[[axes]]\nname = ""\nkey = "perception.field_deg"\nvalues = [60, 180]\n'),
    run_case("labels that repeat", "labels repeat",
             axes='[[axes]]\nkey = "perception.field_deg"\nvalues = [60, 180]\nlabels = ["a", "a"]\n'),
    run_case("a dotted key 3,000 deep", "toml", top="a" + ".a" * 3000 + " = 1"),
    run_case("a table header 3,000 deep", "toml", top="[" + "a." * 3000 + "a]"),
    run_case("a --set key 3,000 deep", "unknown key", args=("--set", "a" + ".a" * 3000 + "=1")),
]

EXPRESSIONS = [
    run_case("a claim condition of 3,000 nested not", "claims[0]", top="", axes=AXIS.format(
        key="perception.field_deg", values="[60, 180]") + '[[claims]]\nid = "c"\nstatement = "s"\ntest = "trend"\n'
        'metric = "polarization_mean"\nfactor = "perception.field_deg"\ndirection = "increasing"\n'
        f'condition = "{"not " * 3000}fragmented"\n'),
    run_case("a claim metric of 20,000 terms", "claims[0]", axes=AXIS.format(
        key="perception.field_deg", values="[60, 180]") + '[[claims]]\nid = "c"\nstatement = "s"\ntest = "trend"\n'
        f'metric = "{"+".join(["cohesion_mean"] * 20000)}"\nfactor = "perception.field_deg"\n'
        'direction = "increasing"\n'),
]

TRACK = "id,t,x,y,z\n1,0,0,0,0\n1,1,1,0,0\n1,2,2,0,0\n2,0,0,1,0\n2,1,1,1,0\n2,2,2,1,0\n"
MEASURE = ("measure", "{d}/t.csv", "--group-radius", "5", "--no-figures", "--no-progress", "--out", "{d}/out")

# output paths that cannot be a folder: each named as --out, exit 2, before anything is written
OUT_PATHS = [
    Case("run: --out a dangling symbolic link", RUN[:3] + ("{d}/dangling",) + RUN[4:], GOOD_SWEEP, 2,
         "dangling is a symbolic link to 'nowhere', which does not exist",
         links={"dangling": "nowhere"}),
    Case("run: --out a symbolic link loop", RUN[:3] + ("{d}/loop1",) + RUN[4:], GOOD_SWEEP, 2, "symbolic link in a loop",
         links={"loop1": "loop2", "loop2": "loop1"}),
    Case("run: --out below a symbolic link loop", RUN[:3] + ("{d}/loop1/sub",) + RUN[4:], GOOD_SWEEP, 2,
         "--out: ", links={"loop1": "loop2", "loop2": "loop1"}),
    Case("calibrate: --out a dangling symbolic link", ("calibrate", "{d}/c.toml", "--out", "{d}/dangling"), GOOD_CAL,
         2, "--out: ", links={"dangling": "nowhere"}),
    Case("measure: --out an existing file", ("measure", "{d}/t.csv", "--group-radius", "5", "--no-figures", "--out",
                                             "{d}/t.csv"), {"t.csv": TRACK}, 2, "is a file; expected a folder"),
    Case("measure: --out a symbolic link loop", ("measure", "{d}/t.csv", "--group-radius", "5", "--no-figures", "--out",
                                                 "{d}/loop1"), {"t.csv": TRACK}, 2, "--out: ",
         links={"loop1": "loop2", "loop2": "loop1"}),
]

MEASURE_FLAGS = [
    Case("measure: --fragmentation-cohesion 2", MEASURE + ("--fragmentation-cohesion", "2"), {"t.csv": TRACK}, 2,
         "--fragmentation-cohesion: got 2.0; allowed range (0.0, 1.0]"),
    Case("measure: --warmup -1", MEASURE + ("--warmup", "-1"), {"t.csv": TRACK}, 2, "--warmup: got -1.0"),
    Case("measure: --dcd-max-delay -1", MEASURE + ("--dcd-max-delay", "-1"), {"t.csv": TRACK}, 2, "--dcd-max-delay"),
]

def _npz(**arrays) -> bytes:
    import io

    import numpy as np
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


_R, _N = 3, 4
GOOD_NPZ = _npz(times=[0.0, 0.5, 1.0], pos=[[[float(i), 0.0, 0.0] for i in range(_N)]] * _R,
                vel=[[[1.0, 0.0, 0.0]] * _N] * _R)
VIEW_NPZ = ("view", "{d}/t/trajectory.npz", "--out", "{d}/p.html", "--no-progress")
PARAMS = '{"preset": {"name": "m", "perception": {"field_deg": %s}}, "seed": 1}'

# trajectory files for the viewer (and the params.json beside them): each refusal names the file
TRAJECTORY_FILES = [
    Case("view: a .npz of garbage", VIEW_NPZ, {"t/trajectory.npz": b"garbage" * 10}, 2,
         "trajectory.npz: not a trajectory .npz (not a zip archive"),
    Case("view: a truncated .npz", VIEW_NPZ, {"t/trajectory.npz": GOOD_NPZ[:len(GOOD_NPZ) // 2]}, 2,
         "trajectory.npz: not a trajectory .npz"),
    Case("view: a .npz without vel", VIEW_NPZ, {"t/trajectory.npz": _npz(times=[0.0], pos=[[[0.0, 0, 0]]])}, 2,
         "trajectory.npz: not a flocksweep trajectory (missing vel"),
    Case("view: a .npz with flat positions", VIEW_NPZ, {"t/trajectory.npz": _npz(times=[0.0], pos=[0.0, 1.0, 2.0],
                                                                                  vel=[0.0, 1.0, 2.0])}, 2,
         "trajectory.npz: pos holds"),
    Case("view: a .npz of pickled objects", VIEW_NPZ, {"t/trajectory.npz": _npz(times=[0.0], pos=[[[0, 0, 0]]],
                                                                                  vel=[[[0, 0, 0]]],
                                                                                  seed=__import__("numpy").array(
                                                                                      [{}], dtype=object))}, 2,
         "trajectory.npz: cannot be read as a trajectory"),
    Case("view: params.json not JSON", VIEW_NPZ, {"t/trajectory.npz": GOOD_NPZ, "t/params.json": "{not json"}, 2,
         "params.json: cannot be read as a trajectory's parameters"),
    Case("view: params.json a list", VIEW_NPZ, {"t/trajectory.npz": GOOD_NPZ, "t/params.json": "[1, 2]"}, 2,
         "params.json: cannot be read as a trajectory's parameters"),
    Case("view: params.json not UTF-8", VIEW_NPZ, {"t/trajectory.npz": GOOD_NPZ, "t/params.json": b'{"\xff": 1}'}, 2, "params.json: cannot be read"),
    Case("view: params.json with a preset value out of range", VIEW_NPZ,
         {"t/trajectory.npz": GOOD_NPZ, "t/params.json": PARAMS % "400"}, 2, "params.json: its preset: "),
]

def _track(x_scale=1.0, t_scale=1.0) -> str:
    return "id,t,x,y,z\n" + "".join(f"{i},{t * t_scale!r},{t * x_scale * i!r},{i},0\n" for i in (1, 2) for t in (0, 1, 2))


# track content: what no flock metric can be computed from; every problem listed in validation.csv (only)
TRACK_CONTENT = [
    Case("measure: --warmup beyond the tracks (1e9 s)", MEASURE + ("--warmup", "1e9"), {"t.csv": TRACK}, 2,
         "no record at or after the warm-up of 1e+09 s", may_write="out"),
    Case("measure: coordinates x 1e305", MEASURE, {"t.csv": _track(x_scale=1e305)}, 2,
         "column 'x': x: 1e+305 is beyond 1e+100 analysis units", may_write="out"),
    Case("measure: coordinates x 1e305 in a mapped column", MEASURE + ("--columns", "x=px"),
         {"t.csv": _track(x_scale=1e305).replace(",x,", ",px,")}, 2, "column 'px'", may_write="out"),
    Case("measure: velocities that overflow (1e99 m in 1e-250 s)", MEASURE, {"t.csv": _track(1e99, 1e-250)}, 2,
         "non-finite derived values (velocities)", may_write="out"),
    Case("measure: speeds that overflow (1e99 m in 1e-101 s)", MEASURE, {"t.csv": _track(1e99, 1e-101)}, 2,
         "non-finite derived values (speed_mean_mean = inf", may_write="out"),
    Case("measure: a header and no rows", MEASURE, {"t.csv": "id,t,x,y,z\n"}, 2,
         "the tracks hold no flock: the file has no rows of detections", may_write="out"),
    Case("measure: a sidecar key typo", MEASURE, {"t.csv": TRACK, "t.json": '{"colums": {"id": "bird"}}'}, 2,
         "t.json: colums: unknown setting (did you mean 'columns'?)"),
    Case("measure: a sidecar unit typo", MEASURE, {"t.csv": TRACK, "t.json": '{"unit": {"length": "cm"}}'}, 2,
         "did you mean 'units'?"),
]

TRACK_FILES = [
    Case("measure: --interval 1e-9 (4e9 positions)", MEASURE + ("--interval", "1e-9"), {"t.csv": TRACK}, 2,
         "over the limit of 20,000,000", may_write="out"),
]

# --- track readers that agree or refuse (issue 42 points 2, 3 and 5): each file a reader cannot read the same
# way as its neighbours, a special file, an oversized declaration or a malformed value is one message, exit 2,
# before the output folder is made

def _trex_npz(**keys) -> bytes:
    import numpy as np
    arrays = {"X": np.arange(5.0), "Y": np.zeros(5), "time": np.arange(5) * 0.1, **keys}
    return _npz(**{k: v for k, v in arrays.items() if v is not None})


def _huge_mat() -> bytes:
    """A 392-byte MATLAB v5 file whose one array declares 200,000 x 4 x 300,000 doubles (1.9 TB)."""
    import io
    import struct

    import numpy as np
    import scipy.io
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, {"tracks": np.zeros((2, 4, 3))}, do_compression=False)
    data = bytearray(buffer.getvalue())
    struct.pack_into("<iii", data, 128 + 8 + 16 + 8, 200_000, 4, 300_000)   # the dimensions sub-element
    return bytes(data)


def _npy(value, pickle: bool = False) -> bytes:
    import io

    import numpy as np
    buffer = io.BytesIO()
    np.save(buffer, value, allow_pickle=pickle)
    return buffer.getvalue()


def _trajr(z: bool = False, clock: str = "t", velocity: bool = False) -> str:
    head = ["t" if clock == "t" else clock, "x", "y"] + (["z"] if z else []) + (["vx", "vy"] if velocity else [])
    rows = [[f"{k * 0.1!r}" if clock == "t" else f"2010-01-01 00:00:0{k}", f"{k * 0.1!r}", "0"] + (["0"] if z else [])
            + (["1", "0"] if velocity else []) for k in range(5)]
    return ",".join(head) + "\n" + "".join(",".join(r) + "\n" for r in rows)


TRACKS_DIR = ("measure", "{d}/data", "--group-radius", "5", "--no-figures", "--no-progress", "--out", "{d}/out")
TRACKS_MAT = ("measure", "{d}/t.mat", "--group-radius", "5", "--no-figures", "--no-progress", "--out", "{d}/out")
TRACKS_NPY = ("measure", "{d}/t.npy", "--group-radius", "5", "--no-figures", "--no-progress", "--out", "{d}/out")
MOVEBANK_CSV = ("event-id,timestamp,location-long,location-lat,individual-local-identifier\n")

TRACK_READERS = [
    Case("measure: a trajr folder in which one file has a z column", TRACKS_DIR,
         {"data/a.csv": _trajr(), "data/b.csv": _trajr(z=True), "data/c.csv": _trajr()}, 2,
         "b.csv: its columns (t, vx, vy, x, y, z) differ".replace("vx, vy, ", "")),
    Case("measure: a trajr folder with velocities in one file only", TRACKS_DIR,
         {"data/a.csv": _trajr(velocity=True), "data/b.csv": _trajr()}, 2, "b.csv: its columns (t, x, y) differ from "
                                                                           "a.csv's (t, vx, vy, x, y)"),
    Case("measure: a TRex folder with velocities in one file only", TRACKS_DIR,
         {"data/v_fish0.npz": _trex_npz(), "data/v_fish1.npz": _trex_npz(VX=[1.0] * 5, VY=[0.0] * 5)}, 2,
         "v_fish1.npz: its columns (X, Y, VX, VY, time) differ from v_fish0.npz's (X, Y, time)"),
    Case("measure: a TRex folder with time in one file and frames in another", TRACKS_DIR + ("--fps", "10"),
         {"data/v_fish0.npz": _trex_npz(), "data/v_fish1.npz": _trex_npz(time=None, frame=list(range(5)))}, 2,
         "v_fish1.npz: its columns (X, Y, frame) differ from v_fish0.npz's (X, Y, time)"),
    Case("measure: a folder of both .npz and .csv exports", TRACKS_DIR,
         {"data/v_fish0.npz": _trex_npz(), "data/v_fish1.csv": "X,Y,time\n0,0,0\n1,0,0.1\n"}, 2,
         "holds both .npz (1: v_fish0.npz, ...) and .csv (1: v_fish1.csv, ...) exports"),
    Case("measure: an empty folder as TRex", TRACKS_DIR + ("--format", "trex"), {"data/readme.txt": "x"}, 2,
         "no TRex exports"),
    Case("measure: an empty folder as trajr", TRACKS_DIR + ("--format", "trajr"), {"data/readme.txt": "x"}, 2,
         "no CSV files in this folder"),
    Case("measure: ragged TRex arrays", TRACKS_DIR, {"data/v_fish0.npz": _trex_npz(Y=[0.0] * 4)}, 2,
         "v_fish0.npz: its arrays differ in length"),
    Case("measure: a FIFO inside a TRex folder", TRACKS_DIR, {"data/v_fish0.npz": _trex_npz()}, 2,
         "v_fish1.npz is not a regular file (a FIFO, device or socket)", specials={"data/v_fish1.npz": "fifo"}),
    Case("measure: a socket inside a trajr folder", TRACKS_DIR, {"data/a.csv": _trajr()}, 2,
         "b.csv is not a regular file", specials={"data/b.csv": "socket"}),
    Case("measure: a link to /dev/zero inside a trajr folder", TRACKS_DIR, {"data/a.csv": _trajr()}, 2,
         "b.csv is not a regular file", links={"data/b.csv": "/dev/zero"}),
    Case("measure: a FIFO as the track file", ("measure", "{d}/t.csv", "--group-radius", "5", "--no-figures",
                                               "--no-progress", "--out", "{d}/out"), {}, 2, "t.csv is not a regular file",
         specials={"t.csv": "fifo"}),
    Case("measure: a 392-byte .mat declaring 1.9 TB", TRACKS_MAT + ("--layout", "channels=x,y,vx,vy", "--fps", "10"),
         {"t.mat": _huge_mat()}, 2, "declares (200000, 4, 300000) (1,920,000,000,000 bytes), more than a file of 392"),
    Case("measure: a misspelt --layout key", TRACKS_MAT + ("--layout", "chanels=x,y,vx,vy", "--fps", "10"),
         {"t.mat": _huge_mat()}, 2, "layout.chanels: unknown layout key (did you mean 'channels'?)"),
    Case("measure: --layout for a CSV", MEASURE + ("--layout", "channels=x,y"), {"t.csv": TRACK}, 2,
         "layout: the csv format has no array layout"),
    Case("measure: --fps for times in seconds", MEASURE + ("--fps", "30"), {"t.csv": TRACK}, 2,
         "fps: the csv file's times are in 's', not frame numbers"),
    Case("measure: --columns for an idtracker.ai file", TRACKS_NPY + ("--columns", "id=fish"),
         {"t.npy": _npy(__import__("numpy").zeros((4, 2, 2)))}, 2, "columns: the idtracker format names its own"),
    Case("measure: text in an idtracker.ai array", TRACKS_NPY, {"t.npy": _npy(__import__("numpy").full((4, 2, 2), "1"))},
         2, "trajectories holds text"),
    Case("measure: text as an idtracker.ai frame rate", TRACKS_NPY,
         {"t.npy": _npy({"trajectories": __import__("numpy").zeros((4, 2, 2)), "frames_per_second": "fast"},
                        pickle=True)}, 2, "frames_per_second: got 'fast'; expected one number > 0"),
    Case("measure: decimal commas in a comma-separated file", MEASURE,
         {"t.csv": "id,t,x,y,z\n1,0,0,0,0\n1,1,1,5,0\n1,2,2,0\n2,0,0,1,0\n2,1,1,1,0\n2,2,2,1,0\n"}, 2,
         "line 4 (4); a decimal comma in a comma-separated file"),
    Case("measure: one field too many on every row", MEASURE,
         {"t.csv": "id,t,x,y\n1,0,0,0,0\n1,1,1,0,5\n2,0,0,1,0\n2,1,1,1,0\n"}, 2,
         "its rows have more fields than its header (4): a decimal comma"),
    Case("measure: a Movebank file with --units length=cm", ("measure", "{d}/gps.csv", "--group-radius", "5",
                                                             "--units", "cm", "--no-figures", "--no-progress",
                                                             "--out", "{d}/out"),
         {"gps.csv": MOVEBANK_CSV + "1,2010-01-01 00:00:00,19.0,47.5,a\n"}, 2,
         "units.length: got 'cm'; Movebank tracks are projected to metres"),
]

CASES = (SWEEP_FILES + SWEEP_VALUES + RUN_FLAGS + SIMULATE_FLAGS + CALIBRATE + TARGETS_FLAGS + SBC_FLAGS + READERS
         + SIZES + SPECIAL_FILES + NUMBERS + TABLES + EXPRESSIONS + OUT_PATHS + MEASURE_FLAGS + TRAJECTORY_FILES + TRACK_CONTENT + TRACK_FILES
         + TRACK_READERS)
QUICK = ("run: not UTF-8", "run: date value", "run: NUL in name", "run: run.n 9e18", "run: warmup beyond duration",
         "run: --batch-size -1", "run: design of 1e9 runs", "run: --until-ci misspelt metric",
         "calibrate: prior beyond the range", "targets: --sd not numbers", "targets: --truth not a number",
         "simulate: --out an existing file", "status: garbage design", "run: --out an existing file",
         "run: --out a dangling symbolic link", "measure: --out an existing file", "measure: --fragmentation-cohesion 2",
         "view: a .npz of garbage", "view: params.json a list", "measure: coordinates x 1e305",
         "measure: a sidecar key typo")


# -- runs and plug-ins (issue 42): a plug-in that does not compile, a bad run.timeout_s ------------------
# (tests/broken_plugin.py: its steer names an attribute that does not exist, on line 15; tests/ is on the path)
PLUGIN_SWEEP = """name = "p"
[model]
preset = "{d}/p.toml"
[run]
warmup = 0.5
[[axes]]
key = "init.radius"
values = [5.0, 6.0]
"""
BROKEN = {"p.toml": FAULTY_PRESET.format(module="broken_plugin"), "s.toml": PLUGIN_SWEEP}
RUNS_AND_PLUGINS = [
    Case("run: a plug-in whose steer does not compile", RUN, BROKEN, 2,
         "broken_plugin.py, line 15 (return (nbrs.nonexistent[0], 0.0, 0.0)): Unknown attribute 'nonexistent'"),
    Case("run --workers 1: a plug-in whose steer does not compile",
         ("run", "{d}/s.toml", "--out", "{d}/out", "--workers", "1", "--no-progress"), BROKEN, 2,
         "plug-in 'broken_plugin' does not compile"),
    Case("simulate: a plug-in whose steer does not compile", ("simulate", "{d}/p.toml", "--out", "{d}/out"), BROKEN,
         2, "broken_plugin.py, line 15"),
    run_case("run.timeout_s = 0", "run.timeout_s: got 0", run="timeout_s = 0"),
    run_case("run.timeout_s negative", "run.timeout_s: got -5", run="timeout_s = -5"),
    run_case("run.timeout_s infinite", "run.timeout_s: got inf", run="timeout_s = inf"),
    run_case("run.timeout_s a string", "run.timeout_s", run='timeout_s = "an hour"'),
    run_case("--set run.timeout_s=nan", "run.timeout_s: got nan", args=("--set", "run.timeout_s=nan")),
]
CASES += RUNS_AND_PLUGINS


# -- flocksweep posterior: damaged estimator folders and bad targets (issue 42) -------------------------
# The estimator folder est/ is made by tests/npe_tiny.py fake_estimator (an untrained flow, sealed as
# calibrate seals one), then damaged; "resealed": its manifest written again over the damage, as a buggy
# or foreign writer would, so that the reader's own checks of each file's content are what refuses it.
POSTERIOR = ("posterior", "{d}/est", "--targets", "{d}/flocks.csv")
FLOCKS = "flock,visible_mean,binocular_share\nF1,3.0,0.2\nF2,3.5,0.25\n"


def _estimator(*damages, reseal: bool = False):
    def prepare(folder):
        from npe_tiny import fake_estimator
        from flocksweep.analysis.calibration.estimator_folder import seal
        where = fake_estimator(folder / "est")
        for damage in damages:
            damage(where)
        if reseal:
            (where / "manifest.json").unlink()
            seal(where)
    return prepare


def _edit(name: str, change):
    def damage(where):
        path = where / name
        path.write_bytes(change(path.read_bytes()))
    return damage


def _json_edit(name: str, change):
    import json
    return _edit(name, lambda raw: json.dumps(change(json.loads(raw))).encode())


def _remove(name: str):
    return lambda where: (where / name).unlink()


def _wider_weights(where):
    from npe_tiny import fake_estimator
    other = fake_estimator(where.parent / "other", width=12)
    (where / "flow.eqx").write_bytes((other / "flow.eqx").read_bytes())
    for path in sorted(other.rglob("*"), reverse=True):
        path.unlink() if path.is_file() else path.rmdir()
    other.rmdir()


def posterior_case(name, expect, *damages, reseal=False, files=None, argv=POSTERIOR, specials=None, est=True):
    return Case(f"posterior: {name}", argv, {"flocks.csv": FLOCKS} if files is None else files, 2, expect,
                specials=specials or {}, prepare=_estimator(*damages, reseal=reseal) if est else None)


ESTIMATOR_FOLDERS = [
    posterior_case("estimator folder missing", "est does not exist; expected the estimator/ folder", est=False),
    posterior_case("estimator written before estimators were sealed (no manifest.json)",
                   "est/manifest.json is missing: the estimator's files cannot be verified", _remove("manifest.json")),
    posterior_case("a member missing (flow.eqx deleted)",
                   "est/flow.eqx is missing (the estimator's manifest.json records it); train it again: "
                   "flocksweep calibrate c.toml", _remove("flow.eqx")),
    posterior_case("a member truncated", "est/flow.eqx changed since it was written",
                   _edit("flow.eqx", lambda raw: raw[:len(raw) // 2])),
    posterior_case("a member garbage", "est/flow.json changed since it was written", _edit("flow.json", lambda raw: b"\x00garbage")),
    posterior_case("identity.json edited", "est/identity.json changed since it was written",
                   _json_edit("identity.json", lambda d: {**d, "bounds": [[0, 360]]})),
    posterior_case("a file dropped into the folder", "est/member9/flow.eqx cannot be verified",
                   lambda where: (where / "member9").mkdir() or (where / "member9" / "flow.eqx").write_bytes(b"x")),
    posterior_case("manifest.json edited", "est/manifest.json changed since it was written",
                   _edit("manifest.json", lambda raw: raw.replace(b'"c.toml"', b'"d.toml"'))),
    posterior_case("identity.json not JSON (resealed)", "est/identity.json: not valid JSON",
                   _edit("identity.json", lambda raw: raw[:-5]), reseal=True),
    posterior_case("identity.json a list (resealed)", "est/identity.json: a JSON list, not an object",
                   _edit("identity.json", lambda raw: b"[1, 2]"), reseal=True),
    posterior_case("identity.json columns a number (resealed)", "est/identity.json: columns: got 3",
                   _json_edit("identity.json", lambda d: {**d, "columns": 3}), reseal=True),
    posterior_case("identity.json bounds reversed (resealed)", "est/identity.json: bounds: got [[300, 60]]",
                   _json_edit("identity.json", lambda d: {**d, "bounds": [[300, 60]]}), reseal=True),
    posterior_case("identity.json parameters of strings (resealed)", "est/identity.json: parameters: got 'field'",
                   _json_edit("identity.json", lambda d: {**d, "parameters": "field"}), reseal=True),
    posterior_case("identity.json without the measurement's interval (resealed)",
                   "est/identity.json: measurement: no interval",
                   _json_edit("identity.json", lambda d: {**d, "measurement": {k: v for k, v in d["measurement"].items()
                                                                                if k != "interval"}}), reseal=True),
    posterior_case("identity.json naming 3 statistics for a flow of 2 (resealed)",
                   "its flow has 1 parameters and 2 statistics, its identity.json 1 and 3",
                   _json_edit("identity.json", lambda d: {**d, "columns": ["visible_mean", "binocular_share", "flock"]}),
                   reseal=True, files={"flocks.csv": "flock,visible_mean,binocular_share\n1,3.0,0.2\n"}),
    posterior_case("flow weights of the wrong shapes (resealed)",
                   "est/flow.eqx: not the weights of this estimator's flow (ValueError: an array of shape",
                   _wider_weights, reseal=True),
    posterior_case("flow weights truncated (resealed)", "est/flow.eqx: not the weights of this estimator's flow",
                   _edit("flow.eqx", lambda raw: raw[:len(raw) // 2]), reseal=True),
    posterior_case("flow weights with bytes left over (resealed)", "bytes left over after the flow's last array",
                   _edit("flow.eqx", lambda raw: raw + b"\x00" * 64), reseal=True),
    posterior_case("flow.json of the wrong lengths (resealed)", "est/flow.json: theta_mean: got 3 values; expected 1",
                   _json_edit("flow.json", lambda d: {**d, "theta_mean": [1.0, 2.0, 3.0]}), reseal=True),
    posterior_case("flow.json a width of 10^9 (resealed)", "est/flow.json: settings: got",
                   _json_edit("flow.json", lambda d: {**d, "settings": {**d["settings"], "width": 10 ** 9}}), reseal=True),
    posterior_case("flow.json of an ensemble of -1 members (resealed)", "est/flow.json: members: got -1",
                   _json_edit("flow.json", lambda d: {"members": -1}), reseal=True),
    posterior_case("coverage.json not a verdict (resealed)", "est/coverage.json: not a coverage verdict",
                   _json_edit("coverage.json", lambda d: {"passed": "yes"}), reseal=True),
]
TARGET_TABLES = [
    posterior_case("targets file missing", "--targets: file not found", files={}),
    posterior_case("targets missing a column", "no column 'binocular_share'",
                   files={"flocks.csv": "flock,visible_mean\nF1,3.0\n"}),
    posterior_case("targets not numeric", "column 'visible_mean': row 1 holds 'high', not a number",
                   files={"flocks.csv": "flock,visible_mean,binocular_share\nF1,3.0,0.2\nF2,high,0.2\n"}),
    posterior_case("targets NaN", "row 0 has a missing or non-finite statistic",
                   files={"flocks.csv": "flock,visible_mean,binocular_share\nF1,nan,0.2\n"}),
    posterior_case("targets an empty file", "flocks.csv cannot be read as a CSV table (EmptyDataError",
                   files={"flocks.csv": ""}),
    posterior_case("targets a header and no rows", "flocks.csv holds no rows",
                   files={"flocks.csv": "flock,visible_mean,binocular_share\n"}),
    posterior_case("targets binary garbage", "flocks.csv cannot be read as a CSV table",
                   files={"flocks.csv": bytes(range(256)) * 4}),
    posterior_case("targets a folder", "is not a regular file", files={"flocks.csv/x": "x"}),
    posterior_case("targets a FIFO", "is not a regular file", files={}, specials={"flocks.csv": "fifo"}),
    posterior_case("targets a Parquet file of garbage", "flocks.parquet cannot be read as a Parquet table",
                   files={"flocks.parquet": b"PAR1garbage"}, argv=("posterior", "{d}/est", "--targets", "{d}/flocks.parquet")),
    posterior_case("measure.json beside the targets not JSON", "measure.json (beside the table: how it was measured) "
                   "is not valid JSON", files={"flocks.csv": FLOCKS, "measure.json": "{"}),
    posterior_case("--tracks file missing", "--tracks: file not found", files={},
                   argv=("posterior", "{d}/est", "--tracks", "{d}/t.csv")),
    posterior_case("--tracks binary garbage", "t.csv: cannot read it as csv", files={"t.csv": bytes(range(256)) * 4},
                   argv=("posterior", "{d}/est", "--tracks", "{d}/t.csv")),
    posterior_case("--tracks a FIFO", "not a regular file", files={}, specials={"t.csv": "fifo"},
                   argv=("posterior", "{d}/est", "--tracks", "{d}/t.csv")),
    posterior_case("--tracks with a column missing", "--tracks: ", files={"t.csv": "id,t,x\n1,0,0\n1,1,1\n"},
                   argv=("posterior", "{d}/est", "--tracks", "{d}/t.csv")),
]
POSTERIOR_INPUTS = ESTIMATOR_FOLDERS + TARGET_TABLES

COMPARE = """name = "cmp"
seed = 1
simulations = {simulations}
heldout = {heldout}
[models]
a = "c.toml"
b = "c.toml"
[targets]
stats = ["cohesion", "polarization"]
mean = [0.9, 0.8]
sd = [0.05, 0.05]
"""
COMPARISONS = [
    Case("compare: simulations 10^12", ("compare", "{d}/cmp.toml", "--out", "{d}/out", "--no-progress"),
         {**GOOD_CAL, "cmp.toml": COMPARE.format(simulations=10 ** 12, heldout=200)}, 2,
         "simulations: got 1,000,000,000,000: 2 models x (1,000,000,000,000 + 200 held out) = 2,000,000,000,400 "
         "simulations: their parameter vectors alone would need about"),
    Case("compare: simulations 10^8 without --yes", ("compare", "{d}/cmp.toml", "--out", "{d}/out", "--no-progress"),
         {**GOOD_CAL, "cmp.toml": COMPARE.format(simulations=10 ** 8, heldout=200)}, 2,
         "(more than 20,000,000); that takes long: use fewer, or pass --yes to go ahead"),
    Case("compare: heldout 10^12 with --yes", ("compare", "{d}/cmp.toml", "--out", "{d}/out", "--no-progress", "--yes"),
         {**GOOD_CAL, "cmp.toml": COMPARE.format(simulations=100, heldout=10 ** 12)}, 2,
         "their parameter vectors alone would need about"),
]
CASES += COMPARISONS


def _has_sbi() -> bool:
    import importlib.util
    return importlib.util.find_spec("flowjax") is not None


if _has_sbi():   # the estimator folders are made with JAX (the sbi extra)
    CASES += POSTERIOR_INPUTS

def materialise(case: Case, folder) -> list[str]:
    """Write the case's files into ``folder``; its argv with ``{d}`` and ``{holland}`` filled in."""
    for name, content in case.files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content.replace("{d}", str(folder)).replace("{holland}", HOLLAND))
    for name, target in case.links.items():
        (folder / name).symlink_to(target)
    for name, kind in case.specials.items():
        _special(folder / name, kind)
    if case.prepare is not None:
        case.prepare(folder)
    return [str(a).replace("{d}", str(folder)).replace("{holland}", HOLLAND) for a in case.argv]


def _special(path, kind: str) -> None:
    """A FIFO, or a UNIX socket's file (the socket closed, its file left), at ``path``."""
    import os
    import socket
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "fifo":
        os.mkfifo(path)
    else:
        with socket.socket(socket.AF_UNIX) as sock:
            sock.bind(str(path))


def snapshot(folder) -> set[str]:
    """Every path under ``folder`` (files and folders), relative."""
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


@dataclass
class Refusal:
    code: int | None
    stderr: str
    written: set
    crash: str = ""   # the exception that escaped main (a traceback for the user)

    def clean(self, case: Case) -> bool:
        """Refused as the catalogue says: its exit status, its words, one message, nothing written."""
        return (not self.crash and self.code == case.code and case.expect.lower() in self.stderr.lower()
                and "Traceback" not in self.stderr
                and not {p for p in self.written if not (case.may_write and p.startswith(case.may_write))})


def attempt(case: Case, folder) -> Refusal:
    """Run ``case`` in the empty folder ``folder`` (as the working directory) with ``flocksweep.cli.main``."""
    import contextlib
    import io
    import os
    import traceback

    from flocksweep.cli import main

    argv = materialise(case, folder)
    before = snapshot(folder)
    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(folder)
    code, crash = None, ""
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main(argv)
    except SystemExit as exit_:   # argparse's own usage errors
        code = exit_.code
    except BaseException as raised:  # noqa: BLE001 - the user would have seen a traceback
        crash = "".join(traceback.format_exception(raised))[-2000:]
    finally:
        os.chdir(cwd)
    return Refusal(code, err.getvalue(), snapshot(folder) - before, crash)
