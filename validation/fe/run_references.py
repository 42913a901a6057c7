#!/usr/bin/env python3
"""Independent axisymmetric finite-element reference curves (CalculiX ccx).

Generates the meshes, writes the decks, runs ccx (single-threaded), parses the
total reaction force from the .dat file and writes the force curves as CSV.
Python 3 standard library only.

  python3 validation/fe/run_references.py --studies  # everything: material check, all cases, levels, studies
  python3 validation/fe/run_references.py --case plates_w1 --levels 1 2 3
  python3 validation/fe/run_references.py --list

Units inside the decks: lengths in um, moduli in Pa, hence forces in pN
(Pa um^2 = 1e-12 N).  The CSVs are SI (m, N).

Layout (relative to this file):
  decks/<run>.inp        generated decks (committed: the exact input)
  runs/<run>/            ccx work directories (not committed)
  curves/<run>.csv       every run's curve; curves/<case>.csv = the reference
  results.json           run times, status, convergence table (written by the script)
"""
import argparse
import json
import math
import os
import random
import re
import resource
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
DECKS = os.path.join(HERE, "decks")
RUNS = os.path.join(HERE, "runs")
CURVES = os.path.join(HERE, "curves")

# ----------------------------------------------------------------------------
# material: the paper's energy (eq. 5, 6, 8) mapped onto ccx *HYPERELASTIC,
# MOONEY-RIVLIN  U = C10 (I1b - 3) + C01 (I2b - 3) + (J - 1)^2 / D1
# ----------------------------------------------------------------------------


def moduli(E, nu, w):
    mu = E / (2.0 * (1.0 + nu))
    kappa = E / (3.0 * (1.0 - 2.0 * nu))
    mu1, mu2 = w * mu, (1.0 - w) * mu
    return {"mu": mu, "kappa": kappa, "C10": mu1 / 2.0, "C01": mu2 / 2.0, "D1": 2.0 / kappa}


def paper_energy(F, E, nu, w):
    """U of eq. 5 for a 3x3 deformation gradient (list of lists)."""
    m = moduli(E, nu, w)
    mu1, mu2, kappa = w * m["mu"], (1 - w) * m["mu"], m["kappa"]
    C = [[sum(F[k][i] * F[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    J = (F[0][0] * (F[1][1] * F[2][2] - F[1][2] * F[2][1])
         - F[0][1] * (F[1][0] * F[2][2] - F[1][2] * F[2][0])
         + F[0][2] * (F[1][0] * F[2][1] - F[1][1] * F[2][0]))
    trC = C[0][0] + C[1][1] + C[2][2]
    trC2 = sum(C[i][j] * C[j][i] for i in range(3) for j in range(3))
    I = trC * J ** (-2.0 / 3.0)
    K = 0.5 * (trC ** 2 - trC2) * J ** (-4.0 / 3.0)
    return mu1 / 2 * (I - 3) + mu2 / 2 * (K - 3) + kappa / 2 * (J - 1) ** 2


def paper_principal_cauchy(stretches, E, nu, w):
    """Cauchy principal stresses sigma_i = lambda_i / J dU/dlambda_i (central differences)."""
    J = stretches[0] * stretches[1] * stretches[2]
    out = []
    for i in range(3):
        h = 1e-6
        lp = list(stretches); lm = list(stretches)
        lp[i] += h; lm[i] -= h
        Up = paper_energy([[lp[0], 0, 0], [0, lp[1], 0], [0, 0, lp[2]]], E, nu, w)
        Um = paper_energy([[lm[0], 0, 0], [0, lm[1], 0], [0, 0, lm[2]]], E, nu, w)
        out.append(stretches[i] / J * (Up - Um) / (2 * h))
    return out


# ----------------------------------------------------------------------------
# block-structured quadratic (8-node) mesher in the (r, z) half plane
# ----------------------------------------------------------------------------


class Mesh:
    def __init__(self):
        self.nodes = []          # [(r, z)]
        self.key = {}
        self.elems = {}          # name -> list of 8-tuples (1-based node ids)
        self.tol = 1e-7

    def node(self, r, z):
        if abs(r) < 1e-9:
            r = 0.0
        k = (round(r / self.tol), round(z / self.tol))
        # tolerant merge: look at the rounded key and its neighbours
        for dr in (0, -1, 1):
            for dz in (0, -1, 1):
                kk = (k[0] + dr, k[1] + dz)
                if kk in self.key:
                    return self.key[kk]
        self.nodes.append((r, z))
        self.key[k] = len(self.nodes)
        return len(self.nodes)

    def block(self, name, bottom, top, left, right, ns, nt, gs, gt):
        """Transfinite block; curves map [0,1] -> (r, z); bottom(s), top(s), left(t), right(t).
        gs, gt: grading maps [0,1] -> [0,1]."""
        P00, P10, P01, P11 = bottom(0.0), bottom(1.0), top(0.0), top(1.0)

        def X(s, t):
            out = []
            for c in range(2):
                v = ((1 - t) * bottom(s)[c] + t * top(s)[c] + (1 - s) * left(t)[c] + s * right(t)[c]
                     - ((1 - s) * (1 - t) * P00[c] + s * (1 - t) * P10[c]
                        + (1 - s) * t * P01[c] + s * t * P11[c]))
                out.append(v)
            return out

        grid = {}
        for i in range(2 * ns + 1):
            for j in range(2 * nt + 1):
                if i % 2 == 1 and j % 2 == 1:
                    continue
                s = gs(i / (2.0 * ns)); t = gt(j / (2.0 * nt))
                r, z = X(s, t)
                grid[(i, j)] = self.node(r, z)
        els = self.elems.setdefault(name, [])
        for i in range(ns):
            for j in range(nt):
                a, b = 2 * i, 2 * j
                c = [grid[(a, b)], grid[(a + 2, b)], grid[(a + 2, b + 2)], grid[(a, b + 2)],
                     grid[(a + 1, b)], grid[(a + 2, b + 1)], grid[(a + 1, b + 2)], grid[(a, b + 1)]]
                els.append(self.orient(c))

    def orient(self, c):
        p = [self.nodes[n - 1] for n in c[:4]]
        area = 0.0
        for k in range(4):
            x1, y1 = p[k]; x2, y2 = p[(k + 1) % 4]
            area += x1 * y2 - x2 * y1
        if area > 0:
            return tuple(c)
        # reverse orientation: 1 4 3 2 / 8 7 6 5
        return (c[0], c[3], c[2], c[1], c[7], c[6], c[5], c[4])

    def boundary_faces(self, name):
        """Faces (element index 0-based within the set, face number 1..4) used by one element only."""
        count = {}
        for e, c in enumerate(self.elems[name]):
            for f in range(4):
                a, b = c[f], c[(f + 1) % 4]
                k = (min(a, b), max(a, b))
                count.setdefault(k, []).append((e, f + 1))
        return [v[0] for v in count.values() if len(v) == 1]


def lin(p, q):
    return lambda s: (p[0] + (q[0] - p[0]) * s, p[1] + (q[1] - p[1]) * s)


def arc(center, radius, a0, a1):
    return lambda s: (center[0] + radius * math.cos(a0 + (a1 - a0) * s),
                      center[1] + radius * math.sin(a0 + (a1 - a0) * s))


def uniform(x):
    return x


def toward1(p):
    """cluster toward x = 1 (power p >= 1)."""
    return lambda x: 1.0 - (1.0 - x) ** p


def toward0(p):
    return lambda x: x ** p


def blend0(beta):
    """mild clustering at x = 0: first element ~ (1 - beta) / n."""
    return lambda x: (1 - beta) * x + beta * x * x


def disk_quarter(mesh, name, zc, R, n, sign, pole_beta=0.0, surf_p=1.4):
    """Quarter disk r >= 0, centre (0, zc), upper (sign=+1) or lower (sign=-1) half.
    O-grid: core square + two curved blocks; radial clustering toward the surface,
    optional clustering toward the pole (axis) along the surface."""
    c, q = 0.5 * R, 0.42 * R
    s2 = 1.0 / math.sqrt(2.0)

    def P(r, z):
        return (r, zc + sign * z)

    def L(p, qq):
        return lin(P(*p), P(*qq))

    def A(a0, a1):
        f = arc((0.0, 0.0), R, a0, a1)
        return lambda s: P(*f(s))

    nr = n
    gpole = blend0(pole_beta)
    gsurf = toward1(surf_p)
    # core: s along r (0..c), t along z (0..c)
    mesh.block(name, L((0, 0), (c, 0)), L((0, c), (q, q)), L((0, 0), (0, c)), L((c, 0), (q, q)),
               n, n, gpole, uniform)
    # right block: s radial (core -> arc), t angle 0 -> 45 deg
    mesh.block(name, L((c, 0), (R, 0)), L((q, q), (R * s2, R * s2)), L((c, 0), (q, q)),
               A(0.0, math.pi / 4), nr, n, gsurf, uniform)
    # top block: s from axis to diagonal, t radial (core -> arc)
    mesh.block(name, L((0, c), (q, q)), A(math.pi / 2, math.pi / 4), L((0, c), (0, R)),
               L((q, q), (R * s2, R * s2)), n, nr, gpole, gsurf)


def plate(mesh, name, z0, W, thick, n, sign):
    """Rigid plate r in [0, W]; contact face at z = z0, material on the side sign (+1 above)."""
    g = toward0(1.5)
    mesh.block(name, lin((0, z0), (W, z0)), lin((0, z0 + sign * thick), (W, z0 + sign * thick)),
               lin((0, z0), (0, z0 + sign * thick)), lin((W, z0), (W, z0 + sign * thick)),
               n, 1, g, uniform)


def probe(mesh, name, zc, Rp, theta, n):
    """Rigid spherical probe cap: ring between 0.9 Rp and Rp, angle from -90 deg (bottom
    pole) to -90 deg + theta; contact face at radius Rp."""
    a0 = -math.pi / 2
    g = blend0(0.3)
    mesh.block(name, arc((0, zc), Rp, a0, a0 + theta), arc((0, zc), 0.9 * Rp, a0, a0 + theta),
               lin((0, zc - Rp), (0, zc - 0.9 * Rp)),
               lin((Rp * math.cos(a0 + theta), zc + Rp * math.sin(a0 + theta)),
                   (0.9 * Rp * math.cos(a0 + theta), zc + 0.9 * Rp * math.sin(a0 + theta))),
               n, 1, g, uniform)


# ----------------------------------------------------------------------------
# cases
# ----------------------------------------------------------------------------

NU = 0.48

CASES = {
    # sphere between two plates, quarter model (mid-plane symmetry), one plate moves delta/2
    "plates_w1": dict(kind="plates", R=8.6, E=150.0, w=1.0, eps_max=0.8, pole_beta=0.5),
    "plates_w0.5": dict(kind="plates", R=8.6, E=150.0, w=0.5, eps_max=0.8, pole_beta=0.5),
    "plates_w0.25": dict(kind="plates", R=8.6, E=150.0, w=0.25, eps_max=0.8, pole_beta=0.5),
    # small-deformation (Hertz-limit) run of plates_w1: to eps = 0.05, mesh clustered at the pole
    "plates_w1_hertz": dict(kind="plates", R=8.6, E=150.0, w=1.0, eps_max=0.05, pole_beta=0.85),
    # plates_w1 at nu = 0.45 to deformation 0.9 (the stability matrix's compression/grid/w1-nu0.45,
    # E and R as there): whether its state near 0.9 (min J ~0.3) is the energy's or the mesh's
    "plates_w1_nu0.45": dict(kind="plates", R=8.6, E=1000.0, w=1.0, eps_max=0.9, pole_beta=0.5, nu=0.45),
    # colloidal probe: cell R=40 on a plate, probe Rp=26.5, 20 um
    "colloidal_probe": dict(kind="probe", R=40.0, Rp=26.5, E=580.0, w=1.0, d_max=20.0,
                            theta=math.radians(75), pole_beta=0.8),
    # AFM-like small probe: Rp=2.5 on R=8, 2 um, refined at the top pole
    "small_probe": dict(kind="probe", R=8.0, Rp=2.5, E=1000.0, w=1.0, d_max=2.0,
                        theta=math.radians(80), pole_beta=0.8),
}

# mesh level -> elements per block edge (3 n^2 elements per quarter disk)
LEVELS = {1: 6, 2: 12, 3: 24, 4: 36}
DEFAULT_LEVELS = [1, 2, 3]
KFAC = 1.0e5          # contact penalty slope K = KFAC * E / R  [Pa / um]
NINC = 80             # target increments (max increment = 1 / NINC)
ELTYPE = "CAX8R"
# ccx expands CAX elements into a 2-degree wedge; its reaction-force totals are for that
# wedge (checked in material_check: sigma_zz * area / RF_total = 180), so the full force is 180 x.
AXI_FACTOR = 180.0
CONTACT = "n2s"       # s2s: slave = cell surface; s2s_rev: slave = rigid surface; n2s: node to surface


def amplitude_lines(name, p=2.0, npts=41):
    """Displacement amplitude a(t) = t^p (dense small-deformation points)."""
    vals = []
    for k in range(npts):
        t = k / (npts - 1.0)
        vals.append("%.8f, %.10e" % (t, t ** p))
    out = ["*AMPLITUDE, NAME=%s" % name]
    for i in range(0, len(vals), 4):
        out.append(", ".join(vals[i:i + 4]))
    return out


def imperfect_surface(m, R, zc, facet, roughness, seed=1):
    """Surface imperfections of the cell (issue 11, w = 0.25 departure): facet=True puts the
    mid-side node of every surface face on the chord of its corners (a faceted meridian with
    a kink at every corner ring, as cellflow's flat triangles have); roughness moves every
    surface corner node radially by a uniform random fraction in [-roughness, roughness] of R
    (seeded), the mid-side nodes following (on the chord if facet, else halfway)."""
    rng = random.Random(seed)
    surf = {}
    for e, f in m.boundary_faces("CELL"):
        c = m.elems["CELL"][e]
        a, b, mid = c[f - 1], c[f % 4], c[4 + f - 1]
        pa, pb = m.nodes[a - 1], m.nodes[b - 1]
        if all(abs(math.hypot(p[0], p[1] - zc) - R) < 1e-6 * R for p in (pa, pb)):
            surf[mid] = (a, b)
    corners = sorted({n for ab in surf.values() for n in ab})
    for n in corners:
        r, z = m.nodes[n - 1]
        # the axis and the mid plane keep their node on them (symmetry conditions)
        s = 1.0 + (rng.uniform(-roughness, roughness) if roughness > 0 and r > 0 and abs(z - zc) > 1e-9 else 0.0)
        m.nodes[n - 1] = (r * s, zc + (z - zc) * s)
    for mid, (a, b) in surf.items():
        pa, pb = m.nodes[a - 1], m.nodes[b - 1]
        if facet:
            m.nodes[mid - 1] = (0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]))
        elif roughness > 0:
            r, z = m.nodes[mid - 1]
            s = 0.5 * (math.hypot(pa[0], pa[1] - zc) + math.hypot(pb[0], pb[1] - zc)) / math.hypot(r, z - zc)
            m.nodes[mid - 1] = (r * s, zc + (z - zc) * s)


def build(case, level, kfac=KFAC, eltype=ELTYPE, ninc=NINC, contact=None, facet=False, roughness=0.0):
    cfg = CASES[case]
    n = LEVELS[level]
    R, E, w = cfg["R"], cfg["E"], cfg["w"]
    m = Mesh()
    if cfg["kind"] == "plates":
        disk_quarter(m, "CELL", 0.0, R, n, +1, pole_beta=cfg.get("pole_beta", 0.0))
        plate(m, "PLATE", R, 2.6 * R, 0.2 * R, max(8, 2 * n), +1)
        if facet or roughness > 0:
            imperfect_surface(m, R, 0.0, facet, roughness)
    else:
        disk_quarter(m, "CELL", R, R, n, +1, pole_beta=cfg["pole_beta"])
        disk_quarter(m, "CELL", R, R, n, -1, pole_beta=cfg["pole_beta"])  # same grading: conforming mid-plane
        Rp = cfg["Rp"]
        plate(m, "PLATE", 0.0, 2.0 * R, 0.2 * R, max(8, 2 * n), -1)
        nprobe = max(12, int(round(4 * n * cfg["theta"] / (math.pi / 4))))
        probe(m, "PROBE", 2 * R + Rp, Rp, cfg["theta"], nprobe)

    nu = cfg.get("nu", NU)
    mat = moduli(E, nu, w)
    K = kfac * E / R
    L = []
    L.append("** generated by validation/fe/run_references.py: case %s, level %d (n=%d), %s, K=%g Pa/um"
             % (case, level, n, eltype, K))
    L.append("** units: um, Pa, pN.  E=%g Pa nu=%g w=%g: mu=%.6g kappa=%.6g" % (E, nu, w, mat["mu"], mat["kappa"]))
    L.append("*NODE, NSET=NALL")
    for i, (r, z) in enumerate(m.nodes, 1):
        L.append("%d, %.12g, %.12g, 0" % (i, r, z))
    eid = 0
    first = {}
    for name in ("CELL", "PLATE", "PROBE"):
        if name not in m.elems:
            continue
        L.append("*ELEMENT, TYPE=%s, ELSET=%s" % (eltype if name == "CELL" else "CAX8", name))
        first[name] = eid + 1
        for c in m.elems[name]:
            eid += 1
            L.append("%d, %s" % (eid, ", ".join(str(x) for x in c)))

    def nodes_of(name):
        s = set()
        for c in m.elems[name]:
            s.update(c)
        return sorted(s)

    def nset(name, ids):
        L.append("*NSET, NSET=%s" % name)
        ids = list(ids)
        for i in range(0, len(ids), 12):
            L.append(", ".join(str(x) for x in ids[i:i + 12]) + ",")

    cell_nodes = nodes_of("CELL")
    axis = [i for i in cell_nodes if m.nodes[i - 1][0] == 0.0]
    nset("AXIS", axis)
    nset("PLATEN", nodes_of("PLATE"))
    if "PROBE" in m.elems:
        nset("PROBEN", nodes_of("PROBE"))

    # surfaces: cell outer faces (distance R from the centre)
    zc = 0.0 if cfg["kind"] == "plates" else R

    surf_tol = 1e-6 + 2.0 * roughness

    def on_circle(p, cen, rad, tol=surf_tol):
        return abs(math.hypot(p[0] - cen[0], p[1] - cen[1]) - rad) < tol * rad

    def faces(name, pred):
        out = []
        for e, f in m.boundary_faces(name):
            c = m.elems[name][e]
            a, b = m.nodes[c[f - 1] - 1], m.nodes[c[f % 4] - 1]
            if pred(a) and pred(b):
                out.append((first[name] + e, f))
        return sorted(out)

    def surface(name, fl):
        L.append("*SURFACE, NAME=%s, TYPE=ELEMENT" % name)
        for e, f in fl:
            L.append("%d, S%d" % (e, f))

    if cfg["kind"] == "plates":
        surface("SCELL", faces("CELL", lambda p: on_circle(p, (0, 0), R)))
        surface("MPLATE", faces("PLATE", lambda p: abs(p[1] - R) < 1e-9))
    else:
        surface("SCELLTOP", faces("CELL", lambda p: on_circle(p, (0, R), R) and p[1] >= R - 1e-9))
        surface("SCELLBOT", faces("CELL", lambda p: on_circle(p, (0, R), R) and p[1] <= R + 1e-9))
        surface("MPLATE", faces("PLATE", lambda p: abs(p[1]) < 1e-9))
        surface("MPROBE", faces("PROBE", lambda p: on_circle(p, (0, 2 * R + cfg["Rp"]), cfg["Rp"])))

    L.append("*MATERIAL, NAME=CELLMAT")
    L.append("*HYPERELASTIC, MOONEY-RIVLIN")
    L.append("%.10g, %.10g, %.10g" % (mat["C10"], mat["C01"], mat["D1"]))
    L.append("*MATERIAL, NAME=RIGID")
    L.append("*ELASTIC")
    L.append("%.6g, 0.3" % (1e6 * E))
    L.append("*SOLID SECTION, ELSET=CELL, MATERIAL=CELLMAT")
    L.append("*SOLID SECTION, ELSET=PLATE, MATERIAL=RIGID")
    if "PROBE" in m.elems:
        L.append("*SOLID SECTION, ELSET=PROBE, MATERIAL=RIGID")

    pairs = [("SCELL", "MPLATE")] if cfg["kind"] == "plates" else [("SCELLBOT", "MPLATE"), ("SCELLTOP", "MPROBE")]
    contact = contact or CONTACT
    for s, mm in pairs:
        if contact == "n2s":
            L.append("*CONTACT PAIR, INTERACTION=SI, TYPE=NODE TO SURFACE")
            L.append("%s, %s" % (s, mm))
        elif contact == "s2s_rev":
            L.append("*CONTACT PAIR, INTERACTION=SI, TYPE=SURFACE TO SURFACE")
            L.append("%s, %s" % (mm, s))
        else:
            L.append("*CONTACT PAIR, INTERACTION=SI, TYPE=SURFACE TO SURFACE")
            L.append("%s, %s" % (s, mm))
    L.append("*SURFACE INTERACTION, NAME=SI")
    L.append("*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR")
    L.append("%.8g" % K)
    L += amplitude_lines("RAMP")

    if cfg["kind"] == "plates":
        mid = [i for i in cell_nodes if abs(m.nodes[i - 1][1]) < 1e-9]
        nset("MID", mid)
        L.append("*BOUNDARY")
        L.append("AXIS, 1, 1, 0.")
        L.append("MID, 2, 2, 0.")
        L.append("PLATEN, 1, 1, 0.")
        move, travel = "PLATEN", 0.5 * cfg["eps_max"] * 2 * R
    else:
        pole = [i for i in cell_nodes if m.nodes[i - 1][0] == 0.0 and abs(m.nodes[i - 1][1]) < 1e-9]
        nset("POLE", pole)
        L.append("*BOUNDARY")
        L.append("AXIS, 1, 1, 0.")
        L.append("POLE, 2, 2, 0.")
        L.append("PLATEN, 1, 2, 0.")
        L.append("PROBEN, 1, 1, 0.")
        move, travel = "PROBEN", cfg["d_max"]
    L.append("*STEP, NLGEOM, INC=100000")
    L.append("*STATIC")
    L.append("%g, 1.0, %g, %g" % (1.0 / ninc, 1e-7, 1.0 / ninc))
    L.append("*BOUNDARY, AMPLITUDE=RAMP")
    L.append("%s, 2, 2, %.10g" % (move, -travel))
    L.append("*NODE PRINT, NSET=%s, TOTALS=ONLY, FREQUENCY=1" % move)
    L.append("RF")
    if cfg["kind"] == "probe":
        L.append("*NODE PRINT, NSET=PLATEN, TOTALS=ONLY")
        L.append("RF")
        L.append("*NODE PRINT, NSET=POLE, TOTALS=ONLY")
        L.append("RF")
    L.append("*NODE FILE, FREQUENCY=1")
    L.append("U")
    L.append("*END STEP")
    info = dict(nodes=len(m.nodes), cell_elements=len(m.elems["CELL"]), n=n, K=K, travel=travel)
    return "\n".join(L) + "\n", info



# ----------------------------------------------------------------------------
# full 3-D check of the plates cases (issue 11 item 3): eighth sphere of C3D20R
# ----------------------------------------------------------------------------
#
# x, y, z >= 0 with symmetry planes x = 0, y = 0 (u_x = 0, u_y = 0) and the mid
# plane z = 0 (u_z = 0); the plate moves down delta/2 onto the pole.  The
# symmetry admits the displacement fields even in x, even in y and even in z:
# azimuthal modes cos(2 k theta) (k = 0, 1, 2, ...: axisymmetric, cos 2theta,
# cos 4theta, ...), symmetric about the mid plane.  It forbids cos(odd theta),
# sin(m theta) and anything antisymmetric about the mid plane (tilting,
# sliding, a fold that differs above and below).

# 20-node hex (ccx/Abaqus order): local coordinates of nodes 1..20
HEX20 = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1),
         (0, -1, -1), (1, 0, -1), (0, 1, -1), (-1, 0, -1), (0, -1, 1), (1, 0, 1), (0, 1, 1), (-1, 0, 1),
         (-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
# faces (corner nodes, 0-based) S1..S6 of C3D20 / C3D8
HEX_FACES = [(0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0)]
HEX8 = HEX20[:8]


class Mesh3:
    def __init__(self, tol=1e-7):
        self.nodes = []
        self.key = {}
        self.elems = {}
        self.tol = tol

    def node(self, p):
        p = tuple(0.0 if abs(v) < 1e-9 else v for v in p)
        k = tuple(round(v / self.tol) for v in p)
        for d0 in (0, -1, 1):
            for d1 in (0, -1, 1):
                for d2 in (0, -1, 1):
                    kk = (k[0] + d0, k[1] + d1, k[2] + d2)
                    if kk in self.key:
                        return self.key[kk]
        self.nodes.append(p)
        self.key[k] = len(self.nodes)
        return len(self.nodes)

    def block(self, name, X, ni, nj, nk, quadratic=True):
        """Structured block: X(p, q, r) maps [0,1]^3 into space; ni x nj x nk hexes."""
        h = 2 if quadratic else 1
        local = HEX20 if quadratic else HEX8
        grid = {}
        for i in range(h * ni + 1):
            for j in range(h * nj + 1):
                for k in range(h * nk + 1):
                    if quadratic and (i % 2) + (j % 2) + (k % 2) > 1:
                        continue
                    grid[(i, j, k)] = self.node(X(i / (h * ni), j / (h * nj), k / (h * nk)))
        els = self.elems.setdefault(name, [])
        for a in range(ni):
            for b in range(nj):
                for c in range(nk):
                    ids = [grid[(h * a + (1 + x) * h // 2, h * b + (1 + y) * h // 2, h * c + (1 + z) * h // 2)]
                           for (x, y, z) in local]
                    els.append(self.orient(ids, quadratic))

    def orient(self, ids, quadratic):
        p = [self.nodes[n - 1] for n in ids[:8]]
        e1 = [p[1][d] - p[0][d] for d in range(3)]
        e2 = [p[3][d] - p[0][d] for d in range(3)]
        e3 = [p[4][d] - p[0][d] for d in range(3)]
        det = (e1[0] * (e2[1] * e3[2] - e2[2] * e3[1]) - e1[1] * (e2[0] * e3[2] - e2[2] * e3[0])
               + e1[2] * (e2[0] * e3[1] - e2[1] * e3[0]))
        if det > 0:
            return ids
        # mirror the local xi direction: node of (x, y, z) <- node of (-x, y, z)
        local = HEX20 if quadratic else HEX8
        pos = {c: n for c, n in zip(local, ids)}
        return [pos[(-x, y, z)] for (x, y, z) in local]


def sphere_octant(mesh, name, R, n, pole_beta=0.5, surf_p=1.4, c=0.4, alpha=0.59, cs=0.569, sy=1.0):
    """O-grid octant of a ball: a core (rounded cube) and three blocks (+x, +y, +z) out to the
    sphere, n elements per block edge (4 n^3 hexes).  Inner surface of the blocks:
    (1 - alpha) c e + alpha cs e'/|e'| (e on the cube face, e' its equiangular direction): 0.5 R on
    the axes, 0.62 R at the cube corner.  Surface parameters graded toward the symmetry planes
    with (1 - beta) x + beta x^2 (the poles are at a = b = 0 of the +z block).  sy = -1: the
    mirror octant y <= 0."""
    c, cs = c * R, cs * R
    G = blend0(pole_beta)
    g = toward1(surf_p)

    def T(e):
        d = [math.tan(math.pi / 4 * v) for v in e]
        s = math.sqrt(sum(v * v for v in d))
        return [v / s for v in d]

    def p_in(e):
        d = T(e)
        return [(1 - alpha) * c * e[k] + alpha * cs * d[k] for k in range(3)]

    def core(u, v, w):
        e = [G(u), G(v), G(w)]
        m = max(e)
        if m <= 0.0:
            return (0.0, 0.0, 0.0)
        q = p_in([x / m for x in e])
        return (m * q[0], sy * m * q[1], m * q[2])

    mesh.block(name, core, n, n, n)
    for f in range(3):
        def X(s, t, rho, f=f):
            e = [0.0, 0.0, 0.0]
            others = [k for k in range(3) if k != f]
            e[f] = 1.0
            e[others[0]], e[others[1]] = G(s), G(t)
            pi, d = p_in(e), T(e)
            gr = g(rho)
            return tuple((sy if k == 1 else 1.0) * ((1 - gr) * pi[k] + gr * R * d[k]) for k in range(3))
        mesh.block(name, X, n, n, n)


def hex_shape20(x, y, z):
    """20-node serendipity shape functions and their local derivatives."""
    N, dN = [], []
    for (a, b, c) in HEX20:
        if a != 0 and b != 0 and c != 0:
            f = 0.125 * (1 + a * x) * (1 + b * y) * (1 + c * z) * (a * x + b * y + c * z - 2)
            dx = 0.125 * a * (1 + b * y) * (1 + c * z) * (2 * a * x + b * y + c * z - 1)
            dy = 0.125 * b * (1 + a * x) * (1 + c * z) * (a * x + 2 * b * y + c * z - 1)
            dz = 0.125 * c * (1 + a * x) * (1 + b * y) * (a * x + b * y + 2 * c * z - 1)
        elif a == 0:
            f = 0.25 * (1 - x * x) * (1 + b * y) * (1 + c * z)
            dx, dy, dz = -0.5 * x * (1 + b * y) * (1 + c * z), 0.25 * b * (1 - x * x) * (1 + c * z), 0.25 * c * (1 - x * x) * (1 + b * y)
        elif b == 0:
            f = 0.25 * (1 - y * y) * (1 + a * x) * (1 + c * z)
            dx, dy, dz = 0.25 * a * (1 - y * y) * (1 + c * z), -0.5 * y * (1 + a * x) * (1 + c * z), 0.25 * c * (1 - y * y) * (1 + a * x)
        else:
            f = 0.25 * (1 - z * z) * (1 + a * x) * (1 + b * y)
            dx, dy, dz = 0.25 * a * (1 - z * z) * (1 + b * y), 0.25 * b * (1 - z * z) * (1 + a * x), -0.5 * z * (1 + a * x) * (1 + b * y)
        N.append(f)
        dN.append((dx, dy, dz))
    return N, dN


def octant_moments(coords, elems, copies=8):
    """Volume and the second moments int x_i^2 dV of the full body (copies x the model, 3x3x3 Gauss),
    coords: list of node positions, node id k at coords[k - 1]."""
    gp = [(-math.sqrt(0.6), 5 / 9.0), (0.0, 8 / 9.0), (math.sqrt(0.6), 5 / 9.0)]
    V, M = 0.0, [0.0, 0.0, 0.0]
    cache = {}
    for el in elems:
        P = [coords[n - 1] for n in el]  # node ids are 1-based
        for (x, wx) in gp:
            for (y, wy) in gp:
                for (z, wz) in gp:
                    key = (x, y, z)
                    if key not in cache:
                        cache[key] = hex_shape20(x, y, z)
                    N, dN = cache[key]
                    Jm = [[sum(dN[a][j] * P[a][i] for a in range(20)) for j in range(3)] for i in range(3)]
                    det = (Jm[0][0] * (Jm[1][1] * Jm[2][2] - Jm[1][2] * Jm[2][1])
                           - Jm[0][1] * (Jm[1][0] * Jm[2][2] - Jm[1][2] * Jm[2][0])
                           + Jm[0][2] * (Jm[1][0] * Jm[2][1] - Jm[1][1] * Jm[2][0]))
                    wgt = wx * wy * wz * det
                    X = [sum(N[a] * P[a][i] for a in range(20)) for i in range(3)]
                    V += wgt
                    for i in range(3):
                        M[i] += wgt * X[i] * X[i]
    return copies * V, [copies * m for m in M]


LEVELS3D = {0: 3, 1: 4, 2: 6, 3: 8}  # elements per block edge of the 3-D octant (4 n^3 hexes per octant)


def build3d(case, level, kfac=KFAC, ninc=NINC, imperfection=1e-3, eltype="C3D20R", contact="s2s",
            amp_p=2.0, model="eighth", imperfection3=1e-3, imperfection4=0.0):
    """Eighth-sphere deck of a plates case; imperfection eta: x -> x (1 + eta), y -> y (1 - eta)
    (a cos 2theta ovalisation of the initial sphere, which the symmetry admits).
    model "quarter": x >= 0, z >= 0 (symmetry planes x = 0 and z = 0 only), which also admits
    sin(m theta) for odd m (and cos(m theta) for even m); its extra imperfection: the in-plane
    position scaled by 1 + imperfection3 sin 3theta; u_y = 0 at the centre removes the free
    sliding along y.  imperfection4: the in-plane position scaled by 1 + imperfection4 cos 4theta
    (a 4-fold equator ripple, the mode cellflow's departed state shows)."""
    cfg = CASES[case]
    n = LEVELS3D[level]
    R, E, w = cfg["R"], cfg["E"], cfg["w"]
    m = Mesh3()
    sphere_octant(m, "CELL", R, n, pole_beta=cfg.get("pole_beta", 0.0))
    if model == "quarter":
        sphere_octant(m, "CELL", R, n, pole_beta=cfg.get("pole_beta", 0.0), sy=-1.0)
    W, th, npl = 2.6 * R, 0.2 * R, 8
    gp = toward0(1.5)
    m.block("PLATE", lambda p, q, r: (W * gp(p), W * gp(q), R + th * r), npl, npl, 1, quadratic=False)
    if model == "quarter":
        m.block("PLATE", lambda p, q, r: (W * gp(p), -W * gp(q), R + th * r), npl, npl, 1, quadratic=False)
    ncell = set(x for el in m.elems["CELL"] for x in el)

    def cell_faces(pred):
        out = []
        for e, el in enumerate(m.elems["CELL"], 1):
            for f, fc in enumerate(HEX_FACES, 1):
                if all(pred(m.nodes[el[k] - 1]) for k in fc):
                    out.append((e, f))
        return out

    on_sphere = lambda p: abs(math.sqrt(sum(v * v for v in p)) - R) < 1e-6 * R
    scell = cell_faces(on_sphere)
    ne = len(m.elems["CELL"])
    mplate = []
    for e, el in enumerate(m.elems["PLATE"], ne + 1):
        for f, fc in enumerate(HEX_FACES, 1):
            if all(abs(m.nodes[el[k] - 1][2] - R) < 1e-9 for k in fc):
                mplate.append((e, f))
    sym = {d: sorted(i for i in ncell if m.nodes[i - 1][d] == 0.0) for d in range(3)}
    # imperfection of the cell nodes (the symmetry planes stay planes)
    coords = list(m.nodes)
    for i in ncell:
        x, y, z = coords[i - 1]
        s3 = 1.0
        if model == "quarter" and (x or y):
            s3 += imperfection3 * math.sin(3 * math.atan2(y, x))
        if imperfection4 and (x or y):
            s3 += imperfection4 * math.cos(4 * math.atan2(y, x))
        coords[i - 1] = (x * (1 + imperfection) * s3, y * (1 - imperfection) * s3, z)

    mat = moduli(E, NU, w)
    K = kfac * E / R
    travel = 0.5 * cfg["eps_max"] * 2 * R
    L = ["** generated by validation/fe/run_references.py: 3-D case %s, level %d (n=%d), %s %s sphere, "
         "K=%g Pa/um, imperfection %g (sin 3theta: %g)" % (case, level, n, eltype, model, K, imperfection,
                                                        imperfection3 if model == "quarter" else 0.0),
         "** units: um, Pa, pN.  E=%g Pa nu=%g w=%g: mu=%.6g kappa=%.6g" % (E, NU, w, mat["mu"], mat["kappa"]),
         "*NODE, NSET=NALL"]
    for i, p in enumerate(coords, 1):
        L.append("%d, %.12g, %.12g, %.12g" % (i, p[0], p[1], p[2]))
    L.append("*ELEMENT, TYPE=%s, ELSET=CELL" % eltype)
    eid = 0
    for el in m.elems["CELL"]:
        eid += 1
        L.append("%d, %s," % (eid, ", ".join(str(x) for x in el[:15])))
        L.append(", ".join(str(x) for x in el[15:]))
    L.append("*ELEMENT, TYPE=C3D8, ELSET=PLATE")
    for el in m.elems["PLATE"]:
        eid += 1
        L.append("%d, %s" % (eid, ", ".join(str(x) for x in el)))

    def nset(name, ids):
        L.append("*NSET, NSET=%s" % name)
        ids = list(ids)
        for i in range(0, len(ids), 12):
            L.append(", ".join(str(x) for x in ids[i:i + 12]) + ",")

    nset("SYMX", sym[0]); nset("SYMZ", sym[2])
    if model == "quarter":
        nset("CENTRE", [i for i in ncell if m.nodes[i - 1] == (0.0, 0.0, 0.0)])
    else:
        nset("SYMY", sym[1])
    nset("PLATEN", sorted(set(x for el in m.elems["PLATE"] for x in el)))
    L.append("*SURFACE, NAME=SCELL, TYPE=ELEMENT")
    L += ["%d, S%d" % ef for ef in scell]
    L.append("*SURFACE, NAME=MPLATE, TYPE=ELEMENT")
    L += ["%d, S%d" % ef for ef in mplate]
    L += ["*MATERIAL, NAME=CELLMAT", "*HYPERELASTIC, MOONEY-RIVLIN",
          "%.10g, %.10g, %.10g" % (mat["C10"], mat["C01"], mat["D1"]),
          "*MATERIAL, NAME=RIGID", "*ELASTIC", "%.6g, 0.3" % (1e6 * E),
          "*SOLID SECTION, ELSET=CELL, MATERIAL=CELLMAT", "*SOLID SECTION, ELSET=PLATE, MATERIAL=RIGID",
          "*CONTACT PAIR, INTERACTION=SI, TYPE=%s" % ("NODE TO SURFACE" if contact == "n2s" else "SURFACE TO SURFACE"),
          "SCELL, MPLATE",
          "*SURFACE INTERACTION, NAME=SI", "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", "%.8g" % K]
    L += amplitude_lines("RAMP", p=amp_p)
    L += ["*BOUNDARY", "SYMX, 1, 1, 0.", "SYMY, 2, 2, 0." if model != "quarter" else "CENTRE, 2, 2, 0.", "SYMZ, 3, 3, 0.", "PLATEN, 1, 2, 0.",
          "*STEP, NLGEOM, INC=100000", "*STATIC", "%g, 1.0, %g, %g" % (1.0 / ninc, 1e-7, 1.0 / ninc),
          "*BOUNDARY, AMPLITUDE=RAMP", "PLATEN, 3, 3, %.10g" % (-travel),
          "*NODE PRINT, NSET=PLATEN, TOTALS=ONLY, FREQUENCY=1", "RF",
          "*EL PRINT, ELSET=CELL, TOTALS=ONLY, FREQUENCY=1", "ELSE",
          "*NODE FILE, FREQUENCY=1", "U", "*END STEP"]
    info = dict(nodes=len(m.nodes), cell_nodes=len(ncell), cell_elements=ne, n=n, K=K, travel=travel,
                imperfection=imperfection, slave_faces=len(scell), amp_p=amp_p, ninc=ninc,
                model=model, copies=8 if model != "quarter" else 4, plate_factor=4 if model != "quarter" else 2,
                imperfection3=imperfection3 if model == "quarter" else 0.0, imperfection4=imperfection4)
    return "\n".join(L) + "\n", info, coords, m.elems["CELL"]

def amp(t, p=2.0):
    return t ** p


def parse_totals(datfile):
    """{set name: [(time, fx, fy, fz)]} from the .dat TOTALS blocks."""
    out = {}
    if not os.path.exists(datfile):
        return out
    lines = open(datfile).read().splitlines()
    pat = re.compile(r"total force \(fx,fy,fz\) for set (\S+) and time\s+(\S+)")
    for i, ln in enumerate(lines):
        mt = pat.search(ln)
        if not mt:
            continue
        for j in range(i + 1, min(i + 5, len(lines))):
            v = lines[j].split()
            if len(v) == 3:
                out.setdefault(mt.group(1), []).append((float(mt.group(2)),) + tuple(float(x) for x in v))
                break
    return out


def hertz_plates(E, R, eps):
    Es = E / (1 - NU * NU)
    return 4.0 / 3.0 * Es * R * R * eps ** 1.5


def hertz_probe(E, R, Rp, d):
    Es = E / (1 - NU * NU)
    R12 = R * Rp / (R + Rp)
    return 4.0 / 3.0 * Es * (d / (R12 ** (-1.0 / 3.0) + R ** (-1.0 / 3.0))) ** 1.5


def run_one(case, level, tag="", **kw):
    name = "%s_L%d%s" % (case, level, tag)
    deck, info = build(case, level, **kw)
    os.makedirs(DECKS, exist_ok=True)
    with open(os.path.join(DECKS, name + ".inp"), "w") as f:
        f.write(deck)
    wd = os.path.join(RUNS, name)
    shutil.rmtree(wd, ignore_errors=True)
    os.makedirs(wd)
    with open(os.path.join(wd, "job.inp"), "w") as f:
        f.write(deck)
    env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_EQUATION_SOLVER="1",
               CCX_NPROC_RESULTS="1", CCX_NPROC_STIFFNESS="1")
    t0 = time.time()
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(os.path.join(wd, "ccx.log"), "w") as log:
        rc = subprocess.call(["ccx", "-i", "job"], cwd=wd, stdout=log, stderr=subprocess.STDOUT, env=env)
    dt = time.time() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    logtxt = open(os.path.join(wd, "ccx.log")).read()
    ok = rc == 0 and "Job finished" in logtxt and "*ERROR" not in logtxt
    tot = parse_totals(os.path.join(wd, "job.dat"))
    cfg = CASES[case]
    mv = "PLATEN" if cfg["kind"] == "plates" else "PROBEN"
    rows = []
    for (t, fx, fy, fz) in tot.get(mv, []):
        u = info["travel"] * amp(t)
        F = abs(fy) * AXI_FACTOR * 1e-12
        if cfg["kind"] == "plates":
            delta = 2 * u
            rows.append((delta / (2 * cfg["R"]), delta * 1e-6, F))
        else:
            rows.append((u * 1e-6, u * 1e-6, F))
    extra = {}
    if cfg["kind"] == "probe" and tot.get("POLE") and tot.get(mv):
        extra["pole_share_end"] = abs(tot["POLE"][-1][2]) / max(abs(tot[mv][-1][2]), 1e-30)
        extra["plate_over_probe_end"] = (abs(tot["PLATEN"][-1][2]) + abs(tot["POLE"][-1][2])) / max(abs(tot[mv][-1][2]), 1e-30)
    os.makedirs(CURVES, exist_ok=True)
    with open(os.path.join(CURVES, name + ".csv"), "w") as f:
        f.write(("deformation" if cfg["kind"] == "plates" else "indentation_m") + ",displacement_m,force_n\n")
        for r in rows:
            f.write("%.8g,%.8g,%.8g\n" % r)
    nerr = logtxt.count("increment size smaller") + logtxt.count("*ERROR")
    res = dict(run=name, case=case, level=level, ok=ok, rc=rc, seconds=round(dt, 1), cpu_seconds=round(cpu, 1),
               load_average=round(os.getloadavg()[0], 1), points=len(rows),
               reached=(rows[-1][0] if rows else 0.0), info=info, kw={k: v for k, v in kw.items()},
               increments=logtxt.count("increment"), **extra)
    print("%-32s ok=%s %.1fs (cpu %.1fs) points=%d reached=%.4g nodes=%d" % (name, ok, dt, cpu, len(rows), res["reached"],
                                                                   info["nodes"]), flush=True)
    return res



def parse_energy(datfile):
    """[(time, internal energy)] of the .dat TOTALS blocks (*EL PRINT ELSE)."""
    out = []
    lines = open(datfile).read().splitlines() if os.path.exists(datfile) else []
    pat = re.compile(r"total internal energy for set (\S+) and time\s+(\S+)")
    for i, ln in enumerate(lines):
        mt = pat.search(ln)
        if mt:
            for j in range(i + 1, min(i + 5, len(lines))):
                v = lines[j].split()
                if len(v) == 1:
                    out.append((float(mt.group(2)), float(v[0])))
                    break
    return out


def read_frd_disp3(path):
    """[(time, {node: (ux, uy, uz)})] of every DISP block of a ccx .frd."""
    blocks, cur, t = [], None, None
    for ln in open(path):
        if ln.startswith("  100CL"):
            t = float(ln[12:24])
        elif ln.startswith(" -4  DISP"):
            cur = {}
            blocks.append((t, cur))
        elif ln.startswith(" -3"):
            cur = None
        elif cur is not None and ln.startswith(" -1"):
            cur[int(ln[3:13])] = (float(ln[13:25]), float(ln[25:37]), float(ln[37:49]))
    return blocks


def shape3d(coords, elems, disp, eq_nodes, copies=8):
    """Deformed cell: equivalent-ellipsoid semi-axes (as cellflow's shape.cc: a_i^2 = 5/V int x_i^2 dV
    for the principal axes, which are x, y, z by the symmetry), volume, the smallest J at the
    2x2x2 (reduced-integration) points, and the cos 2theta / cos 4theta amplitudes of the deformed
    equator radius r(theta) (least squares r = r0 + A2 cos 2theta + A4 cos 4theta)."""
    cur = [tuple(p[k] + disp.get(i, (0, 0, 0))[k] for k in range(3)) for i, p in enumerate(coords, 1)]
    V, M = octant_moments(cur, elems, copies)
    axes = [math.sqrt(5 * m / V) for m in M]
    g = 1 / math.sqrt(3)
    jmin = 1e9
    for el in elems:
        P0 = [coords[n - 1] for n in el]
        P1 = [cur[n - 1] for n in el]
        for x in (-g, g):
            for y in (-g, g):
                for z in (-g, g):
                    _, dN = hex_shape20(x, y, z)
                    dets = []
                    for P in (P0, P1):
                        Jm = [[sum(dN[a][j] * P[a][i] for a in range(20)) for j in range(3)] for i in range(3)]
                        dets.append(Jm[0][0] * (Jm[1][1] * Jm[2][2] - Jm[1][2] * Jm[2][1])
                                    - Jm[0][1] * (Jm[1][0] * Jm[2][2] - Jm[1][2] * Jm[2][0])
                                    + Jm[0][2] * (Jm[1][0] * Jm[2][1] - Jm[1][1] * Jm[2][0]))
                    jmin = min(jmin, dets[1] / dets[0])
    # least squares on the equator nodes
    rows = []
    for i in eq_nodes:
        x, y, _ = cur[i - 1]
        th = math.atan2(y, x)
        basis = [1.0, math.cos(2 * th), math.cos(4 * th)]
        if copies == 4:   # quarter model: the odd modes it admits
            basis += [math.sin(th), math.sin(3 * th)]
        rows.append(basis + [math.hypot(x, y)])
    nb = len(rows[0]) - 1
    A = [[sum(r[a] * r[b] for r in rows) for b in range(nb)] for a in range(nb)]
    bvec = [sum(r[a] * r[nb] for r in rows) for a in range(nb)]
    sol = solve_linear(A, bvec) + [0.0, 0.0]
    return dict(volume=V, axes=axes, jmin=jmin, r0=sol[0], A2=sol[1], A4=sol[2], B1=sol[3], B3=sol[4])


def solve_linear(A, b):
    """Gauss-Jordan with partial pivoting (small dense systems)."""
    n = len(b)
    A = [row[:] + [bb] for row, bb in zip(A, b)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(A[r][c]))
        A[c], A[p] = A[p], A[c]
        for r in range(n):
            if r != c:
                f = A[r][c] / A[c][c]
                A[r] = [A[r][k] - f * A[c][k] for k in range(n + 1)]
    return [A[r][n] / A[r][r] for r in range(n)]


SHAPE_EPS = [0.3, 0.5, 0.6, 0.64, 0.66, 0.68, 0.7, 0.72, 0.75, 0.78, 0.8]


def run_one3d(case, level, tag="", **kw):
    """One 3-D ccx run: deck, solve, curves/<case>_3d_L<level><tag>.csv (deformation, displacement,
    force, elastic energy) and curves/<case>_3d_L<level><tag>_shape.csv."""
    name = "%s_3d_L%d%s" % (case, level, tag)
    deck, info, coords, elems = build3d(case, level, **kw)
    os.makedirs(DECKS, exist_ok=True)
    with open(os.path.join(DECKS, name + ".inp"), "w") as f:
        f.write(deck)
    wd = os.path.join(RUNS, name)
    shutil.rmtree(wd, ignore_errors=True)
    os.makedirs(wd)
    with open(os.path.join(wd, "job.inp"), "w") as f:
        f.write(deck)
    env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_EQUATION_SOLVER="1",
               CCX_NPROC_RESULTS="1", CCX_NPROC_STIFFNESS="1")
    t0 = time.time()
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(os.path.join(wd, "ccx.log"), "w") as log:
        rc = subprocess.call(["ccx", "-i", "job"], cwd=wd, stdout=log, stderr=subprocess.STDOUT, env=env)
    dt = time.time() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    res = analyse3d(case, name, info, coords, elems, level)
    logtxt = open(os.path.join(wd, "ccx.log")).read()
    res.update(rc=rc, ok=rc == 0 and "Job finished" in logtxt and "*ERROR" not in logtxt, seconds=round(dt, 1),
               cpu_seconds=round(cpu, 1), load_average=round(os.getloadavg()[0], 1), kw=kw)
    print("%-32s ok=%s %.1fs (cpu %.1fs) points=%d reached=%.4g nodes=%d" % (
        name, res["ok"], dt, cpu, res["points"], res["reached"], info["nodes"]), flush=True)
    return res


def analyse3d(case, name, info, coords, elems, level):
    """Curves and shapes of a finished (or stopped) 3-D run from its .dat and .frd."""
    wd = os.path.join(RUNS, name)
    cfg = CASES[case]
    R = cfg["R"]
    tot = parse_totals(os.path.join(wd, "job.dat")).get("PLATEN", [])
    energy = dict(parse_energy(os.path.join(wd, "job.dat")))
    rows = []
    for (t, fx, fy, fz) in tot:
        u = info["travel"] * amp(t, info["amp_p"])
        # the octant carries a quarter of the plate's contact and an eighth of the cell
        rows.append((u / R, 2 * u * 1e-6, info["plate_factor"] * abs(fz) * 1e-12,
                     info["copies"] * energy.get(t, float("nan")) * 1e-18))
    os.makedirs(CURVES, exist_ok=True)
    with open(os.path.join(CURVES, name + ".csv"), "w") as f:
        f.write("deformation,displacement_m,force_n,elastic_energy_j\n")
        for r in rows:
            f.write("%.8g,%.8g,%.8g,%.8g\n" % r)
    # shapes at the frames nearest to SHAPE_EPS
    frd = os.path.join(wd, "job.frd")
    blocks = read_frd_disp3(frd) if os.path.exists(frd) else []
    # equator nodes: on the mid plane and on the sphere (the cos 4theta imperfection taken out)
    e4 = info.get("imperfection4", 0.0)

    def on_equator(p):
        r = math.hypot(p[0], p[1])
        return abs(p[2]) < 1e-9 and r > 0 and abs(r / (1 + e4 * math.cos(4 * math.atan2(p[1], p[0]))) - R) < 1e-2 * R
    eq = sorted(set(n for el in elems for n in el if on_equator(coords[n - 1])))
    shapes = []
    for e in SHAPE_EPS:
        if not blocks:
            break
        t, d = min(blocks, key=lambda b: abs(info["travel"] * amp(b[0], info["amp_p"]) / R - e))
        eps = info["travel"] * amp(t, info["amp_p"]) / R
        if abs(eps - e) > 0.01:
            continue
        s = shape3d(coords, elems, d, eq, info["copies"])
        shapes.append(dict(deformation=eps, **s))
    with open(os.path.join(CURVES, name + "_shape.csv"), "w") as f:
        f.write("deformation,a_x_m,a_y_m,a_z_m,volume_ratio,min_J,equator_r0_m,equator_cos2_m,equator_cos4_m,"
                "equator_sin1_m,equator_sin3_m\n")
        V0 = 4.0 / 3.0 * math.pi * R ** 3
        for s in shapes:
            f.write("%.6g,%.8g,%.8g,%.8g,%.6f,%.5f,%.8g,%.5g,%.5g,%.5g,%.5g\n" % (
                s["deformation"], s["axes"][0] * 1e-6, s["axes"][1] * 1e-6, s["axes"][2] * 1e-6, s["volume"] / V0,
                s["jmin"], s["r0"] * 1e-6, s["A2"] * 1e-6, s["A4"] * 1e-6, s["B1"] * 1e-6, s["B3"] * 1e-6))
    return dict(run=name, case=case, level=level, points=len(rows), reached=rows[-1][0] if rows else 0.0,
                info=info, shapes=shapes)

def read_curve(name):
    p = os.path.join(CURVES, name + ".csv")
    rows = []
    for ln in open(p).read().splitlines()[1:]:
        rows.append(tuple(float(x) for x in ln.split(",")))
    return rows


def interp(rows, x):
    """force at abscissa x (column 0), log-log interpolation; None outside."""
    for a, b in zip(rows, rows[1:]):
        if a[0] <= x <= b[0] and b[0] > a[0]:
            if a[0] > 0 and a[2] > 0:
                s = math.log(x / a[0]) / math.log(b[0] / a[0])
                return math.exp(math.log(a[2]) + s * math.log(b[2] / a[2]))
            return a[2] + (b[2] - a[2]) * (x - a[0]) / (b[0] - a[0])
    return None


def material_check():
    """One CAX8 element under a prescribed homogeneous (non-equilibrium) deformation
    lambda_r = lambda_theta = a, lambda_z = b; ccx Cauchy stress vs the paper's energy."""
    results = []
    for w in (1.0, 0.5, 0.25):
        for (a, b) in ((1.1, 0.7), (0.95, 1.3), (1.05, 1.05)):
            E = 150.0
            mat = moduli(E, NU, w)
            r0, r1, z0, z1 = 1.0, 2.0, 0.0, 1.0
            nodes = [(r0, z0), (r1, z0), (r1, z1), (r0, z1), (0.5 * (r0 + r1), z0), (r1, 0.5 * (z0 + z1)),
                     (0.5 * (r0 + r1), z1), (r0, 0.5 * (z0 + z1))]
            L = ["*NODE, NSET=NALL"]
            for i, (r, z) in enumerate(nodes, 1):
                L.append("%d, %g, %g, 0" % (i, r, z))
            L += ["*ELEMENT, TYPE=CAX8, ELSET=E1", "1, 1, 2, 3, 4, 5, 6, 7, 8",
                  "*MATERIAL, NAME=M", "*HYPERELASTIC, MOONEY-RIVLIN",
                  "%.10g, %.10g, %.10g" % (mat["C10"], mat["C01"], mat["D1"]),
                  "*SOLID SECTION, ELSET=E1, MATERIAL=M", "*STEP, NLGEOM", "*STATIC", "0.5, 1.0", "*BOUNDARY"]
            for i, (r, z) in enumerate(nodes, 1):
                L.append("%d, 1, 1, %.10g" % (i, (a - 1) * r))
                L.append("%d, 2, 2, %.10g" % (i, (b - 1) * z))
            L += ["*NSET, NSET=TOP", "3, 4, 7", "*NODE PRINT, NSET=TOP, TOTALS=ONLY", "RF",
                  "*EL PRINT, ELSET=E1", "S", "*END STEP"]
            wd = os.path.join(RUNS, "matcheck")
            shutil.rmtree(wd, ignore_errors=True); os.makedirs(wd)
            open(os.path.join(wd, "job.inp"), "w").write("\n".join(L) + "\n")
            env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_EQUATION_SOLVER="1")
            subprocess.call(["ccx", "-i", "job"], cwd=wd, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, env=env)
            dat = open(os.path.join(wd, "job.dat")).read().splitlines()
            sx = sy = None
            for k, ln in enumerate(dat):
                if "stresses (elem, integ.pnt.,sxx,syy,szz,sxy,sxz,syz)" in ln:
                    blk = [x.split() for x in dat[k + 1:] if len(x.split()) == 8]
                    # last time block; all points equal (homogeneous state): take the first
                    v = [float(x) for x in blk[0][2:]]
                    sx, sy, sz = v[0], v[1], v[2]
            ana = paper_principal_cauchy([a, a, b], E, NU, w)   # (r, theta, z)
            top = parse_totals(os.path.join(wd, "job.dat"))["TOP"][-1][2]
            area = math.pi * a * a * (r1 * r1 - r0 * r0)
            wedge = ana[2] * area / top   # full-circumference force / ccx total RF
            results.append(dict(w=w, a=a, b=b, ccx_srr=sx, ccx_szz=sy, ccx_stt=sz, paper_srr=ana[0], paper_szz=ana[2],
                                rel_err=max(abs(sx - ana[0]), abs(sy - ana[2])) / max(abs(ana[0]), abs(ana[2])),
                                full_force_over_rf=wedge))
            print("matcheck w=%.2f a=%.2f b=%.2f ccx (srr,szz,stt)=(%.5g,%.5g,%.5g) paper (srr,szz)=(%.5g,%.5g)"
                  " sigma_zz*area/RF_total=%.6g" % (w, a, b, sx, sy, sz, ana[0], ana[2], wedge), flush=True)
    return results


# penalty and element studies (--studies): (case, level, tag, settings)
STUDIES = [
    ("plates_w1", 2, "_k1e3", dict(kfac=1e3)),
    ("plates_w1", 2, "_k1e4", dict(kfac=1e4)),
    ("plates_w1", 2, "_k1e6", dict(kfac=1e6)),
    ("plates_w1", 2, "_cax8", dict(eltype="CAX8")),
    ("colloidal_probe", 1, "_k1e4", dict(kfac=1e4)),
    ("colloidal_probe", 1, "_k1e6", dict(kfac=1e6)),
    ("small_probe", 1, "_k1e4", dict(kfac=1e4)),
    ("small_probe", 1, "_k1e6", dict(kfac=1e6)),
]

CHECK = {
    "plates": dict(points=[0.05, 0.1, 0.3, 0.5, 0.675, 0.8], hertz=[0.002, 0.005, 0.01, 0.02, 0.05, 0.1], unit=1.0,
                   label="eps"),
    "colloidal_probe": dict(points=[0.5, 2.0, 10.0, 20.0], hertz=[0.1, 0.2, 0.5, 1.0, 2.0], unit=1e-6, label="d [um]"),
    "small_probe": dict(points=[0.1, 0.5, 1.0, 2.0], hertz=[0.02, 0.05, 0.1, 0.2], unit=1e-6, label="d [um]"),
}


def hertz_of(case, x):
    cfg = CASES[case]
    if cfg["kind"] == "plates":
        return hertz_plates(cfg["E"], cfg["R"] * 1e-6, x)
    return hertz_probe(cfg["E"], cfg["R"] * 1e-6, cfg["Rp"] * 1e-6, x)


def report(cases, levels, allres):
    """Markdown convergence / Hertz tables from the curves on disk."""
    out = []
    runs = allres.get("runs", {})
    for case in cases:
        cfg = CASES[case]
        ck = CHECK["plates" if cfg["kind"] == "plates" else case]
        if case == "plates_w1_hertz":
            ck = dict(points=[0.005, 0.01, 0.02, 0.05], hertz=[0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05],
                      unit=1.0, label="eps")
        have = [lv for lv in levels if os.path.exists(os.path.join(CURVES, "%s_L%d.csv" % (case, lv)))]
        if not have:
            continue
        curves = {lv: read_curve("%s_L%d" % (case, lv)) for lv in have}
        out.append("#### %s" % case)
        out.append("")
        out.append("| level | n | cell elements | nodes | ccx wall [s] | ccx cpu [s] | finished | reached | points |")
        out.append("|---|---|---|---|---|---|---|---|---|")
        for lv in have:
            r = runs.get("%s_L%d" % (case, lv), {})
            inf = r.get("info", {})
            reached = r.get("reached", 0.0) / ck["unit"]
            out.append("| L%d | %s | %s | %s | %s | %s | %s | %.4g | %s |" % (lv, inf.get("n", ""), inf.get("cell_elements", ""),
                                                               inf.get("nodes", ""), r.get("seconds", ""), r.get("cpu_seconds", "-"),
                                                               "yes" if r.get("ok") else "NO", reached, r.get("points", "")))
        out.append("")
        fin = have[-1]
        hdr = "| %s | " % ck["label"] + " | ".join("F L%d [nN]" % lv for lv in have) + " | " + \
              " | ".join("L%d vs L%d" % (a, b) for a, b in zip(have, have[1:])) + " |"
        out.append(hdr)
        out.append("|" + "---|" * (1 + len(have) + len(have) - 1))
        for x in ck["points"]:
            xv = x * ck["unit"]
            F = {lv: interp(curves[lv], xv) for lv in have}
            cells = ["%.5g" % (F[lv] * 1e9) if F[lv] else "-" for lv in have]
            diffs = []
            for a, b in zip(have, have[1:]):
                diffs.append("%+.3f %%" % (100 * (F[a] - F[b]) / F[b]) if F[a] and F[b] else "-")
            out.append("| %g | " % x + " | ".join(cells) + " | " + " | ".join(diffs) + " |")
        out.append("")
        out.append("F / F_Hertz:")
        out.append("")
        out.append("| %s | " % ck["label"] + " | ".join("L%d" % lv for lv in have) + " |")
        out.append("|" + "---|" * (1 + len(have)))
        for x in ck["hertz"]:
            xv = x * ck["unit"]
            cells = []
            for lv in have:
                F = interp(curves[lv], xv)
                cells.append("%.4f" % (F / hertz_of(case, xv)) if F else "-")
            out.append("| %g | " % x + " | ".join(cells) + " |")
        out.append("")
    # studies: tagged runs against the untagged run of the same case and level
    st = [r for r in runs.values() if r["run"] != "%s_L%d" % (r["case"], r["level"]) and r["case"] in cases]
    if st:
        out.append("#### studies (tagged runs) against the default run of the same level")
        out.append("")
        out.append("| run | setting | finished | reached | force change vs default at the check points |")
        out.append("|---|---|---|---|---|")
        for r in sorted(st, key=lambda r: r["run"]):
            base = "%s_L%d" % (r["case"], r["level"])
            cfg = CASES[r["case"]]
            ck = CHECK["plates" if cfg["kind"] == "plates" else r["case"]]
            try:
                cb, ct = read_curve(base), read_curve(r["run"])
            except OSError:
                continue
            cells = []
            for x in ck["points"]:
                fb, ft = interp(cb, x * ck["unit"]), interp(ct, x * ck["unit"])
                cells.append("%g: %s" % (x, ("%+.3f %%" % (100 * (ft - fb) / fb)) if fb and ft else "-"))
            setting = ", ".join("%s=%g" % (k, v) if isinstance(v, float) else "%s=%s" % (k, v) for k, v in r["kw"].items())
            out.append("| %s | %s | %s | %.4g | %s |" % (r["run"], setting, "yes" if r["ok"] else "NO",
                                                         r["reached"] / ck["unit"], "; ".join(cells)))
        out.append("")
    return "\n".join(out) + "\n"


def three_d(a):
    """--three-d: run (or with --analyse re-read) the 3-D plates runs; results.json key runs3d
    (re-read just before writing: two runs may go at the same time)."""
    resfile = os.path.join(HERE, "results.json")
    cases = a.case or ["plates_w0.25"]
    for case in cases:
        for lv in a.levels:
            kw = {}
            if a.imperfection != 1e-3:
                kw["imperfection"] = a.imperfection
            if a.kfac != KFAC:
                kw["kfac"] = a.kfac
            if a.contact:
                kw["contact"] = a.contact
            if a.ramp_power != 2.0:
                kw["amp_p"] = a.ramp_power
            if a.increments != NINC:
                kw["ninc"] = a.increments
            if a.model != "eighth":
                kw["model"] = a.model
            if a.imperfection4:
                kw["imperfection4"] = a.imperfection4
            if a.analyse:
                name = "%s_3d_L%d%s" % (case, lv, a.tag)
                _, info, coords, elems = build3d(case, lv, **kw)
                r = analyse3d(case, name, info, coords, elems, lv)
                old = json.load(open(resfile)).get("runs3d", {}).get(name, {})
                r = dict(old, **r)
            else:
                if shutil.which("ccx") is None:
                    sys.exit("ccx not found: run validation/fe/install-fe-deps.sh")
                r = run_one3d(case, lv, tag=a.tag, **kw)
            allres = json.load(open(resfile))
            allres.setdefault("runs3d", {})[r["run"]] = r
            json.dump(allres, open(resfile, "w"), indent=1, sort_keys=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", nargs="*", default=None, help="default: all cases (and the material check)")
    ap.add_argument("--levels", nargs="*", type=int, default=DEFAULT_LEVELS)
    ap.add_argument("--kfac", type=float, default=KFAC)
    ap.add_argument("--eltype", default=ELTYPE)
    ap.add_argument("--tag", default="")
    ap.add_argument("--contact", default=None, help="2-D: n2s (default), s2s, s2s_rev; 3-D: s2s (default) or n2s")
    ap.add_argument("--no-reference", action="store_true", help="do not copy the finest level to curves/<case>.csv")
    ap.add_argument("--matcheck", action="store_true", help="only the one-element material mapping check")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--studies", action="store_true",
                    help="also run the penalty and element studies (tagged runs, see README)")
    ap.add_argument("--report", action="store_true", help="only rewrite convergence.md from the curves")
    ap.add_argument("--three-d", action="store_true",
                    help="the full 3-D check instead (eighth sphere of C3D20R, plates cases; levels %s)" % LEVELS3D)
    ap.add_argument("--imperfection", type=float, default=1e-3, help="3-D: initial cos 2theta ovalisation eta")
    ap.add_argument("--imperfection4", type=float, default=0.0, help="3-D: initial cos 4theta equator ripple")
    ap.add_argument("--ramp-power", type=float, default=2.0, help="3-D: plate travel ~ t^p (2: dense at small deformation)")
    ap.add_argument("--increments", type=int, default=NINC, help="3-D: the largest increment is 1/N of the step")
    ap.add_argument("--model", default="eighth", choices=["eighth", "quarter"],
                    help="3-D: eighth sphere (x, y, z symmetry planes) or quarter (x and z planes)")
    ap.add_argument("--facet", action="store_true",
                    help="2-D plates: surface mid-side nodes on the chords (a faceted meridian)")
    ap.add_argument("--roughness", type=float, default=0.0,
                    help="2-D plates: random radial offset of the surface corner nodes, fraction of R")
    ap.add_argument("--analyse", action="store_true", help="3-D: only re-read the runs (curves, shapes)")
    a = ap.parse_args()
    if a.list:
        for k, v in CASES.items():
            print(k, v)
        return
    everything = a.case is None
    if a.case is None:
        a.case = list(CASES)
    if a.report:
        allres = json.load(open(os.path.join(HERE, "results.json")))
        open(os.path.join(HERE, "convergence.md"), "w").write(report(a.case, a.levels, allres))
        print(open(os.path.join(HERE, "convergence.md")).read())
        return
    if a.three_d:
        three_d(a)
        return
    if shutil.which("ccx") is None:
        sys.exit("ccx not found: run validation/fe/install-fe-deps.sh")
    resfile = os.path.join(HERE, "results.json")
    allres = json.load(open(resfile)) if os.path.exists(resfile) else {}
    if a.matcheck or everything:
        allres["matcheck"] = material_check()
        json.dump(allres, open(resfile, "w"), indent=1, sort_keys=True)
        if a.matcheck:
            return
    for case in a.case:
        for lv in a.levels:
            kw = {}
            if a.kfac != KFAC:
                kw["kfac"] = a.kfac
            if a.eltype != ELTYPE:
                kw["eltype"] = a.eltype
            if a.contact and a.contact != CONTACT:
                kw["contact"] = a.contact
            if a.facet:
                kw["facet"] = True
            if a.roughness > 0:
                kw["roughness"] = a.roughness
            r = run_one(case, lv, tag=a.tag, **kw)
            allres.setdefault("runs", {})[r["run"]] = r
            json.dump(allres, open(resfile, "w"), indent=1, sort_keys=True)
        if not a.no_reference and not a.tag:
            best = "%s_L%d" % (case, max(a.levels))
            shutil.copy(os.path.join(CURVES, best + ".csv"), os.path.join(CURVES, case + ".csv"))
    if a.studies:
        for case, lv, tag, kw in STUDIES:
            r = run_one(case, lv, tag=tag, **kw)
            allres.setdefault("runs", {})[r["run"]] = r
            json.dump(allres, open(resfile, "w"), indent=1, sort_keys=True)
    if not a.tag:
        open(os.path.join(HERE, "convergence.md"), "w").write(report(list(CASES), sorted(LEVELS), allres))


if __name__ == "__main__":
    main()
