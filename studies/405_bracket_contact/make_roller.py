"""Writes roller.obj, the support of study 405: a circle of radius 0.05 m centred at
(0.1, -0.0505) m as a closed 2D polyline of 48 segments (OBJ `v`/`l` records), so that its
top vertex (0.1, -0.0005) lies 0.5 mm below the bridge's bottom edge (y = 0).
Deterministic (no random numbers). Run from the repository root:

    /usr/bin/python3 studies/405_bracket_contact/make_roller.py
"""
import math
import pathlib

RADIUS, CENTER, SEGMENTS = 0.05, (0.1, -0.0505), 48

path = pathlib.Path(__file__).resolve().parent / "roller.obj"
lines = [f"# study 405: roller support, circle r = {RADIUS} m at {CENTER}, {SEGMENTS} segments (make_roller.py)"]
for i in range(SEGMENTS):
    a = math.pi / 2 + 2 * math.pi * i / SEGMENTS  # vertex 1 is the top of the roller
    lines.append(f"v {CENTER[0] + RADIUS * math.cos(a):.15g} {CENTER[1] + RADIUS * math.sin(a):.15g} 0")
lines += [f"l {i + 1} {(i + 1) % SEGMENTS + 1}" for i in range(SEGMENTS)]
path.write_text("\n".join(lines) + "\n")
print(f"wrote {path} ({SEGMENTS} vertices, {SEGMENTS} segments)")
