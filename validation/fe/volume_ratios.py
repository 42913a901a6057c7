#!/usr/bin/env python3
"""Volume ratio V/V0 of the cell and the smallest element volume ratio J per increment
of an axisymmetric plates run of run_references.py (CAX8 / CAX8R, quarter model).

    python3 validation/fe/volume_ratios.py plates_w1_nu0.45_L2_cax8 [--from 0.8]

Each element's volume is that of the solid of revolution of its 8-node boundary polygon
(Pappus: 2 pi r_centroid A), so J is an element average; the run's .inp and .frd are read
from validation/fe/runs/<run>/ (made by run_references.py, not kept in git).
"""
import argparse
import math
import os

import run_references as rr


def read_deck(path):
    """Nodes {id: (r, z)} and the CELL elements (8 node ids each) of a 2-D deck."""
    nodes, elems, mode = {}, [], None
    for ln in open(path):
        if ln.startswith("*"):
            u = ln.upper()
            if u.startswith("*NODE,"):
                mode = "node"
            elif u.startswith("*ELEMENT") and "ELSET=CELL" in u:
                mode = "cell"
            else:
                mode = None
            continue
        if mode == "node":
            p = ln.split(",")
            nodes[int(p[0])] = (float(p[1]), float(p[2]))
        elif mode == "cell":
            elems.append([int(x) for x in ln.strip().strip(",").split(",")][1:9])
    return nodes, elems


def revolved_volume(pos, e):
    """Volume of revolution of the element's boundary (corner, mid-side, corner, ...)."""
    poly = [pos[e[0]], pos[e[4]], pos[e[1]], pos[e[5]], pos[e[2]], pos[e[6]], pos[e[3]], pos[e[7]]]
    area = moment = 0.0
    for i in range(8):
        (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % 8]
        c = x0 * y1 - x1 * y0
        area += c
        moment += (x0 + x1) * c
    return 2.0 * math.pi * moment / 6.0  # 2 pi r_c A with r_c A = moment / 6


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run", help="run name, e.g. plates_w1_nu0.45_L2_cax8")
    ap.add_argument("--from", dest="start", type=float, default=0.0, help="first deformation printed")
    a = ap.parse_args()
    case = next(c for c in sorted(rr.CASES, key=len, reverse=True) if a.run.startswith(c + "_L"))
    cfg = rr.CASES[case]
    wd = os.path.join(rr.RUNS, a.run)
    nodes, elems = read_deck(os.path.join(wd, "job.inp"))
    v0 = [revolved_volume(nodes, e) for e in elems]
    print("deformation  V/V0    min J  at r/R   z/R")
    for t, disp in rr.read_frd_disp3(os.path.join(wd, "job.frd")):
        eps = cfg["eps_max"] * rr.amp(t)
        if eps < a.start:
            continue
        pos = {k: (x + disp.get(k, (0, 0, 0))[0], z + disp.get(k, (0, 0, 0))[1]) for k, (x, z) in nodes.items()}
        j = [revolved_volume(pos, e) / v0[i] for i, e in enumerate(elems)]
        k = min(range(len(j)), key=j.__getitem__)
        r, z = (sum(pos[n][c] for n in elems[k][:4]) / 4 / cfg["R"] for c in range(2))
        print("%.4f       %.4f  %.3f  %.3f    %.3f" % (eps, sum(revolved_volume(pos, e) for e in elems) / sum(v0), j[k], r, z))


if __name__ == "__main__":
    main()
