"""Calibration methods are objects registered once (analysis.calibration.methods): the file's [method] table,
``flocksweep calibrate --method`` and the docs' methods table take their choices from the registry, and a
method registered from outside (a toy: the prior's draws as its "posterior") runs end to end through the
same driver, outputs and report as the built-ins."""
from __future__ import annotations

import ast
import json
import re
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from flocksweep.analysis.calibration import methods
from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.methods import CalibrationMethod, register, unregister
from flocksweep.analysis.calibration.posterior_outputs import write_draws
from flocksweep.analysis.calibration.run import run_calibration
from flocksweep.analysis.calibration.settings import MethodSettings
from flocksweep.cli import build_parser, main
from flocksweep.simcore.schema import ConfigError, check_at_least
from flocksweep.sweeps.seeds import generator
from paths import ROOT

HOLLAND = str(ROOT / "configs" / "models" / "holland.toml")


@dataclass(frozen=True, kw_only=True)
class ToySettings(MethodSettings):
    kind: ClassVar[str] = "toy"
    draws: int = 200

    def __post_init__(self):
        super().__post_init__()
        check_at_least("draws", self.draws, 10)


class Toy(CalibrationMethod):
    """The prior as the posterior: draws from the prior, no simulation but the predictive check's."""

    kind = "toy"
    settings = ToySettings
    what = "prior draws"
    cost = "the predictive check"
    use_when = "testing"

    def run(self, job):
        job.phases.start(f"drawing {job.config.method.draws} prior draws")
        draws = np.asarray(job.config.prior.sample(generator(job.config.seed, 99), job.config.method.draws),
                           dtype=float).reshape(job.config.method.draws, -1)
        outcome, _ = write_draws(job, draws, {"converged": True, "messages": ["toy: the prior itself"]},
                                 {"toy": {"draws": len(draws)}})
        return outcome


@pytest.fixture
def toy():
    register(Toy())
    yield
    unregister("toy")


def calibration(kind="toy") -> dict:
    return {"name": "toy_fit", "seed": 2, "model": {"preset": HOLLAND},
            "run": {"n": 6, "duration": 1.0, "record_interval": 0.5, "warmup": 0.5},
            "parameters": {"field": {"key": "perception.field_deg",
                                     "prior": {"dist": "uniform", "low": 100, "high": 300}}},
            "targets": {"stats": ["polarization", "nn_distance"], "mean": [0.8, 3.0], "sd": [0.1, 0.5]},
            "method": {"kind": kind, "n_sim": 5}}


def test_the_builtins_are_registered_and_nothing_else_names_a_method():
    assert methods.kinds()[:4] == ("emcee", "optimize", "npe", "emulator")
    for kind in methods.kinds():
        assert methods.method_of(kind).settings.kind == kind
    # no branching on a method's kind outside the registry's package
    folder = ROOT / "analysis" / "calibration"
    names = "|".join(methods.kinds())
    branching = re.compile(rf"kind\s*(==|!=|in|not in)\s*[(\"']+({names})\b|isinstance\([^)]*(Emcee|Optimize|Npe|Emulator)Settings")
    found = [f"{path.name}:{n}" for path in folder.glob("*.py")
             for n, line in enumerate(path.read_text().splitlines(), 1) if branching.search(line)]
    assert found == []


@pytest.mark.slow   # over a second of CPU: out of the quick loop, still in CI
def test_a_registered_method_runs_end_to_end_with_the_common_outputs(toy, tmp_path):
    config = calibration_from_dict(calibration(), ROOT)
    assert config.method.kind == "toy" and config.method.draws == 200
    result = run_calibration(config, tmp_path / "out", progress=False, predictive_draws=8)
    report = json.loads((tmp_path / "out" / "convergence.json").read_text())
    assert report["method"] == "toy" and report["toy"] == {"draws": 200}
    assert report["accounting"]["simulations"] == {"predictive": 8, "total": 8}
    for name in ("posterior.csv", "posterior.nc", "predictive.csv", "flock_check.csv", "report.html", "corner.png"):
        assert (tmp_path / "out" / name).is_file(), name
    assert list(result.summary.index) == ["field"]
    assert "toy: the prior itself" in (tmp_path / "out" / "report.md").read_text()


def test_a_registered_method_is_a_choice_of_the_file_and_of_the_command_line(toy, tmp_path, capsys):
    with pytest.raises(ConfigError, match=r"draws: got 3"):
        calibration_from_dict({**calibration(), "method": {"kind": "toy", "draws": 3}}, ROOT)
    with pytest.raises(ConfigError, match=r"method.kind: got 'tyo'; allowed: 'emcee', 'optimize', 'npe', 'emulator', 'toy' \(did you mean 'toy'\?\)"):
        calibration_from_dict(calibration("tyo"), ROOT)
    parser = build_parser("calibrate")
    sub = next(a for a in parser._actions if a.dest == "command").choices["calibrate"]
    method = next(a for a in sub._actions if a.dest == "method")
    assert method.metavar == "emcee|optimize|npe|emulator|toy"
    path = tmp_path / "toy.toml"
    import tomli_w
    data = calibration("emcee")
    data["method"] = {"kind": "emcee", "n_sim": 5, "toy": {"draws": 20}}
    path.write_text(tomli_w.dumps(data))
    assert main(["calibrate", str(path), "--method", "toy", "--out", str(tmp_path / "cli"), "--no-progress"]) == 0
    assert "toy: the prior itself" in capsys.readouterr().out
    assert json.loads((tmp_path / "cli" / "convergence.json").read_text())["draws"] == 20


def test_registration_refuses_a_clash_and_a_settings_class_of_another_kind(toy):
    with pytest.raises(ValueError, match="registered already"):
        register(Toy())

    class Wrong(Toy):
        kind = "wrong"
    with pytest.raises(ValueError, match="kind 'toy'"):
        register(Wrong())


def test_the_docs_methods_table_is_the_registry():
    text = (ROOT / "docs" / "calibration.md").read_text()
    assert methods.methods_table() in text


def test_the_calibrate_command_names_no_method_itself():
    source = (ROOT / "flocksweep" / "commands" / "calibrate.py").read_text()
    strings = [node.value for node in ast.walk(ast.parse(source)) if isinstance(node, ast.Constant)
               and isinstance(node.value, str)]
    assert not [s for s in strings if re.search(r"\bemcee\|optimize", s)]


def test_a_method_without_run_cannot_be_made():
    """The base class states run as abstract: a method that forgets it fails when made, not mid-calibration."""
    from flocksweep.analysis.calibration.methods.base import CalibrationMethod

    class Forgetful(CalibrationMethod):
        kind = "forgetful"

    with pytest.raises(TypeError, match="abstract method.*run"):
        Forgetful()
