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


def build(case, level, kfac=KFAC, eltype=ELTYPE, ninc=NINC, contact=None):
    cfg = CASES[case]
    n = LEVELS[level]
    R, E, w = cfg["R"], cfg["E"], cfg["w"]
    m = Mesh()
    if cfg["kind"] == "plates":
        disk_quarter(m, "CELL", 0.0, R, n, +1, pole_beta=cfg.get("pole_beta", 0.0))
        plate(m, "PLATE", R, 2.6 * R, 0.2 * R, max(8, 2 * n), +1)
    else:
        disk_quarter(m, "CELL", R, R, n, +1, pole_beta=cfg["pole_beta"])
        disk_quarter(m, "CELL", R, R, n, -1, pole_beta=cfg["pole_beta"])  # same grading: conforming mid-plane
        Rp = cfg["Rp"]
        plate(m, "PLATE", 0.0, 2.0 * R, 0.2 * R, max(8, 2 * n), -1)
        nprobe = max(12, int(round(4 * n * cfg["theta"] / (math.pi / 4))))
        probe(m, "PROBE", 2 * R + Rp, Rp, cfg["theta"], nprobe)

    mat = moduli(E, NU, w)
    K = kfac * E / R
    L = []
    L.append("** generated by validation/fe/run_references.py: case %s, level %d (n=%d), %s, K=%g Pa/um"
             % (case, level, n, eltype, K))
    L.append("** units: um, Pa, pN.  E=%g Pa nu=%g w=%g: mu=%.6g kappa=%.6g" % (E, NU, w, mat["mu"], mat["kappa"]))
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

    def on_circle(p, cen, rad, tol=1e-6):
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", nargs="*", default=None, help="default: all cases (and the material check)")
    ap.add_argument("--levels", nargs="*", type=int, default=DEFAULT_LEVELS)
    ap.add_argument("--kfac", type=float, default=KFAC)
    ap.add_argument("--eltype", default=ELTYPE)
    ap.add_argument("--tag", default="")
    ap.add_argument("--contact", default=CONTACT)
    ap.add_argument("--no-reference", action="store_true", help="do not copy the finest level to curves/<case>.csv")
    ap.add_argument("--matcheck", action="store_true", help="only the one-element material mapping check")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--studies", action="store_true",
                    help="also run the penalty and element studies (tagged runs, see README)")
    ap.add_argument("--report", action="store_true", help="only rewrite convergence.md from the curves")
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
            if a.contact != CONTACT:
                kw["contact"] = a.contact
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
