"""Tiny test meshes and the path of the nmbake binary under test."""

import math
import os


def nmbake_binary():
    """The binary ctest passes in $NMBAKE (tests/CMakeLists.txt), else the
    release build's."""
    given = os.environ.get("NMBAKE")
    if given:
        return given
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "build", "nmbake"))


def write_pair(folder, low_name="low.obj", high_name="high.obj"):
    """Writes a low quad with UVs (z = 0, [-1, 1]²) and a wavy high grid
    over it; returns their paths."""
    low = os.path.join(folder, low_name)
    high = os.path.join(folder, high_name)
    with open(low, "w", encoding="utf-8") as f:
        f.write("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n")
        f.write("vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n")
        f.write("f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n")
    n = 24
    with open(high, "w", encoding="utf-8") as f:
        for j in range(n + 1):
            for i in range(n + 1):
                x = -1.0 + 2.0 * i / n
                y = -1.0 + 2.0 * j / n
                z = 0.05 * math.sin(3.0 * x) * math.cos(2.0 * y)
                f.write("v %.6f %.6f %.6f\n" % (x, y, z))
        for j in range(n):
            for i in range(n):
                a = j * (n + 1) + i + 1
                b, c, d = a + 1, a + n + 2, a + n + 1
                f.write("f %d %d %d\nf %d %d %d\n" % (a, b, c, a, c, d))
    return low, high
