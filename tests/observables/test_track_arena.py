"""A track file declares its tank (observables.tracks.TrackSource.arena, docs/measured.md): the geometry in
the file's length unit, checked when the source is read, and given back in the analysis unit as the
simulator's own [arena] table (simcore.arena.Arena), so simulations and tracks share one tank."""
from __future__ import annotations

import pytest

from flocksweep.observables.tracks import TrackSource, read_sidecar, track_source
from flocksweep.simcore.arena import Arena
from flocksweep.simcore.schema import ConfigError


def test_a_tank_in_metres_is_given_in_body_lengths():
    source = TrackSource(units={"length": "m"}, body_length=0.05,
                         arena={"kind": "cylinder", "centre": [0.5, 0.25, 0.0], "radius": 0.6})
    tank = source.tank()
    assert isinstance(tank, Arena) and tank.kind == "cylinder"
    assert tank.radius == pytest.approx(12.0) and tank.centre == pytest.approx((10.0, 5.0, 0.0))
    assert tank.contains((10.0 + 11.9, 5.0, 0.0), 2) and not tank.contains((10.0 + 12.1, 5.0, 0.0), 2)


def test_a_box_in_centimetres_and_in_pixels():
    cm = TrackSource(units={"length": "cm"}, arena={"kind": "box", "size": [100.0, 50.0, 30.0]})
    assert cm.tank().size == pytest.approx((1.0, 0.5, 0.3))                     # metres
    px = TrackSource(units={"length": "px"}, body_length_px=20.0,
                     arena={"kind": "box", "centre": [400.0, 300.0, 0.0], "size": [800.0, 600.0, 1.0]})
    assert px.tank().size == pytest.approx((40.0, 30.0, 0.05)) and px.tank().centre == pytest.approx((20.0, 15.0, 0.0))
    assert TrackSource().tank() is None


@pytest.mark.parametrize("arena, key", [
    ({"kind": "bowl", "radius": 1.0}, "arena.kind"),
    ({"radius": 1.0}, "arena.kind"),
    ({"kind": "cylinder", "radius": -1.0}, "arena.radius"),
    ({"kind": "cylinder", "radius": 1.0, "wall_weight": 3.0}, "arena.wall_weight"),   # the model's, not the file's
    ({"kind": "box", "size": [1.0, 2.0]}, "arena.size"),
])
def test_a_bad_tank_is_refused_naming_the_key(arena, key):
    with pytest.raises(ConfigError) as err:
        TrackSource(arena=arena)
    assert err.value.key == key


def test_a_sidecar_declares_the_tank(tmp_path):
    tracks = tmp_path / "fish.csv"
    tracks.write_text("id,t,x,y\n1,0.0,0.1,0.2\n")
    (tmp_path / "fish.json").write_text('{"units": {"length": "m"}, "body_length": 0.04, '
                                        '"arena": {"kind": "cylinder", "radius": 0.4}}')
    source = track_source(tracks, read_sidecar(tracks))
    assert source.tank().radius == pytest.approx(10.0)
