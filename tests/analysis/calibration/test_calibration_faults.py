"""Failures of calibrations (docs/errors.md): priors checked over their whole support before anything
is written, a resume refused with the list of what changed, a chain step written whole, a chain file
that cannot be read set aside, a failed write naming the chain file, an interrupt saving the chain and
saying how to resume, and (slow) a short calibration killed at random moments resuming bit for bit.
"""
from __future__ import annotations

import errno
import os

import h5py
import numpy as np
import pytest

import faults
from flocksweep.analysis.calibration import chainfile
from flocksweep.analysis.calibration.bsl import run_bsl
from flocksweep.analysis.calibration.config import calibration_from_dict
from flocksweep.analysis.calibration.mcmc import ChainMismatch
from flocksweep.analysis.calibration.priors import JointPrior, Uniform
from paths import ROOT
from flocksweep.simcore import ConfigError
from flocksweep.cli import main
from flocksweep.sweeps.files import WriteFailed

HOLLAND = str(ROOT / "configs/models/holland.toml")


def calibration(**changes) -> dict:
    data = {"name": "cal", "seed": 1, "model": {"preset": HOLLAND},
            "run": {"n": 6, "duration": 1.0, "record_interval": 0.5, "warmup": 0.5},
            "parameters": {"field": {"key": "perception.field_deg",
                                     "prior": {"dist": "uniform", "low": 60, "high": 300}}},
            "targets": {"stats": ["cohesion", "polarization"], "mean": [0.9, 0.8], "sd": [0.05, 0.05]},
            "method": {"kind": "emcee", "n_sim": 5, "walkers": 4, "steps": 3}}
    for key, value in changes.items():
        data[key] = value
    return data


# -- priors over their whole support --------------------------------------------------------------

@pytest.mark.parametrize("parameter, where", [
    ({"key": "perception.field_deg", "prior": {"dist": "uniform", "low": 30, "high": 400}}, "parameters.p.prior"),
    ({"key": "perception.direction_deg", "prior": {"dist": "uniform", "low": -5, "high": 45}}, "parameters.p.prior"),
    ({"key": "perception.field_deg", "prior": {"dist": "normal", "mean": 100, "sd": 80}, "bounds": [1, 500]},
     "parameters.p.bounds"),
    ({"key": "init.n", "prior": {"dist": "uniform", "low": 0.2, "high": 30}}, "parameters.p.prior"),
])
def test_a_prior_reaching_outside_the_models_range_is_refused_naming_the_parameter(parameter, where):
    with pytest.raises(ConfigError) as info:
        calibration_from_dict(calibration(parameters={"p": parameter}), ROOT)
    assert info.value.key == where and "support" in str(info.value)


@pytest.mark.parametrize("parameter", [
    {"key": "perception.field_deg", "prior": {"dist": "uniform", "low": 0, "high": 360}},   # 0 excluded, inside fine
    {"key": "perception.range", "prior": {"dist": "loguniform", "low": 1, "high": 60}},
    {"key": "init.n", "prior": {"dist": "uniform", "low": 0.6, "high": 30}},                 # rounds to >= 1
])
def test_a_prior_inside_the_range_is_accepted(parameter):
    config = calibration_from_dict(calibration(parameters={"p": parameter}), ROOT)
    assert config.keys == (parameter["key"],)


def test_the_prior_is_refused_before_any_file_is_written(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text(f'name = "c"\n[model]\npreset = "{HOLLAND}"\n[run]\nn = 6\nduration = 1.0\nwarmup = 0.5\n'
                    '[parameters.field]\nkey = "perception.field_deg"\nprior = { dist = "uniform", low = 60, '
                    'high = 400 }\n[targets]\nstats = ["cohesion", "polarization"]\nmean = [0.9, 0.8]\n'
                    'sd = [0.05, 0.05]\n[method]\nkind = "emcee"\nn_sim = 5\nwalkers = 4\nsteps = 3\n')
    assert main(["calibrate", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "parameters.field.prior" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# -- resume: every chain-defining setting is compared ---------------------------------------------

@pytest.fixture
def short_chain(tmp_path):
    out = tmp_path / "out"
    assert main(["calibrate", str(ROOT / "configs/calibration/recover_holland.toml"), "--out", str(out),
                 "--no-progress", "--set", "method.kind=emcee", "--set", "method.emcee.steps=2", "--set", "method.n_sim=6", "--set", "run.n=6",
                 "--set", "run.duration=2.5", "--set", "method.emcee.reevaluate_every=0"]) == 0
    return out


BASE = ["--no-progress", "--resume", "--set", "method.kind=emcee", "--set", "method.emcee.steps=3", "--set", "run.n=6", "--set", "run.duration=2.5",
        "--set", "method.emcee.reevaluate_every=0"]


@pytest.mark.slow
@pytest.mark.parametrize("changes, named", [
    (["method.n_sim=8"], ["chain_n_sim: stored 6, now 8"]),
    (["targets.mean=[0.8, 3.9, 0.18, 0.06]", "method.n_sim=6"], ["chain_targets: the targets"]),
    (["seed=2", "method.n_sim=6", "method.emcee.walkers=10"], ["bsl_seed: stored 1, now 2", "walkers: stored 8, now 10"]),
    (["method.n_sim=6", "run.warmup=1.0"], ["chain_metrics"]),
    (["method.n_sim=6", "model.perception.range=25"], ["chain_model: the model"]),
])
def test_a_resume_with_changed_settings_is_refused_listing_every_difference(short_chain, changes, named, capsys):
    argv = ["calibrate", str(ROOT / "configs/calibration/recover_holland.toml"), "--out", str(short_chain)] + BASE
    before = (short_chain / "chain.h5").read_bytes()
    assert main(argv + [x for change in changes for x in ("--set", change)]) == 2
    err = capsys.readouterr().err
    assert "--resume:" in err and "holds a chain made with other settings" in err and "Traceback" not in err
    for phrase in named:
        assert phrase in err
    assert (short_chain / "chain.h5").read_bytes() == before
    assert main(argv + ["--set", "method.n_sim=6"]) == 0           # the same settings resume


# -- the chain file ---------------------------------------------------------------------------------

def toy(theta, rng):
    return theta[None, :] + rng.standard_normal((8, theta.size))


PRIOR = JointPrior(["a", "b"], [Uniform(-5.0, 5.0)] * 2)
OBSERVED = np.array([[0.5, -1.0]])


def toy_chain(path=None, steps=12, **options):
    return run_bsl(toy, OBSERVED, PRIOR, walkers=6, steps=steps, seed=3, path=path, **options)


def same(a, b) -> bool:
    return (np.array_equal(a.chain, b.chain) and np.array_equal(a.log_prob, b.log_prob)
            and np.array_equal(a.acceptance_fraction, b.acceptance_fraction))


@pytest.mark.parametrize("crash_at", [1, 5])
def test_a_step_cut_between_its_writes_leaves_the_previous_state_and_resumes_bit_for_bit(crash_at, tmp_path,
                                                                                           monkeypatch):
    whole = toy_chain()
    path = tmp_path / "chain.h5"
    real = chainfile.ChainFile._commit

    def crash(self, g, iteration, state, total):
        if iteration == crash_at:
            raise KeyboardInterrupt   # as if killed: the row and the new state are staged, not committed
        return real(self, g, iteration, state, total)
    monkeypatch.setattr(chainfile.ChainFile, "_commit", crash)
    with pytest.raises(KeyboardInterrupt):
        toy_chain(path)
    monkeypatch.undo()
    assert chainfile.stored_steps(path) == crash_at
    assert same(toy_chain(path, resume=True), whole)


def test_a_failure_before_the_first_step_leaves_no_chain_file(tmp_path):
    def broken(theta, rng):
        raise ValueError("the simulator is broken")
    path = tmp_path / "chain.h5"
    with pytest.raises(ValueError, match="broken"):
        run_bsl(broken, OBSERVED, PRIOR, walkers=6, steps=3, seed=3, path=path)
    assert not path.exists()          # a plain rerun is not blocked by a file holding nothing
    assert toy_chain(path, steps=3).chain.shape == (3, 6, 2)


def test_an_unreadable_chain_file_is_set_aside_and_the_chain_starts_again(tmp_path, caplog):
    path = tmp_path / "chain.h5"
    whole = toy_chain(path)
    path.write_bytes(path.read_bytes()[:200])     # truncated
    resumed = toy_chain(path, resume=True)
    assert same(resumed, whole)
    moved = list((tmp_path / "quarantine").glob("chain.h5.*"))
    assert len(moved) == 1 and "cannot be read as a chain file" in caplog.text


def test_a_failed_write_that_leaves_the_file_unreadable_deletes_nothing_and_a_rerun_restarts(tmp_path, monkeypatch,
                                                                                            caplog):
    """A full disk cut step 5's write and left the file unreadable (the HDF5 library's KeyError of a
    damaged object header): WriteFailed naming the file, the file kept; the rerun sets it aside."""
    whole = toy_chain()
    path = tmp_path / "chain.h5"
    real = chainfile.ChainFile._stage

    def full(self, g, iteration, state, accepted):
        if iteration == 5:
            raise KeyError("Unable to synchronously open object (addr overflow, addr = 800, size = 8)")
        return real(self, g, iteration, state, accepted)

    def unreadable(path):
        raise chainfile.DamagedChain(f"{path} cannot be read as a chain file (KeyError: addr overflow)")
    monkeypatch.setattr(chainfile.ChainFile, "_stage", full)
    monkeypatch.setattr("flocksweep.analysis.calibration.mcmc.stored_attrs", unreadable)
    with pytest.raises(WriteFailed) as info:
        toy_chain(path)
    assert info.value.filename == str(path) and "became unreadable" in str(info.value)
    monkeypatch.undo()
    assert path.exists()                        # what was saved is never deleted
    data = bytearray(path.read_bytes())
    data[96:4096] = b"\xff" * (4096 - 96)         # and really damaged now
    path.write_bytes(bytes(data))
    assert same(toy_chain(path, resume=True), whole)
    assert len(list((tmp_path / "quarantine").glob("chain.h5.*"))) == 1
    assert "cannot be read as a chain file" in caplog.text


def test_a_chain_row_changed_after_it_was_written_is_detected_set_aside_and_recomputed(tmp_path, caplog):
    path = tmp_path / "chain.h5"
    whole = toy_chain(path)
    assert chainfile.check_chain(path) == 12
    with h5py.File(path, "r+") as f:
        f["mcmc"]["chain"][3, 0, 0] = 0.25          # a valid number, silently wrong
    with pytest.raises(chainfile.DamagedChain, match="row 4 of its chain changed"):
        chainfile.check_chain(path)
    assert same(toy_chain(path, resume=True), whole)
    moved = list((tmp_path / "quarantine").glob("chain.h5.*"))
    assert len(moved) == 1 and "row 4 of its chain changed since it was written" in caplog.text
    assert chainfile.check_chain(path) == 12


def test_a_chain_file_without_checksums_gets_them_from_its_next_step(tmp_path):
    path = tmp_path / "chain.h5"
    whole = toy_chain()
    toy_chain(path, steps=4)
    with h5py.File(path, "r+") as f:                 # as an older flocksweep wrote it
        del f["mcmc"][chainfile.CHECKSUM]
        del f["mcmc"].attrs["checksums_from"]
    assert chainfile.check_chain(path) == 4
    assert same(toy_chain(path, resume=True), whole)
    with h5py.File(path, "r") as f:
        assert f["mcmc"].attrs["checksums_from"] == 4
    assert chainfile.check_chain(path) == 12


def test_a_resume_with_another_walker_count_is_a_mismatch_not_a_traceback(tmp_path):
    path = tmp_path / "chain.h5"
    toy_chain(path, steps=3)
    with pytest.raises(ChainMismatch) as info:
        run_bsl(toy, OBSERVED, PRIOR, walkers=8, steps=5, seed=3, path=path, resume=True)
    assert info.value.key == "--resume" and "walkers: stored 6, now 8" in str(info.value)


def test_a_full_disk_while_writing_a_step_names_the_chain_file(tmp_path, monkeypatch):
    path = tmp_path / "chain.h5"

    def full(self, g, iteration, state, accepted):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(chainfile.ChainFile, "_stage", full)
    with pytest.raises(WriteFailed) as info:
        toy_chain(path)
    assert info.value.filename == str(path) and info.value.errno == errno.ENOSPC


def test_the_chain_file_stays_readable_by_emcee_and_h5py(tmp_path):
    import emcee

    path = tmp_path / "chain.h5"
    result = toy_chain(path)
    plain = emcee.backends.HDFBackend(str(path), name="mcmc", read_only=True)
    assert np.array_equal(plain.get_chain(), result.chain)
    assert np.array_equal(plain.accepted, (result.acceptance_fraction * 12).round())
    with h5py.File(path, "r") as f:
        assert f["mcmc"].attrs["iteration"] == 12 and f["mcmc"].attrs["walkers"] == 6


# -- interrupts --------------------------------------------------------------------------------------

@pytest.mark.slow
def test_an_interrupted_calibration_saves_its_chain_and_resumes_bit_for_bit(tmp_path, capsys, monkeypatch):
    from flocksweep.analysis.calibration import simulator

    config = str(ROOT / "configs/calibration/recover_holland.toml")
    settings = ["--no-progress", "--set", "method.kind=emcee", "--set", "method.emcee.steps=4", "--set", "method.n_sim=6", "--set", "run.n=6",
                "--set", "run.duration=2.5", "--set", "method.emcee.reevaluate_every=0"]
    assert main(["calibrate", config, "--out", str(tmp_path / "whole")] + settings) == 0
    real, calls = simulator.SummarySimulator.simulate, []

    def interrupted(self, theta, seeds):
        calls.append(1)
        if len(calls) == 8 + 2 * 8 + 1:      # 8 initial walkers (more if some are redrawn), 8 proposals a step
            raise KeyboardInterrupt
        return real(self, theta, seeds)
    monkeypatch.setattr(simulator.SummarySimulator, "simulate", interrupted)
    out = tmp_path / "cut"
    assert main(["calibrate", config, "--out", str(out)] + settings) == 130
    err = capsys.readouterr().err
    # (a cold numba cache prints its compile notice first)
    assert "\nflocksweep: interrupted (SIGINT)" in "\n" + err and "Traceback" not in err
    steps = chainfile.stored_steps(out / "chain.h5")
    assert steps >= 1 and steps < 4 and f"saved: {steps} chain steps in {out / 'chain.h5'}; resume with: flocksweep " in err
    monkeypatch.undo()
    assert main(["calibrate", config, "--out", str(out)] + settings) == 0    # the same command continues it
    assert faults.same_chain(tmp_path / "whole", out) == ""


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("uninterrupted")
    _, span = faults.timed_run(faults.calibration_argv(folder), folder, faults.calibration_ready(folder))
    return folder / "out", span


@pytest.mark.slow
@pytest.mark.parametrize("how", faults.HOW)
def test_a_calibration_killed_at_a_random_moment_resumes_bit_for_bit(how, tmp_path, uninterrupted):
    reference, seconds = uninterrupted
    trial, rerun, difference = faults.calibration_trial(tmp_path, reference, how, 1, window=(0.1, 0.8 * seconds))
    assert trial.hit, f"the calibration had finished before the signal ({trial.delay:.1f} s)"
    assert trial.exit_code == faults.EXPECTED_EXIT[how], trial.stderr
    assert not trial.traceback, trial.stderr
    if how in ("sigint", "sigterm"):
        assert trial.stderr.startswith("flocksweep: interrupted (")
        assert "--resume" in trial.stderr or "no chain step was saved yet: run the same command" in trial.stderr
    assert trial.orphans == []
    assert rerun.returncode == 0 and "Traceback" not in rerun.stderr, rerun.stderr
    assert difference == ""


@pytest.mark.slow
def test_a_full_disk_while_npe_writes_posterior_nc_is_exit_4_and_keeps_the_accounting(tmp_path):
    """issue 42: a traceback, then SIGSEGV, before. Now exit 4 naming posterior.nc, no traceback; the
    calibration's accounting.json says it failed writing, with its simulations counted, and the estimator it
    trained is kept sealed: the same command, space freed, reuses it (no training run)."""
    pytest.importorskip("flowjax", reason="the sbi extra")
    case = {c.name: c for c in faults.CONTAINED}["npe: a full disk while posterior.nc is written"]
    result = faults.contained_trial(case, tmp_path)
    assert result.problems == []
    import json

    from flocksweep.analysis.calibration.estimator_folder import verify
    accounting = json.loads((tmp_path / "out" / "accounting.json").read_text())
    assert accounting["status"] == "failed" and "posterior.nc" in accounting["error"]
    assert accounting["accounting"]["simulations"]["training"] == 60
    assert accounting["accounting"]["simulations"]["predictive"] == 100
    verify(tmp_path / "out" / "estimator")
    assert not (tmp_path / "out" / "posterior.nc").exists()
