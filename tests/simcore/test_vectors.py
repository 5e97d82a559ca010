"""The one 3-vector check and the one direction of the config files (simcore.schema), used by obstacles,
reynolds.migration_direction and the Boids++ prey's target centre alike."""
import numpy as np
import pytest

from flocksweep.simcore.boidspp_params import Prey
from flocksweep.simcore.obstacle_spec import Obstacle
from flocksweep.simcore.reynolds_params import Reynolds
from flocksweep.simcore.schema import ConfigError, check_vector3, unit_vector3


@pytest.mark.parametrize("bad, message", [(None, "list of 3 numbers"), ([1, 2], "list of 3 numbers"),
                                          ("abc", "list of 3 numbers"), ([1, True, 0], "list of 3 numbers"),
                                          ([1, float("inf"), 0], "every component must be finite")])
def test_a_bad_vector_is_refused_alike_by_every_table(bad, message):
    builders = [lambda v: check_vector3("k", v), lambda v: Prey(target_centre=v),
                lambda v: Reynolds(migration_direction=v)]
    if bad is not None:   # an obstacle's None is a key not given ("missing key")
        builders.append(lambda v: Obstacle(kind="plane", centre=(0, 0, 0), normal=v))
    for build in builders:
        with pytest.raises(ConfigError, match=message):
            build(bad)


def test_a_direction_is_divided_by_its_length_unless_already_unit():
    assert unit_vector3("k", np.array([0, 3, 4])) == (0.0, 0.6, 0.8)
    nearly = (1.0 + 5e-13, 0.0, 0.0)
    assert unit_vector3("k", nearly) == nearly                     # within 1e-12: kept as written
    assert Reynolds(migration_direction=(0.0, 0.0, 2.0)).migration_direction == (0.0, 0.0, 1.0)
    with pytest.raises(ConfigError, match="non-zero vector"):
        unit_vector3("axis", (0, 0, 0))
