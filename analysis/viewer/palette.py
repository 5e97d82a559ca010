"""The viewer's colour modes and fixed colours, in one light module (the command line's help reads it
without loading the viewer's encoder).

* ``COLOR_MODES``: how boids can be coloured (per boid, Holland's pattern, leader state, group, speed);
* ``TABLE_1_HEX``: the colours of Holland & Semwal's Table 1 patterns;
* ``AGENT_COLOURS``: the predator and the prey (Boids++), in colours no boid colouring uses: magenta and
  black lie outside the turbo (per boid) and viridis (speed) maps and Table 1's four colours, so
  neither is taken for a boid (the red and green they had were the ends of turbo and a pattern colour).
"""
from __future__ import annotations

COLOR_MODES = ("boid", "pattern", "leader", "group", "speed")
AGENT_COLOURS = {"predator": "#e6007e", "prey": "#000000"}
TABLE_1_HEX = {0b00000000: "#ffd700", 0b00111010: "#008000", 0b11000101: "#0000ff", 0b11111111: "#ff0000"}
