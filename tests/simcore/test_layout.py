"""Named slots (simcore/layout.py): every packed parameter and per-boid buffer column is declared once.

The float and int slots, their IntEnums and ``pack`` come from one declaration each, so they cannot
disagree; the compiled kernel reads a slot by name.
"""
from __future__ import annotations

import math

import numpy as np

from conftest import make_model
from flocksweep.simcore.jit import leaf
from flocksweep.simcore.layout import FLOAT_SLOTS, HB, INT_SLOTS, OS, STEER_WIDTH, F, I, pack
from flocksweep.simcore.hartman_benes_params import Gains
from flocksweep.simcore.opensteer_params import Steering
from flocksweep.simcore.params import Leadership, ModelParams, Perception, Vehicle


def test_enums_follow_the_declarations():
    assert [m.name for m in F] == list(FLOAT_SLOTS) and [m.value for m in F] == list(range(len(FLOAT_SLOTS)))
    assert [m.name for m in I] == list(INT_SLOTS) and [m.value for m in I] == list(range(len(INT_SLOTS)))


def test_pack_fills_every_slot_from_its_declaration():
    model = ModelParams(perception=Perception(kind="binocular", direction_deg=30.0, field_deg=150.0, range=12.0),
                        steering=Steering(1.0, 2.0, 3.0), vehicle=Vehicle(7.0, 21.0, 2.0), gains=Gains(0.01, 0.02, 0.3),
                        leadership=Leadership(x=0.5, duration=2.0))
    fp, ip = pack(model, 0.02)
    assert fp.shape == (len(F),) and ip.shape == (len(I),)
    for name, value in FLOAT_SLOTS.items():
        assert fp[F[name]] == value(model, 0.02), name
    for name, value in INT_SLOTS.items():
        assert ip[I[name]] == value(model, 0.02), name
    assert fp[F.DT] == 0.02 and fp[F.MAX_SPEED] == 7.0 and fp[F.RANGE] == 12.0
    assert fp[F.COS_HALF_FIELD] == math.cos(math.radians(75.0)) and ip[I.LEADERSHIP] == 1


def test_unset_topological_radius_packs_as_infinite():
    fp, _ = pack(make_model("topological"), 0.01)
    assert fp[F.TOPO_RADIUS] == math.inf
    fp, _ = pack(make_model("topological", max_distance=3.0), 0.01)
    assert fp[F.TOPO_RADIUS] == 3.0


@leaf
def _read_slots(fp, ip):
    return fp[F.MAX_FORCE], ip[I.NEIGHBOURS]


def test_compiled_code_reads_slots_by_name():
    fp, ip = pack(make_model("topological", neighbours=5, vehicle=Vehicle(max_force=13.0)), 0.01)
    assert _read_slots(fp, ip) == (13.0, 5)


def test_steer_buffer_columns_fit_every_dynamics():
    assert STEER_WIDTH == max(len(OS), len(HB)) == 9
    assert [m.value for m in HB] == list(range(9)) and [m.value for m in OS] == [0, 1, 2]
    assert np.zeros((2, STEER_WIDTH))[:, HB.MZ].shape == (2,)
