"""When a results folder's runs were computed (sweeps.status.computed): from the invocations that
computed runs, never a rerun that found everything done; first computed and last extended when a sweep
grew; older manifests by their own times."""
from __future__ import annotations

from flocksweep.sweeps.status import computed


def invocation(started, finished, runs):
    return {"started": started, "finished": finished, "computed": runs, "started_unix": 0}


def test_a_no_op_rerun_does_not_change_when_the_results_were_computed():
    manifest = {"started": "T9", "finished": "T9b", "computed_this_invocation": 0,
                "invocations": [invocation("T1", "T2", 8)]}
    assert computed(manifest) == "T1 to T2 (8 runs)"


def test_an_extended_sweep_says_when_it_was_first_computed_and_last_extended():
    manifest = {"started": "T9", "finished": "T9b",
                "invocations": [invocation("T1", "T2", 8), invocation("T3", None, 2), invocation("T5", "T6", 4)]}
    assert computed(manifest) == ("first computed T1 to T2 (8 runs); last extended T5 to T6 (4 runs) "
                                  "(3 invocations computed runs)")


def test_a_manifest_without_invocations_uses_its_own_times():
    assert computed({"started": "T1", "finished": "T2"}) == "T1 to T2"
    assert computed({"started": "T1", "finished": None}) == "T1 to unfinished"
    assert computed({}) == "unknown"
