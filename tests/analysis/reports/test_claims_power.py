"""The replicates search of analysis.reports.claims.power: the fewest replicates with enough power, found from
the normal approximation's guess in a few calls, the same answer whatever the guess (each layout's simulated
data sets are its own stream, so "enough at r" is a function of r alone)."""
from __future__ import annotations

import numpy as np
import pytest

from flocksweep.analysis.reports.claims import power
from flocksweep.analysis.reports.claims.power import _fewest, _predicted


def counting(threshold: int | None):
    """A predicate true from ``threshold`` on (never when None), and the list of r it was asked at."""
    asked = []

    def enough(r: int) -> bool:
        asked.append(r)
        return threshold is not None and r >= threshold
    return enough, asked


@pytest.mark.parametrize("low, cap", [(1, 200), (3, 40), (2, 3), (1, 2)])
def test_the_search_finds_the_smallest_enough_whatever_the_guess(low, cap):
    for threshold in [*range(low + 1, cap + 1), None]:
        for guess in (low - 5, low + 1, (low + cap) // 2, cap, cap + 10, threshold or cap):
            enough, _ = counting(threshold)
            assert _fewest(enough, low, cap, guess) == threshold, (threshold, guess)


def test_a_good_guess_costs_a_few_calls_near_it_and_none_at_the_cap():
    enough, asked = counting(24)
    assert _fewest(enough, 1, 200, 22) == 24
    assert len(asked) <= 6 and max(asked) <= 48             # the old search began at the cap (200)
    enough, asked = counting(24)
    assert _fewest(enough, 1, 200, 30) == 24 and max(asked) == 30 and len(asked) <= 6


def test_the_guess_scales_with_the_square_of_the_z_ratio():
    # power 0.5 now at 4 replicates, alpha 0.05 (z 1.645): (0.842 + 1.645)^2 / 1.645^2 = 2.29 -> 4 * 2.29
    assert _predicted(4, 0.5, 0.05, 0.8) == 10
    assert _predicted(4, 0.0, 0.05, 0.8) == 8                # nothing to scale from: twice as many
    assert _predicted(1, 0.79, 0.05, 0.8) in (1, 2)


def test_enough_at_r_does_not_depend_on_what_the_search_tried_before(monkeypatch):
    """Two searches from different guesses ask the same layouts the same question with the same draws."""
    from flocksweep.analysis.reports.claims.kinds import LeafData

    class Test:        # a one-sample t test against 0, direction positive
        kind, method, value, claimed_sign, paired = "sign", "t", 0.0, 1, False

    rng = np.random.default_rng(0)
    data = LeafData(rng.normal(0.0, 1.0, 8), None, np.arange(8), None, 0)
    model = power._model(Test, data)
    answers = {}
    seen: dict[int, list[float]] = {}
    real = power._Simulation.power

    def recorded(self, effect, alpha):
        value = real(self, effect, alpha)
        seen.setdefault(len(self.point) // 8, []).append(value)
        return value
    monkeypatch.setattr(power._Simulation, "power", recorded)
    for guess in (2, 40):
        monkeypatch.setattr(power, "_predicted", lambda *args, g=guess: g)
        answers[guess] = power._replicates_needed(Test, model, 0.5, 0.05, 0.8, 400, 60,
                                                  np.random.default_rng(7), 0.2)
    assert answers[2] == answers[40] is not None
    assert all(len(set(values)) == 1 for values in seen.values())   # each r: one power, however often asked
    assert len([r for r, values in seen.items() if len(values) == 2]) >= 1
