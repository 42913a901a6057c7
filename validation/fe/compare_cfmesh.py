#!/usr/bin/env python3
"""Tables of validation/fe/cfmesh.md: forces and energies per load point, cellflow (its two
volumetric terms) against CalculiX on cellflow's own mesh (C3D4, C3D10), the axisymmetric
reference (L3) and the 3-D check (eighth sphere L1).

    python3 validation/fe/compare_cfmesh.py --cf NODAL=/tmp/cf_na.h5 --cf PER_TET=/tmp/cf_pt.h5 \
        --ccx cfmesh_C3D4_load_1000 --ccx cfmesh_C3D10_load_1000

Forces at the load points by linear interpolation in the deformation; the axisymmetric
energy is the work of its force, the trapezoidal integral of F d(delta).
"""
import argparse
import csv
import os

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
POINTS = [0.3, 0.5, 0.6, 0.64, 0.66, 0.68, 0.7, 0.72, 0.74, 0.76, 0.78, 0.8]
R = 8.6e-6


def table(path, xcol, fcol, ecol=None, step=None):
    rows = list(csv.DictReader(open(path)))
    if step is not None:
        rows = [r for r in rows if int(r["step"]) == step]
    x = np.array([float(r[xcol]) for r in rows])
    F = np.array([float(r[fcol]) for r in rows])
    E = np.array([float(r[ecol]) for r in rows]) if ecol else None
    return x, F, E


def at(x, y, p):
    return float(np.interp(p, x, y)) if len(x) and x[0] - 1e-9 <= p <= x[-1] + 1e-9 else float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cf", action="append", default=[], help="LABEL=result.h5")
    ap.add_argument("--ccx", action="append", default=[], help="run name (curves/<name>.csv)")
    ap.add_argument("--step", type=int, default=None, help="only this ccx step (restart runs: 2)")
    a = ap.parse_args()
    xa, Fa, _ = table(os.path.join(HERE, "curves", "plates_w0.25.csv"), "deformation", "force_n")
    Wa = np.concatenate([[0.0], np.cumsum(0.5 * (Fa[1:] + Fa[:-1]) * np.diff(xa * 2 * R))])
    x3, F3, E3 = table(os.path.join(HERE, "curves", "plates_w0.25_3d_L1.csv"), "deformation", "force_n",
                       "elastic_energy_j")
    series = []
    for spec in a.cf:
        label, path = spec.split("=", 1)
        ob = h5py.File(path, "r")["observables"]
        series.append(("cf " + label, ob["deformation/value"][:], ob["force_n/value"][:],
                       ob["elastic_energy_j/value"][:]))
    for name in a.ccx:
        x, F, E = table(os.path.join(HERE, "curves", name + ".csv"), "deformation", "force_top_n",
                        "elastic_energy_j", a.step)
        series.append((name.replace("cfmesh_", "ccx "), x, F, E))
    print("Forces [nN] (ratio to the axisymmetric reference):\n")
    print("| eps | axisym. L3 | 3-D L1 | " + " | ".join(s[0] for s in series) + " |")
    print("|---" * (3 + len(series)) + "|")
    for p in POINTS:
        fa = at(xa, Fa, p)
        cells = ["%.2f" % p, "%.4g" % (fa * 1e9), "%.4g (%.4f)" % (at(x3, F3, p) * 1e9, at(x3, F3, p) / fa)]
        for _, x, F, _ in series:
            f = at(x, F, p)
            cells.append("%.4g (%.4f)" % (f * 1e9, f / fa) if f == f else "-")
        print("| " + " | ".join(cells) + " |")
    print("\nElastic energy [pJ] (ratio to the axisymmetric work):\n")
    print("| eps | axisym. work | 3-D L1 | " + " | ".join(s[0] for s in series) + " |")
    print("|---" * (3 + len(series)) + "|")
    for p in POINTS:
        wa = at(xa, Wa, p)
        cells = ["%.2f" % p, "%.4g" % (wa * 1e12), "%.4g (%.4f)" % (at(x3, E3, p) * 1e12, at(x3, E3, p) / wa)]
        for _, x, _, E in series:
            e = at(x, E, p)
            cells.append("%.4g (%.4f)" % (e * 1e12, e / wa) if e == e else "-")
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
