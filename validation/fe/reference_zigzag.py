#!/usr/bin/env python3
"""The reference curves' own raggedness: each row's ln F against a quadratic
in ln x fitted to the 7 rows around it (least squares, the row included), as
a percentage of the force; printed per range of x as the largest and the rms
departure. CalculiX's node-to-surface contact takes its nodes into contact in
steps, and the rows alternate about a smooth curve; interpolated between rows
the alternation mostly averages out (plates_w1: L3 and L4 agree to 0.13 % at
cellflow's load points while their rows alternate by up to 0.3-0.4 %;
validation/fe/README.md, "Graded poles with the rings moved").

    python3 validation/fe/reference_zigzag.py plates_w1 colloidal_probe small_probe

Python 3 standard library only.
"""
import math
import sys

from compare_cellflow import polynomial_fit, reference_rows

# case prefix: (x column, ranges of x to report, unit scale, unit)
COLUMNS = {
    "plates": ("deformation", [(0.02, 0.1), (0.1, 0.3), (0.3, 0.8)], 1.0, ""),
    "colloidal": ("indentation_m", [(0.25e-6, 2e-6), (2e-6, 20e-6)], 1e6, " um"),
    "small": ("indentation_m", [(0.1e-6, 0.5e-6), (0.5e-6, 2e-6)], 1e6, " um"),
}


def main():
    for name in sys.argv[1:] or ["plates_w1", "plates_w0.5", "plates_w0.25", "colloidal_probe", "small_probe"]:
        column, ranges, scale, unit = COLUMNS[name.split("_")[0]]
        rows = [(x, y) for x, y in reference_rows(name, column) if x > 0 and y > 0]
        lx = [math.log(x) for x, _ in rows]
        ly = [math.log(y) for _, y in rows]
        departures = []
        for i in range(3, len(rows) - 3):
            us = [u - lx[i] for u in lx[i - 3:i + 4]]
            # the quadratic's value at u = 0 (the row itself) is its c_0
            departures.append((rows[i][0], 100.0 * (ly[i] - polynomial_fit(list(zip(us, ly[i - 3:i + 4])), 2)[0])))
        for lo, hi in ranges:
            d = [abs(e) for x, e in departures if lo * (1 - 1e-9) <= x <= hi * (1 + 1e-9)]
            if not d:
                continue
            rms = math.sqrt(sum(e * e for e in d) / len(d))
            print(f"{name}: x {lo * scale:g}-{hi * scale:g}{unit}: {len(d)} rows, largest {max(d):.3f} %, "
                  f"rms {rms:.3f} %")


if __name__ == "__main__":
    main()
