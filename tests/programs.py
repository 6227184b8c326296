"""Small generated programs for the tests of files, faults and the command line."""

from __future__ import annotations


def dome(n: int = 10, rev: int = 0, spindle: bool = True) -> bytes:
    """A zig-zag finish over a dome (n x n points, D6 ball work, S4000 F800): plans in a few
    tens of ms; n=60 gives a rewrite (132 KB) larger than a pipe holds.  ``rev`` changes the
    dome (another CAM output); without ``spindle`` there is nothing to plan."""
    lines = [f"(dome rev {rev})", "G21 G90 G94 G17", "T1 M6", "S4000 M3" if spindle else "M5",
             "G0 X-10 Y-10 Z15"]
    for i in range(n):
        y = -10 + 20 * i / (n - 1)
        xs = [-10 + 20 * k / (n - 1) for k in range(n)]
        for j, x in enumerate(xs if i % 2 == 0 else xs[::-1]):
            z = 10 - (x * x + y * y) / (40 + rev)
            lines.append(f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f}" + (" F800" if i == j == 0 else ""))
    return ("\n".join(lines + ["G0 Z20", "M30"]) + "\n").encode()
