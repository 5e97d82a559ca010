"""The viewer's colour modes and fixed colours, in one light module (the command line's help reads it
without loading the viewer's encoder).

* ``COLOR_MODES``: how boids can be coloured (per boid, Holland's pattern, leader state, group, speed);
* ``TABLE_1_HEX``: the colours of Holland & Semwal's Table 1 patterns;
* ``AGENT_COLOURS``: the predator and the prey (Boids++).
"""
from __future__ import annotations

COLOR_MODES = ("boid", "pattern", "leader", "group", "speed")
AGENT_COLOURS = {"predator": "#d62728", "prey": "#2ca02c"}
TABLE_1_HEX = {0b00000000: "#ffd700", 0b00111010: "#008000", 0b11000101: "#0000ff", 0b11111111: "#ff0000"}
