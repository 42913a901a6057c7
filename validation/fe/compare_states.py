#!/usr/bin/env python3
"""cellflow's compression state against the 3-D CalculiX solution, frame by frame (issue 11 item 3).

    build/bin/cellflow-run -r /tmp/w025.h5 spec.json      # a compression run with position frames
    /usr/bin/python3 validation/fe/compare_states.py /tmp/w025.h5 [--run plates_w0.25_3d_L1] [--w 0.25]

For every position frame of the cellflow result: the effective deformation (1 - height / initial
height: the plates' penalty range keeps the vertices off the nominal gap), cellflow's force and
elastic energy (its own element) against the 3-D run at that deformation, the conforming per-tet
energy of eq. 5 evaluated on cellflow's positions (an admissible field: its energy bounds the
continuum minimum from above), the volume, the contact radius (upper surface within 2e-3 R of the
top) and the largest radius, the equatorial cos 2theta / cos 4theta content (|A_m| / r0, least
squares over the surface vertices within 0.1 height of the mid plane), and the number of vertices
strictly inside a tet they do not belong to (self-overlap).  The same columns for the 3-D run come
from run_references.py (curves/<run>.csv and its .frd).  Needs numpy and h5py (Debian packages).
"""
import argparse
import csv
import math
import os
import sys

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import run_references as rr  # noqa: E402


def per_tet_energy(X, P, T, w, E=150.0, nu=0.48):
    """Eq. 5 per tet, exactly integrated for the P1 field (signed reference volumes)."""
    mu = E / (2 * (1 + nu)); kap = E / (3 * (1 - 2 * nu))

    def edges(Q):
        return np.stack([Q[T[:, 1]] - Q[T[:, 0]], Q[T[:, 2]] - Q[T[:, 0]], Q[T[:, 3]] - Q[T[:, 0]]], axis=2)

    D0 = edges(X); V0 = np.abs(np.linalg.det(D0)) / 6
    F = edges(P) @ np.linalg.inv(D0)
    J = np.linalg.det(F)
    C = np.transpose(F, (0, 2, 1)) @ F
    I1 = np.trace(C, axis1=1, axis2=2); I2 = 0.5 * (I1 ** 2 - np.einsum('tij,tji->t', C, C))
    U = (w * mu / 2 * (I1 * J ** (-2 / 3) - 3) + (1 - w) * mu / 2 * (I2 * J ** (-4 / 3) - 3)
         + kap / 2 * (J - 1) ** 2)
    return float((U * V0).sum()), float(J.min()), float((J * V0).sum() / V0.sum())


def overlaps(P, T):
    A = P[T[:, 0]]
    Mi = np.linalg.inv(np.stack([P[T[:, 1]] - A, P[T[:, 2]] - A, P[T[:, 3]] - A], axis=2))
    lo = P[T].min(axis=1); hi = P[T].max(axis=1)
    count = 0
    for v in range(len(P)):
        cand = np.where(np.all((P[v] >= lo) & (P[v] <= hi), axis=1))[0]
        cand = cand[~np.any(T[cand] == v, axis=1)]
        if len(cand):
            b = np.einsum('tij,tj->ti', Mi[cand], P[v] - A[cand])
            count += int(np.any(np.minimum(b.min(axis=1), 1 - b.sum(axis=1)) > 1e-6))
    return count


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("result")
    ap.add_argument("--run", default="plates_w0.25_3d_L1")
    ap.add_argument("--case", default="plates_w0.25")
    ap.add_argument("--w", type=float, default=0.25)
    a = ap.parse_args()
    R = rr.CASES[a.case]["R"] * 1e-6
    f = h5py.File(a.result, "r")
    pos = f["particles/cell/position/value"][:]
    fstep = f["particles/cell/position/step"][:]
    T = f["connectivity/cell"][:]
    ob = f["observables"]
    ostep = ob["deformation/step"][:]
    Fc = ob["force_n/value"][:]; Ec = ob["elastic_energy_j/value"][:]
    rows = list(csv.DictReader(open(os.path.join(HERE, "curves", a.run + ".csv"))))
    e3 = np.array([float(r["deformation"]) for r in rows])
    F3 = np.array([float(r["force_n"]) for r in rows]); E3 = np.array([float(r["elastic_energy_j"]) for r in rows])
    X = pos[0]
    faces = np.sort(np.concatenate([T[:, [0, 1, 2]], T[:, [0, 1, 3]], T[:, [0, 2, 3]], T[:, [1, 2, 3]]]), axis=1)
    uf, cnt = np.unique(faces, axis=0, return_counts=True)
    surf = np.unique(uf[cnt == 1])
    h0 = X[:, 2].max() - X[:, 2].min()
    print("cellflow %s (%d vertices, %d tets) against %s" % (a.result, len(X), len(T), a.run))
    print("eps_eff | F_cf/F_3d | E_cf/E_3d | per-tet E/E_3d | V/V0 | J min | contact r/R | max r/R | |A2|/r0 | |A4|/r0 | overlaps")
    for k in range(1, len(fstep)):
        i = np.where(ostep == fstep[k])[0]
        if not len(i):
            continue
        i = i[0]
        P = pos[k]
        eff = 1 - (P[:, 2].max() - P[:, 2].min()) / h0
        Et, jmin, vr = per_tet_energy(X, P, T, a.w)
        q = P[surf] - P.mean(axis=0)
        r = np.hypot(q[:, 0], q[:, 1])
        up = q[:, 2] > 0
        top = q[:, 2].max()
        rc = r[up & (top - q[:, 2] < 2e-3 * R)].max()
        band = np.abs(q[:, 2]) < 0.1 * (q[:, 2].max() - q[:, 2].min())
        th = np.arctan2(q[band, 1], q[band, 0])
        B = np.array([np.ones_like(th)] + [fn(m * th) for m in range(1, 7) for fn in (np.cos, np.sin)]).T
        s = np.linalg.lstsq(B, r[band], rcond=None)[0]
        amp = lambda m: math.hypot(s[2 * m - 1], s[2 * m]) / s[0]
        e3i = np.interp(eff, e3, E3); f3i = np.interp(eff, e3, F3)
        print("%.4f | %.4f | %.4f | %.4f | %.4f | %.3f | %.3f | %.3f | %.1e | %.1e | %d" % (
            eff, Fc[i] / f3i, Ec[i] / e3i, Et / e3i, vr, jmin, rc / R, r.max() / R, amp(2), amp(4), overlaps(P, T)))
    # the 3-D run's own columns
    _, info, coords, elems = rr.build3d(a.case, int(a.run.split("_L")[1][0]),
                                        model="quarter" if "quarter" in a.run else "eighth")
    blocks = rr.read_frd_disp3(os.path.join(HERE, "runs", a.run, "job.frd"))
    Rm = rr.CASES[a.case]["R"]
    cn = set(x for el in elems for x in el)
    sn = [n for n in cn if abs(math.sqrt(sum(v * v for v in coords[n - 1])) - Rm) < 1e-2 * Rm]
    print("%s: eps | V/V0 | contact r/R | max r/R (from runs/%s/job.frd)" % (a.run, a.run))
    for e in (0.56, 0.64, 0.72, 0.8):
        t, d = min(blocks, key=lambda b: abs(info["travel"] * rr.amp(b[0], info["amp_p"]) / Rm - e))
        eps = info["travel"] * rr.amp(t, info["amp_p"]) / Rm
        plate = Rm - info["travel"] * rr.amp(t, info["amp_p"])
        pts = [tuple(coords[n - 1][c] + d[n][c] for c in range(3)) for n in sn]
        rc = max(math.hypot(p[0], p[1]) for p in pts if plate - p[2] < 2e-3 * Rm)
        rm = max(math.hypot(p[0], p[1]) for p in pts)
        cur = [tuple(p[c] + d.get(j, (0, 0, 0))[c] for c in range(3)) for j, p in enumerate(coords, 1)]
        V, _ = rr.octant_moments(cur, elems, info["copies"])
        print("%.4f | %.4f | %.3f | %.3f" % (eps, V / (4 / 3 * math.pi * Rm ** 3), rc / Rm, rm / Rm))


if __name__ == "__main__":
    main()
