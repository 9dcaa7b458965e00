#!/usr/bin/env python3
"""Inputs of tests/cli/align.sh, made from examples/2d: the template moved
by a known rigid motion (rotation 30 degrees about the origin, then a
translation of 100 template diameters), the target in millimetres (the
background's coordinates and distances times 1000) against the template
in metres, landmark CSV files (the moved template's points and where they
belong), and malformed landmark files.  Usage: align_inputs.py EXAMPLE_DIR WORK"""
import gzip
import math
import sys

ANGLE = math.radians(30.0)
SHIFT = (40.0, -30.0)   # |SHIFT| = 50 = 100 diameters of the 0.5-wide disk


def move(x, y):
    c, s = math.cos(ANGLE), math.sin(ANGLE)
    return c * x - s * y + SHIFT[0], s * x + c * y + SHIFT[1]


def rewrite_vertices(lines, fn):
    """Medit ASCII: the Vertices section's coordinates through fn."""
    out, i = [], 0
    while i < len(lines):
        out.append(lines[i])
        if lines[i].strip() == "Vertices":
            n = int(lines[i + 1])
            out.append(lines[i + 1])
            for k in range(n):
                x, y, ref = lines[i + 2 + k].split()
                u, v = fn(float(x), float(y))
                out.append(" %.17g %.17g %s\n" % (u, v, ref))
            i += 2 + n
            continue
        i += 1
    return out


def main():
    ex, work = sys.argv[1], sys.argv[2]
    with open(ex + "/template.mesh") as f:
        lines = f.readlines()
    with open(work + "/moved.mesh", "w") as f:
        f.writelines(rewrite_vertices(lines, move))
    with gzip.open(ex + "/background.mesh.gz", "rt") as f:
        lines = f.readlines()
    with open(work + "/mm.mesh", "w") as f:
        f.writelines(rewrite_vertices(lines, lambda x, y: (1000 * x, 1000 * y)))
    with gzip.open(ex + "/background.sol.gz", "rt") as f:
        sol = f.read().split("\n")
    # SolAtVertices: count, "1 1", then one value a line until End
    out, in_values = [], False
    for k, line in enumerate(sol):
        if in_values and line.strip() and line.strip() != "End":
            line = "%.17g" % (1000 * float(line))
        if line.strip() == "1 1":
            in_values = True
        if line.strip() == "End":
            in_values = False
        out.append(line)
    with open(work + "/mm.sol", "w") as f:
        f.write("\n".join(out))
    points = [(0.5, 0.5), (0.75, 0.5), (0.5, 0.75), (0.3, 0.4)]
    with open(work + "/lm_template.csv", "w") as f:
        f.write("x,y\n")
        for p in points:
            f.write("%.17g,%.17g\n" % move(*p))
    with open(work + "/lm_target.csv", "w") as f:
        f.write("# where the points belong\n")
        for p in points:
            f.write("%.17g, %.17g\n" % p)
    with open(work + "/lm_three.csv", "w") as f:
        for p in points[:3]:
            f.write("%.17g,%.17g\n" % p)
    with open(work + "/lm_bad.csv", "w") as f:
        f.write("0.5,0.5\n0.75,zero\n")
    with open(work + "/lm_same.csv", "w") as f:
        f.write("1,1\n1,1\n1,1\n1,1\n")


main()
