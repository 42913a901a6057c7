#!/usr/bin/env python3
"""CalculiX on cellflow's own tetrahedral mesh (issue 11, item 3: w = 0.25 past deformation 0.65).

The full sphere (no symmetry planes) of a cellflow compression result (H5MD, `cellflow-run -r`),
as linear tetrahedra C3D4 (the element of cellflow's VOLUMETRIC_TERM_PER_TET: one integration
point, each tet its own J) or as C3D10 (the same tets with straight-edge mid-side nodes:
the same geometry, a quadratic field), the paper's energy eq. 5 as ccx's Mooney-Rivlin with
its volumetric term (C10 = mu1/2, C01 = mu2/2, D1 = 2/kappa; README "Energy mapping"), two rigid
plates (C3D8 slabs, all nodes prescribed) with frictionless surface-to-surface penalty contact
(linear, K = 1e5 E/R, as the references; --contact n2s and --c0 (exponential law) were tried and
stall, cfmesh.md), nonlinear geometry, quasi-static.

Rigid modes of the free sphere: the vertex nearest the centre is held in x, y, z, the surface
vertex nearest (R, 0, 0) in y (rotation about z), and springs of SPRING_ER E R (x, y) at the two
pole vertices take the rotations about x and y; both plates move, by delta/2 each, from the
mesh's extreme heights.  No mode of the continuum is excluded by these point constraints (the
sphere is otherwise free, both sides of the mid plane).

Runs (`--mode`):
  load:    from the undeformed mesh to --eps (default 0.8), plate travel ~ t^2, increments
           <= 1/--ninc of the step; force and elastic energy at every increment.
  restart: cellflow's state at the frame nearest to --at as a first step (every cell node's
           displacement prescribed but the centre's x, the plates 1.5e-4 um into the state's
           extreme heights): ccx's nodal reactions at cellflow's positions (the same-state check,
           printed and in results_cfmesh.json); then released with the plates held and compressed
           on to --eps (that release diverges in ccx 2.20, also for an equilibrium state:
           cfmesh.md).
Deformation = delta / (2R): delta the sum of both plates' travel from the mesh's extreme heights
(cellflow's: 1 - height / initial height of the vertices, the stand-off of its penalty range taken
out), R = 8.6 um.

    build/bin/cellflow-run -r /tmp/w025_1000.h5 spec.json   # plates_w0.25 at 1000 vertices
    python3 validation/fe/run_cellflow_mesh.py /tmp/w025_1000.h5 --eltype C3D4 --mode load --tag _1000
    python3 validation/fe/run_cellflow_mesh.py /tmp/w025_1000_07.h5 --eltype C3D4 --mode restart --at 0.7

Writes decks/cfmesh_<eltype>_<mode><tag>.inp, curves/cfmesh_<eltype>_<mode><tag>.csv
(step, time, deformation, force_top_n, force_bottom_n, elastic_energy_j: ccx's ELSE, integrated over
the increments), the run's ccx wall / CPU seconds to results_cfmesh.json. numpy and h5py (Debian python3-numpy, python3-h5py).
"""
import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import time

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import run_references as rr  # noqa: E402

RUNS = os.path.join(HERE, "runs")
R_UM = 8.6
E_PA = 150.0
RESTART_C0_UM = 0.05  # restart decks: clearance within which ccx makes contact elements [um]
P0_E = 1e-2  # exponential contact law: pressure at zero clearance, per E
SPRING_ER = 1e-3  # pole springs against the free rotations, per E R
TET_FACES = [(0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)]  # ccx C3D4/C3D10 faces S1..S4


def load_result(path):
    f = h5py.File(path, "r")
    pos = f["particles/cell/position/value"][:] * 1e6  # um
    fstep = f["particles/cell/position/step"][:]
    T = f["connectivity/cell"][:].astype(np.int64)
    ob = f["observables"]
    obs = {k: ob[k + "/value"][:] for k in ("deformation", "force_n", "elastic_energy_j")}
    obs["step"] = ob["deformation/step"][:]
    return pos, fstep, T, obs


def orient(X, T):
    """ccx's positive orientation: (x2 - x1) x (x3 - x1) . (x4 - x1) > 0."""
    a, b, c, d = (X[T[:, k]] for k in range(4))
    vol = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)
    T = T.copy()
    neg = vol < 0
    T[neg, 1], T[neg, 2] = T[neg, 2].copy(), T[neg, 1].copy()
    return T


def boundary_faces(T):
    """(element index, ccx face number) of the faces on the surface."""
    faces = {}
    for e, t in enumerate(T):
        for f, fc in enumerate(TET_FACES):
            key = tuple(sorted(int(t[k]) for k in fc))
            faces.setdefault(key, []).append((e, f + 1))
    return [v[0] for v in faces.values() if len(v) == 1]


def midside(T):
    """C3D10 mid-side nodes: edge (a, b) -> new index; element lists in ccx order."""
    pairs = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]  # nodes 5..10
    edges = {}
    elems = []
    for t in T:
        mids = []
        for a, b in pairs:
            key = (min(t[a], t[b]), max(t[a], t[b]))
            if key not in edges:
                edges[key] = len(edges)
            mids.append(edges[key])
        elems.append(mids)
    return edges, np.array(elems, dtype=np.int64)


def sphere_midpoints(X, ends, boundary):
    """cellflow's ELEMENT_QUADRATIC_TET mid-edge nodes (physics/mesh/quadratic_tets.cc): the
    midpoint of every boundary edge moved radially about the origin to the mean distance of the
    edge's ends (the quadratic surface on the sphere through its vertices); inner edges straight."""
    a, b = X[ends[:, 0]], X[ends[:, 1]]
    m = 0.5 * (a + b)
    r = 0.5 * (np.linalg.norm(a, axis=1) + np.linalg.norm(b, axis=1))
    lm = np.linalg.norm(m, axis=1)
    sel = boundary & (lm > 0)
    m[sel] *= (r[sel] / lm[sel])[:, None]
    return m


def build(pos, T, eltype, mode, frame, eps_max, ninc, kfac=rr.KFAC, w=0.25, controls=None, c0_r=0.0, contact="s2s",
          midside_mode="straight", frd_every=0):
    X = pos[0]
    T = orient(X, T)
    nv = len(X)
    mat = rr.moduli(E_PA, rr.NU, w)
    K = kfac * E_PA / R_UM
    ztop, zbot = X[:, 2].max(), X[:, 2].min()
    h0 = ztop - zbot
    travel = 0.5 * eps_max * 2 * R_UM  # each plate
    # nodes: cell corners, [mid-side], then the plates
    coords = [tuple(p) for p in X]
    if eltype == "C3D10":
        edges, mids = midside(T)
        ends = np.zeros((len(edges), 2), dtype=np.int64)
        for (a, b), i in edges.items():
            ends[i] = (a, b)
        if midside_mode == "sphere":
            bedges = set()
            for e, f in boundary_faces(T):
                fc = [int(T[e][k]) for k in TET_FACES[f - 1]]
                for u, v in ((0, 1), (1, 2), (2, 0)):
                    bedges.add((min(fc[u], fc[v]), max(fc[u], fc[v])))
            on_b = np.array([(int(a), int(b)) in bedges for a, b in ends])
            mid_xyz = sphere_midpoints(X, ends, on_b)
        else:
            mid_xyz = 0.5 * (X[ends[:, 0]] + X[ends[:, 1]])
        coords += [tuple(p) for p in mid_xyz]
        # the plates start at the extreme heights of all nodes (curved mid-side nodes may lie outside
        # the corners' range; for the generated sphere with a vertex at each pole they do not)
        ztop, zbot = max(ztop, mid_xyz[:, 2].max()), min(zbot, mid_xyz[:, 2].min())
        h0 = ztop - zbot
    ncell = len(coords)
    W, th, npl = 2.6 * R_UM, 0.2 * R_UM, 10
    plates = {}
    for name, z0, sgn in (("TOP", ztop, +1), ("BOT", zbot, -1)):
        base = len(coords)
        for k in range(2):
            for j in range(npl + 1):
                for i in range(npl + 1):
                    coords.append((-W + 2 * W * i / npl, -W + 2 * W * j / npl, z0 + sgn * th * k))
        idx = lambda i, j, k: base + k * (npl + 1) ** 2 + j * (npl + 1) + i + 1
        els = []
        for j in range(npl):
            for i in range(npl):
                lo = [idx(i, j, 0), idx(i + 1, j, 0), idx(i + 1, j + 1, 0), idx(i, j + 1, 0)]
                hi = [idx(i, j, 1), idx(i + 1, j, 1), idx(i + 1, j + 1, 1), idx(i, j + 1, 1)]
                # C3D8 nodes 1-4 at the bottom of the slab, 5-8 at the top (positive volume)
                els.append(lo + hi if sgn > 0 else hi + lo)
        # the face towards the cell: S1 (nodes 1-4) of the top plate, S2 (5-8) of the bottom one
        plates[name] = (els, 1 if sgn > 0 else 2, list(range(base + 1, len(coords) + 1)))
    centre = int(np.argmin(np.linalg.norm(X, axis=1)))
    surf_nodes = np.unique(np.array([[T[e][k] for k in TET_FACES[f - 1]] for e, f in boundary_faces(T)]))
    ypin = int(surf_nodes[np.argmin(np.linalg.norm(X[surf_nodes] - np.array([R_UM, 0, 0]), axis=1))])
    poles = [int(np.argmax(X[:, 2])), int(np.argmin(X[:, 2]))]

    L = ["** generated by validation/fe/run_cellflow_mesh.py: cellflow's mesh (%d vertices, %d tets), %s, "
         "mode %s, K=%g Pa/um" % (nv, len(T), eltype, mode, K),
         "** units: um, Pa, pN.  E=%g Pa nu=%g w=%g: mu=%.6g kappa=%.6g" % (E_PA, rr.NU, w, mat["mu"], mat["kappa"]),
         "*NODE, NSET=NALL"]
    for i, p in enumerate(coords, 1):
        L.append("%d, %.12g, %.12g, %.12g" % (i, p[0], p[1], p[2]))
    L.append("*ELEMENT, TYPE=%s, ELSET=CELL" % eltype)
    for e, t in enumerate(T, 1):
        ids = [int(x) + 1 for x in t]
        if eltype == "C3D10":
            ids += [nv + int(x) + 1 for x in mids[e - 1]]
        L.append("%d, %s" % (e, ", ".join(str(x) for x in ids)))
    eid = len(T)
    # Weak springs to ground, x and y, at the two pole vertices: the rotations about x and y are
    # free while the plates touch only the poles (no friction).  k = SPRING_ER E R per spring:
    # at 1 um of lateral pole motion 1e-3 E R um = 1.3 pN, 1e-5 of the force at deformation 0.3.
    ksp = SPRING_ER * E_PA * R_UM
    for c, nm in ((1, "SPRX"), (2, "SPRY")):
        L.append("*ELEMENT, TYPE=SPRING1, ELSET=%s" % nm)
        for pv in poles:
            eid += 1
            L.append("%d, %d" % (eid, pv + 1))
    surf = {}
    for name in ("TOP", "BOT"):
        els, face, _ = plates[name]
        L.append("*ELEMENT, TYPE=C3D8, ELSET=PLATE%s" % name)
        surf[name] = []
        for el in els:
            eid += 1
            L.append("%d, %s" % (eid, ", ".join(str(x) for x in el)))
            surf[name].append((eid, face))

    def nset(name, ids):
        L.append("*NSET, NSET=%s" % name)
        ids = list(ids)
        for i in range(0, len(ids), 12):
            L.append(", ".join(str(x) for x in ids[i:i + 12]) + ",")

    nset("CENTRE", [centre + 1]); nset("YPIN", [ypin + 1])
    nset("PTOP", plates["TOP"][2]); nset("PBOT", plates["BOT"][2])
    nset("CELLN", range(1, ncell + 1))
    L.append("*ELSET, ELSET=PLATES")
    L.append("PLATETOP, PLATEBOT")
    L.append("*SURFACE, NAME=SCELL, TYPE=ELEMENT")
    L += ["%d, S%d" % (e + 1, f) for e, f in boundary_faces(T)]
    L.append("*SURFACE, NAME=MPLATES, TYPE=ELEMENT")
    L += ["%d, S%d" % ef for ef in surf["TOP"] + surf["BOT"]]
    L += ["*MATERIAL, NAME=CELLMAT", "*HYPERELASTIC, MOONEY-RIVLIN",
          "%.10g, %.10g, %.10g" % (mat["C10"], mat["C01"], mat["D1"]),
          "*MATERIAL, NAME=RIGID", "*ELASTIC", "%.6g, 0.3" % (1e6 * E_PA),
          "*SOLID SECTION, ELSET=CELL, MATERIAL=CELLMAT", "*SOLID SECTION, ELSET=PLATES, MATERIAL=RIGID",
          "*SPRING, ELSET=SPRX", "1", "%.8g" % ksp, "*SPRING, ELSET=SPRY", "2", "%.8g" % ksp,
          "*CONTACT PAIR, INTERACTION=SI, TYPE=%s" % ("NODE TO SURFACE" if contact == "n2s" else "SURFACE TO SURFACE"),
          "SCELL, MPLATES",
          "*SURFACE INTERACTION, NAME=SI"]
    if c0_r:
        # exponential law (C1: no kink where a node enters the contact; the linear law's kink made
        # ccx cycle between two contact states at deformation 0.40, increment below minimum):
        # pressure p0 at zero clearance, ~0 at clearance c0, growing exponentially with overclosure
        L += ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=EXPONENTIAL", "%.8g, %.8g" % (c0_r * R_UM, P0_E * E_PA)]
    elif mode == "restart":
        L += ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", "%.8g, 1e-3, %.8g" % (K, RESTART_C0_UM)]
    else:
        L += ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", "%.8g" % K]
    L += rr.amplitude_lines("RAMP", p=2.0)
    out = ["*NODE PRINT, NSET=PTOP, TOTALS=ONLY, FREQUENCY=1", "RF",
           "*NODE PRINT, NSET=PBOT, TOTALS=ONLY, FREQUENCY=1", "RF",
           "*EL PRINT, ELSET=CELL, TOTALS=ONLY, FREQUENCY=1", "ELSE",
           "*NODE FILE, NSET=CELLN, FREQUENCY=%d" % (frd_every or (1 if eltype == "C3D4" else 4)), "U"]
    # (ccx 2.20 takes this last FREQUENCY for the .dat too: C3D10's force rows every 4th increment)
    info = dict(vertices=nv, tets=len(T), nodes=len(coords), cell_nodes=ncell, h0_um=h0, K=K, eltype=eltype,
                midside=midside_mode if eltype == "C3D10" else None, mode=mode, centre=centre, ypin=ypin, poles=poles, spring_n_per_m=ksp * 1e-6, ninc=ninc)
    if mode == "load":
        L += ["*BOUNDARY", "CENTRE, 1, 3, 0.", "YPIN, 2, 2, 0.", "PTOP, 1, 2, 0.", "PBOT, 1, 2, 0.",
              "*STEP, NLGEOM, INC=100000", "*STATIC", "%g, 1.0, %g, %g" % (1.0 / ninc, 1e-7, 1.0 / ninc),
              "*BOUNDARY, AMPLITUDE=RAMP", "PTOP, 3, 3, %.10g" % (-travel), "PBOT, 3, 3, %.10g" % travel] + out + \
             ["*END STEP"]
        info.update(steps=[dict(kind="ramp", d0=0.0, d1=2 * travel, amp_p=2.0)])
    else:
        P = pos[frame]
        U = P - X
        # The plates 1.5e-4 um into the extreme vertices (about the linear law's penetration p / K
        # at 250 Pa); the surface-to-surface contact elements are generated within the clearance
        # c0 of the restart's contact law (RESTART_C0_UM), so cellflow's contact vertices, spread
        # over its penalty range (~0.01 um), are in contact when the state is released.  (Plates
        # overlapping all of them by their spread put 1e5 pN on single nodes; plates at the extreme
        # heights with the default c0 left the release without contact elements.)
        tol = 2e-3 * R_UM
        off_top = off_bot = 1.5e-4
        dz_top, dz_bot = P[:, 2].max() - ztop - off_top, P[:, 2].min() - zbot + off_bot
        d_state = dz_bot - dz_top  # total compression of the plates in ccx
        # the vertices cellflow's plates act on (within 2e-3 R of the state's extreme heights)
        nset("CTOP", [i + 1 for i in range(nv) if P[i, 2] > P[:, 2].max() - tol])
        nset("CBOT", [i + 1 for i in range(nv) if P[i, 2] < P[:, 2].min() + tol])
        L += ["*BOUNDARY", "PTOP, 1, 2, 0.", "PBOT, 1, 2, 0.",
              "*STEP, NLGEOM, INC=100000", "*STATIC", "0.05, 1.0, 1e-7, 0.05",
              "*BOUNDARY"]
        # every cell node prescribed but the x of the centre vertex: with no free degree of freedom
        # ccx solves nothing in the step and the prescribed state never reaches its solution
        # (released, the nodes jumped by the whole displacement, ~10 um)
        for i in range(nv):
            for c in range(3):
                if not (i == centre and c == 0):
                    L.append("%d, %d, %d, %.12g" % (i + 1, c + 1, c + 1, U[i, c]))
        if eltype == "C3D10":
            for i, (a, b) in enumerate(ends):
                um = 0.5 * (U[a] + U[b])
                for c in range(3):
                    L.append("%d, %d, %d, %.12g" % (nv + i + 1, c + 1, c + 1, um[c]))
        L += ["PTOP, 3, 3, %.12g" % dz_top, "PBOT, 3, 3, %.12g" % dz_bot] + out + [
            "*NODE PRINT, NSET=CTOP, TOTALS=ONLY, FREQUENCY=1", "RF",
            "*NODE PRINT, NSET=CBOT, TOTALS=ONLY, FREQUENCY=1", "RF",
            "*NODE PRINT, NSET=CELLN, FREQUENCY=1", "RF", "*END STEP"]
        # release: the plates held, the centre and the y pin at cellflow's values
        L += ["*STEP, NLGEOM, INC=100000", "*STATIC", "%g, 1.0, %g, %g" % (1.0 / 10, 1e-7, 1.0 / 10),
              "*BOUNDARY, OP=NEW", "PTOP, 1, 2, 0.", "PBOT, 1, 2, 0.",
              "PTOP, 3, 3, %.12g" % dz_top, "PBOT, 3, 3, %.12g" % dz_bot]
        L += ["%d, %d, %d, %.12g" % (centre + 1, c + 1, c + 1, U[centre, c]) for c in range(3)]
        L += ["%d, 2, 2, %.12g" % (ypin + 1, U[ypin, 1])] + out + ["*END STEP"]
        # on to eps_max (linear ramp of the remaining travel)
        rest = travel - 0.5 * d_state
        steps = [dict(kind="impose", d0=0.0, d1=d_state), dict(kind="release", d0=d_state, d1=d_state)]
        if rest > 1e-9:
            L += ["*STEP, NLGEOM, INC=100000", "*STATIC", "%g, 1.0, %g, %g" % (1.0 / 20, 1e-7, 1.0 / 20),
                  "*BOUNDARY", "PTOP, 3, 3, %.12g" % (dz_top - rest), "PBOT, 3, 3, %.12g" % (dz_bot + rest)] + \
                 out + ["*END STEP"]
            steps.append(dict(kind="linear", d0=d_state, d1=d_state + 2 * rest))
        info.update(steps=steps, frame=int(frame), state_eps=d_state / (2 * R_UM), plate_overlap_um=[off_top, off_bot],
                    cf_state_eps=(h0 - (P[:, 2].max() - P[:, 2].min())) / (2 * R_UM),
                    state_eps_eff=d_state / h0)
    if controls:  # ccx's time incrementation controls I0, IR, IP, IC, ... (a step card: in every step)
        M = []
        for k, ln in enumerate(L):
            M.append(ln)
            if k > 0 and L[k - 1] == "*STATIC":
                M += ["*CONTROLS, PARAMETERS=TIME INCREMENTATION", controls]
        L = M
    return "\n".join(L) + "\n", info


def parse(datfile, info):
    """Rows (step, time, deformation, force_n top, force_n bottom, energy_j) from the .dat."""
    lines = open(datfile).read().splitlines() if os.path.exists(datfile) else []
    pf = re.compile(r"total force \(fx,fy,fz\) for set (\S+) and time\s+(\S+)")
    pe = re.compile(r"total internal energy for set (\S+) and time\s+(\S+)")
    recs = []  # (kind, set, time, value)
    for i, ln in enumerate(lines):
        for pat, kind, n in ((pf, "F", 3), (pe, "E", 1)):
            mt = pat.search(ln)
            if mt:
                for j in range(i + 1, min(i + 5, len(lines))):
                    v = lines[j].split()
                    if len(v) == n:
                        recs.append((kind, mt.group(1), float(mt.group(2)), [float(x) for x in v]))
                        break
    # the step changes where the time falls back
    rows, step, last_t, cur = [], 0, -1.0, {}
    for kind, name, t, v in recs:
        if kind == "F" and name == "PTOP":
            if t < last_t - 1e-12:
                step += 1
            last_t = t
            cur = dict(step=step, t=t, ftop=-v[2])
        elif kind == "F" and name == "PBOT":
            cur["fbot"] = v[2]
        elif kind == "E":
            cur["E"] = v[0]
            rows.append(cur)
    out = []
    for r in rows:
        s = info["steps"][min(r["step"], len(info["steps"]) - 1)]
        if s["kind"] == "ramp":
            d = s["d0"] + (s["d1"] - s["d0"]) * r["t"] ** s["amp_p"]
        else:
            d = s["d0"] + (s["d1"] - s["d0"]) * r["t"]
        out.append((r["step"], r["t"], d / (2 * R_UM), r["ftop"] * 1e-12, r.get("fbot", float("nan")) * 1e-12,
                    r["E"] * 1e-18))
    return out


def log_stats(logtxt):
    """ccx's incrementation from its log: attempts (every try of an increment), converged increments,
    cut-backs (retries of an increment after a failed attempt), Newton iterations, the
    smallest increment size tried [step time]."""
    attempts = len(re.findall(r"^ increment \d+ attempt \d+", logtxt, re.M))
    converged = len(re.findall(r"^ convergence", logtxt, re.M))
    iterations = len(re.findall(r"^ iteration \d+", logtxt, re.M))
    sizes = [float(x) for x in re.findall(r"^ increment size=\s*(\S+)", logtxt, re.M)]
    retries = len(re.findall(r"^ increment \d+ attempt (?:[2-9]|\d\d+)\b", logtxt, re.M))
    return dict(attempts=attempts, increments=converged, cutbacks=retries, iterations=iterations,
                min_increment=min(sizes) if sizes else None)


def state_check(datfile, info):
    """Restart runs: ccx's nodal reactions at cellflow's prescribed state (end of the first step):
    the z force on the vertices cellflow's plates act on (top, bottom) and the reactions on every
    cell node (zero at the free nodes where the state is an equilibrium of ccx's discretisation)."""
    lines = open(datfile).read().splitlines()
    pf = re.compile(r"total force \(fx,fy,fz\) for set (CTOP|CBOT) and time\s+(\S+)")
    pn = re.compile(r"forces \(fx,fy,fz\) for set CELLN and time\s+(\S+)")
    tot, blocks, cur, last_t = {}, [], None, -1.0
    for i, ln in enumerate(lines):
        mt = pf.search(ln)
        if mt:
            cur = None
            for j in range(i + 1, min(i + 5, len(lines))):
                v = lines[j].split()
                if len(v) == 3:
                    tot[mt.group(1)] = float(v[2])
                    break
            continue
        mt = pn.search(ln)
        if mt:
            t = float(mt.group(1))
            if t < last_t - 1e-12:
                break  # the second step: the first step's blocks are complete
            last_t = t
            cur = {}
            blocks.append(cur)
            continue
        if cur is not None:
            v = ln.split()
            if len(v) == 4:
                cur[int(v[0])] = [float(x) for x in v[1:]]
            elif v:
                cur = None
    return tot, (blocks[-1] if blocks else {})


def write_states(frd, info, X, T, out, converged):
    """ccx's cell states (the .frd's U blocks of a load run) as a cellflow-like H5MD file for
    departure_state.py: position frames [m] with the deformation as their time, the corner
    connectivity, the mid-side nodes (C3D10) after the corners.  Only blocks at the step times of
    converged increments (`converged`, the .dat rows' times): after "too many cutbacks" ccx writes
    the diverged attempt as a last block."""
    blocks = rr.read_frd_disp3(frd)
    n = info["cell_nodes"]
    s = info["steps"][0]
    times, frames = [], []
    for t, U in blocks:
        if len(U) < n or not any(abs(t - tc) < 1e-5 * max(tc, 1e-3) for tc in converged):
            continue
        u = np.array([U[i + 1] for i in range(n)])
        times.append((s["d0"] + (s["d1"] - s["d0"]) * t ** s["amp_p"]) / (2 * R_UM))
        frames.append((X[:n] + u) * 1e-6)
    with h5py.File(out, "w") as f:
        f["particles/cell/position/value"] = np.array(frames)
        f["particles/cell/position/time"] = np.array(times)
        f["particles/cell/position/step"] = np.arange(len(times))
        f["connectivity/cell"] = T.astype(np.int32)
    return len(times)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("result")
    ap.add_argument("--eltype", default="C3D4", choices=["C3D4", "C3D10"])
    ap.add_argument("--mode", default="load", choices=["load", "restart"])
    ap.add_argument("--at", type=float, default=0.7, help="restart: the frame nearest to this deformation")
    ap.add_argument("--eps", type=float, default=0.8)
    ap.add_argument("--ninc", type=int, default=80)
    ap.add_argument("--w", type=float, default=0.25)
    ap.add_argument("--tag", default="")
    ap.add_argument("--kfac", type=float, default=rr.KFAC, help="penalty slope K / (E/R)")
    ap.add_argument("--c0", type=float, default=0.0, help="exponential contact law, clearance c0 / R (0: linear)")
    ap.add_argument("--contact", default="s2s", choices=["s2s", "n2s"],
                    help="ccx contact: surface to surface (penalty over the cell's faces) or node to surface")
    ap.add_argument("--controls", default=None, help="ccx *CONTROLS time incrementation line, e.g. 8,10,9,40")
    ap.add_argument("--midside", default="straight", choices=["straight", "sphere"],
                    help="C3D10 mid-side nodes: edge midpoints, or boundary ones on the sphere as cellflow's "
                         "ELEMENT_QUADRATIC_TET (physics/mesh/quadratic_tets.cc)")
    ap.add_argument("--states-h5", default=None,
                    help="load runs: also write ccx's cell states (.frd) to this H5 file for departure_state.py")
    ap.add_argument("--frd-every", type=int, default=0,
                    help="output every N increments (0: 1 for C3D4, 4 for C3D10; ccx applies it to the .dat too)")
    ap.add_argument("--deck-only", action="store_true")
    ap.add_argument("--parse-only", action="store_true")
    a = ap.parse_args()
    pos, fstep, T, obs = load_result(a.result)
    frame = 0
    if a.mode == "restart":
        # frame k holds load point step fstep[k]; its deformation from the observables
        defs = {int(s): float(d) for s, d in zip(obs["step"], obs["deformation"])}
        frame = min(range(1, len(fstep)), key=lambda k: abs(defs.get(int(fstep[k]), 9.0) - a.at))
    name = "cfmesh_%s_%s%s" % (a.eltype, a.mode, a.tag)
    deck, info = build(pos, T, a.eltype, a.mode, frame, a.eps, a.ninc, kfac=a.kfac, w=a.w, controls=a.controls,
                       c0_r=a.c0, contact=a.contact, midside_mode=a.midside,
                       frd_every=a.frd_every)
    info.update(contact=a.contact, kfac=a.kfac, controls=a.controls, c0_r=a.c0, p0_pa=P0_E * E_PA if a.c0 else None)
    info["result"] = os.path.abspath(a.result)
    os.makedirs(os.path.join(HERE, "decks"), exist_ok=True)
    with open(os.path.join(HERE, "decks", name + ".inp"), "w") as f:
        f.write(deck)
    wd = os.path.join(RUNS, name)
    if a.deck_only:
        print(name, json.dumps(info))
        return
    dt = cpu = None
    if not a.parse_only:
        shutil.rmtree(wd, ignore_errors=True)
        os.makedirs(wd)
        with open(os.path.join(wd, "job.inp"), "w") as f:
            f.write(deck)
        env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_EQUATION_SOLVER="1", CCX_NPROC_RESULTS="1",
                   CCX_NPROC_STIFFNESS="1")
        t0 = time.time()
        ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        with open(os.path.join(wd, "ccx.log"), "w") as log:
            rc = subprocess.call(["nice", "-n", "5", "ccx", "-i", "job"], cwd=wd, stdout=log,
                                 stderr=subprocess.STDOUT, env=env)
        dt = time.time() - t0
        ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
        info["rc"] = rc
    rows = parse(os.path.join(wd, "job.dat"), info)
    logtxt = open(os.path.join(wd, "ccx.log")).read() if os.path.exists(os.path.join(wd, "ccx.log")) else ""
    info.update(ok="Job finished" in logtxt and "*ERROR" not in logtxt, seconds=dt and round(dt, 1),
                cpu_seconds=cpu and round(cpu, 1), points=len(rows), reached=rows[-1][2] if rows else 0.0,
                **log_stats(logtxt))
    if a.mode == "restart" and rows:
        tot, nodal = state_check(os.path.join(wd, "job.dat"), info)
        P = pos[frame]
        nv = len(P)
        tol = 2e-3 * R_UM
        contact = set(i + 1 for i in range(nv) if P[i, 2] > P[:, 2].max() - tol or P[i, 2] < P[:, 2].min() + tol)
        free = np.array([v for k, v in nodal.items() if k not in contact and k <= nv])
        k_cf = int(np.where(obs["step"] == fstep[frame])[0][0])
        e0 = [r for r in rows if r[0] == 0][-1]
        e1 = [r for r in rows if r[0] == 1][-1] if any(r[0] == 1 for r in rows) else None
        info["state_check"] = dict(
            ccx_force_on_cf_top_vertices_n=-tot.get("CTOP", float("nan")) * 1e-12,
            ccx_force_on_cf_bottom_vertices_n=tot.get("CBOT", float("nan")) * 1e-12,
            cellflow_force_n=float(obs["force_n"][k_cf]), cellflow_energy_j=float(obs["elastic_energy_j"][k_cf]),
            cellflow_deformation=float(obs["deformation"][k_cf]),
            ccx_energy_of_cf_state_j=e0[5], ccx_energy_released_j=e1[5] if e1 else None,
            ccx_force_released_n=e1[3] if e1 else None,
            free_node_reaction_rms_n=float(np.sqrt((free ** 2).sum(axis=1).mean())) * 1e-12 if len(free) else None,
            free_node_reaction_max_n=float(np.sqrt((free ** 2).sum(axis=1)).max()) * 1e-12 if len(free) else None,
            contact_vertices=len(contact))
        print(json.dumps(info["state_check"], indent=1))
    if a.states_h5 and a.mode == "load":
        lines = deck.splitlines()
        i0 = lines.index("*NODE, NSET=NALL") + 1
        Xn = np.array([[float(x) for x in ln.split(",")[1:]] for ln in lines[i0:i0 + info["cell_nodes"]]])
        k = write_states(os.path.join(wd, "job.frd"), info, Xn, orient(pos[0], T), a.states_h5,
                         [r[1] for r in rows])
        print("%d states -> %s" % (k, a.states_h5))
    with open(os.path.join(HERE, "curves", name + ".csv"), "w") as f:
        f.write("step,time,deformation,force_top_n,force_bottom_n,elastic_energy_j\n")
        for r in rows:
            f.write("%d,%.6g,%.8g,%.8g,%.8g,%.8g\n" % r)
    jf = os.path.join(HERE, "results_cfmesh.json")
    allres = json.load(open(jf)) if os.path.exists(jf) else {}
    if a.parse_only and name in allres:  # keep the run's measured times and exit status
        for k in ("seconds", "cpu_seconds", "rc"):
            if allres[name].get(k) is not None:
                info[k] = allres[name][k]
    allres[name] = info
    json.dump(allres, open(jf, "w"), indent=1, sort_keys=True)
    print("%s ok=%s wall %s s cpu %s s points %d reached %.4f nodes %d; %d increments, %d attempts (%d cut-backs), "
          "%d iterations, smallest increment %s" % (
              name, info["ok"], info["seconds"], info["cpu_seconds"], len(rows), info["reached"], info["nodes"],
              info["increments"], info["attempts"], info["cutbacks"], info["iterations"], info["min_increment"]),
          flush=True)


if __name__ == "__main__":
    main()
