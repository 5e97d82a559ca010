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


# ------------------------------------------------------------------ every sample inside the declared tank

def _measured(path, **interval):
    from flocksweep.observables.measured import prepare_flocks
    from flocksweep.observables.tracks import load_tracks

    return prepare_flocks(load_tracks(path, track_source(path, {})), **interval)


def test_tracks_inside_their_tank_pass_and_the_tank_is_in_body_lengths(tmp_path):
    from tank_tracks import write_tank_tracks

    path = write_tank_tracks(tmp_path)
    source = track_source(path, {})
    assert source.tank().radius == pytest.approx(10.0) and source.tank().centre == pytest.approx((16.0, 12.0, 0.0))
    prepared, issues = _measured(path)
    assert len(prepared) == 2 and not [i for i in issues if i.check == "outside the tank"]
    assert [i for i in issues if i.check == "gap"]                     # the fixture's gap is there, and bridged


def test_samples_just_outside_the_wall_are_a_warning_and_far_outside_an_error(tmp_path):
    from flocksweep.observables.validation import TrackError, beyond_wall
    from tank_tracks import TANK, write_tank_tracks

    # flock B's outermost fish mills at 145 px: 3 px (0.15 BL) beyond a 142 px wall, within 5% of 7.1 BL
    near = write_tank_tracks(tmp_path, "near", arena={**TANK, "radius": 142.0})
    prepared, issues = _measured(near)
    outside = [i for i in issues if i.check == "outside the tank"]
    assert len(prepared) == 2 and [(i.level, i.flock, i.id) for i in outside] == [("warning", "B", "5")]
    assert "0.15 BL outside" in outside[0].detail and len(outside[0].rows) == 80
    # a wall at 130 px: flock A's fish 5 (140 px) is 0.5 BL out, beyond the tolerance (0.325 BL): an error
    far = write_tank_tracks(tmp_path, "far", arena={**TANK, "radius": 130.0})
    with pytest.raises(TrackError) as err:
        _measured(far)
    found = [i for i in err.value.issues if i.check == "outside the tank"]
    assert {(i.level, i.flock) for i in found} == {("error", "A"), ("error", "B")}
    assert "circle of radius 6.5 BL about (16, 12)" in str(err.value)
    assert "check the arena's centre and size" in str(err.value)
    # a box: its distance beyond the walls is the largest excess over the half sides
    box = Arena(kind="box", centre=(1.0, 1.0, 0.0), size=(4.0, 2.0, 2.0))
    assert beyond_wall(box, [[1.0, 1.0, 5.0], [4.0, 1.0, 0.0], [1.0, 2.5, 0.0]], 2) == pytest.approx([-1.0, 1.0, 0.5])
    cyl = Arena(kind="cylinder", radius=2.0, height=2.0)
    assert beyond_wall(cyl, [[0.0, 0.0, 3.0], [1.0, 0.0, 0.0]], 3) == pytest.approx([2.0, -1.0])
    assert beyond_wall(cyl, [[0.0, 0.0, 3.0]], 2) == pytest.approx([-2.0])   # 2-D tracks: the plane only
