"""Synthetic tracks of fish in a circular tank, as a tracker delivers them: positions in pixels (a sidecar
gives the body length in pixels and the tank), two flocks, one fish with a gap of a few samples. The tank:
centre (320, 240) px, radius 200 px, body length 20 px: a circle of radius 10 BL about (16, 12) BL."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd

CENTRE_PX = (320.0, 240.0)
RADIUS_PX = 200.0
BODY_LENGTH_PX = 20.0
TANK = {"kind": "cylinder", "centre": [CENTRE_PX[0], CENTRE_PX[1], 0.0], "radius": RADIUS_PX}


def write_tank_tracks(folder, name: str = "tank", n: int = 6, samples: int = 80, interval: float = 0.1,
                      arena: dict | None = TANK, outside_px: float = 0.0, flocks=("A", "B")):
    """``folder/name.csv`` and its sidecar; ``outside_px`` moves one sample of flock A's fish 0 that far
    beyond the wall; ``arena`` None: the sidecar declares no tank. Returns the CSV's path."""
    rows = []
    for k, flock in enumerate(flocks):
        for i in range(n):
            radius = 60.0 + 16.0 * i + 5.0 * k                      # px from the centre
            for s in range(samples):
                if i == 2 and 20 <= s < 24:                          # a gap: fish 2 lost for four samples
                    continue
                angle = 0.3 * s * interval * (1 + 0.05 * i) + i
                x = CENTRE_PX[0] + radius * np.cos(angle)
                y = CENTRE_PX[1] + radius * np.sin(angle)
                rows.append((flock, i, round(s * interval, 6), x, y))
    path = folder / f"{name}.csv"
    pd.DataFrame(rows, columns=["flock", "id", "t", "x", "y"]).to_csv(path, index=False)
    sidecar = {"units": {"length": "px", "time": "s"}, "body_length_px": BODY_LENGTH_PX,
               "description": "synthetic fish milling in a round tank"}
    if arena is not None:
        sidecar["arena"] = arena
    (folder / f"{name}.json").write_text(json.dumps(sidecar))
    return path
