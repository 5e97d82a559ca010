"""The compile notice (simcore.simulate): one line when a run loop starts compiling, with an estimate,
and one when it is done, with its time; pieces compiled inside it say nothing; each later run loop of
the process is named too; the seconds are counted (what `flocksweep simulate` reports apart)."""
from __future__ import annotations

import importlib
import re

simulate_module = importlib.import_module("flocksweep.simcore.simulate")   # the module (simcore.simulate is the function)


def test_each_run_loop_compile_is_announced_with_an_estimate_and_timed(capsys, monkeypatch):
    monkeypatch.setattr(simulate_module, "_NOTICE_SHOWN", False)
    before = simulate_module.compile_seconds()
    first = simulate_module._CompileNotice("run_model (binocular perception)")
    first.on_start(None)
    first.on_start(None)   # a piece compiled inside the run loop
    first.on_end(None)
    first.on_end(None)
    second = simulate_module._CompileNotice("run_reynolds")
    second.on_start(None)
    second.on_end(None)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 4
    assert lines[0].startswith("simcore: compiling the simulation kernels: run_model (binocular perception) (once")
    assert simulate_module.COMPILE_ESTIMATE in lines[0]
    assert re.fullmatch(r"simcore: compiled run_model \(binocular perception\) in \d+ s \(cached for later runs\)",
                        lines[1])
    assert lines[2].startswith("simcore: compiling one more run loop: run_reynolds")
    assert lines[3].startswith("simcore: compiled run_reynolds in ")
    assert simulate_module.compile_seconds() >= before
