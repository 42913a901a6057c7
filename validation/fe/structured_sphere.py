#!/usr/bin/env python3
"""A structured, mirror-symmetric tetrahedral sphere mesh (Gmsh MSH 4.1, metres) for cellflow.

Issue 11 item 3: does cellflow's w = 0.25 departure at deformation 0.65 come from the irregular
TetGen meshes (every tet mesh tried left the branch there) or from the continuum?  This mesh is
the O-grid of the 3-D CalculiX check (run_references.py `sphere_octant`: a rounded-cube core and
three blocks per octant, n hexes per block edge, radial clustering toward the surface), mirrored
into all eight octants and split into tetrahedra conformingly: every hex face into four triangles
around its centre (shared with the neighbour, on the sphere for surface faces), each triangle
with the hex centre a tetrahedron (24 per hex).  The result has the octahedral mirror symmetry of
the O-grid: no mesh-scale irregularity seeds an azimuthal mode.

    python3 validation/fe/structured_sphere.py --radius 8.6e-6 --n 3 --out /tmp/sphere_n3.msh
    python3 validation/fe/compare_cellflow.py build --cases plates_w0.25 --mesh-file /tmp/sphere_n3.msh
"""
import argparse
import math
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run_references as rr  # noqa: E402


def octant_hexes(n, pole_beta):
    """Unit-radius octant: node coordinates and 8-node hexes (corner nodes of the 20-node O-grid)."""
    m = rr.Mesh3()
    rr.sphere_octant(m, "CELL", 1.0, n, pole_beta=pole_beta)
    return m.nodes, [el[:8] for el in m.elems["CELL"]]


def full_sphere(n, pole_beta):
    """The octant mirrored into all eight, coincident nodes merged (run_references' Mesh3, 1-based
    node ids: mg.nodes[i - 1])."""
    nodes, hexes = octant_hexes(n, pole_beta)
    mg = rr.Mesh3()
    out = []
    for sx in (1, -1):
        for sy in (1, -1):
            for sz in (1, -1):
                ids = [mg.node((sx * x, sy * y, sz * z)) for (x, y, z) in nodes]
                out += [[ids[v - 1] for v in h] for h in hexes]
    return mg, out


def unit(p):
    s = math.sqrt(sum(v * v for v in p))
    return tuple(v / s for v in p)


def tetrahedralise(mg, hexes):
    tets = []
    xyz = lambda i: mg.nodes[i - 1]
    on_sphere = lambda i: abs(math.sqrt(sum(v * v for v in xyz(i))) - 1.0) < 1e-9
    for h in hexes:
        centre = mg.node(tuple(sum(xyz(i)[d] for i in h) / 8.0 for d in range(3)))
        for face in rr.HEX_FACES:
            c = [h[k] for k in face]
            fc = tuple(sum(xyz(i)[d] for i in c) / 4.0 for d in range(3))
            if all(on_sphere(i) for i in c):
                fc = unit(fc)
            f = mg.node(fc)
            for a, b in zip(c, c[1:] + c[:1]):
                tets.append([a - 1, b - 1, f - 1, centre - 1])
    return orient_positive(mg.nodes, tets)


def tet_det(xyz, t):
    p = [xyz[i] for i in t]
    e = [[p[k][d] - p[0][d] for d in range(3)] for k in (1, 2, 3)]
    return (e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
            + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]))


def orient_positive(xyz, tets):
    """Positive orientation in Gmsh's convention: det[x1 - x0, x2 - x0, x3 - x0] > 0."""
    for t in tets:
        det = tet_det(xyz, t)
        if det < 0:
            t[1], t[2] = t[2], t[1]
        elif det == 0:
            raise SystemExit("degenerate tetrahedron")
    return tets


def jitter(xyz, tets, amplitude, seed):
    """Moves every vertex by a random vector of length up to amplitude x its shortest edge
    (surface vertices then projected back onto the sphere): an irregular mesh of the same
    resolution, to measure how the departure depends on the mesh's irregularity."""
    rng = random.Random(seed)
    shortest = [float("inf")] * len(xyz)
    for t in tets:
        for i in range(4):
            for j in range(i + 1, 4):
                a, b = t[i], t[j]
                d = math.dist(xyz[a], xyz[b])
                shortest[a] = min(shortest[a], d)
                shortest[b] = min(shortest[b], d)
    out = []
    for i, p in enumerate(xyz):
        if shortest[i] == float("inf"):
            out.append(p)
            continue
        while True:
            v = [rng.uniform(-1, 1) for _ in range(3)]
            if 0 < sum(c * c for c in v) <= 1:
                break
        r = math.sqrt(sum(c * c for c in p))
        q = tuple(p[d] + amplitude * shortest[i] * v[d] for d in range(3))
        out.append(unit(q) if abs(r - 1.0) < 1e-9 else q)
    return out


def write_msh(path, xyz, tets, radius):
    used = sorted(set(i for t in tets for i in t))
    tag = {i: k + 1 for k, i in enumerate(used)}
    lo = [min(xyz[i][d] for i in used) * radius for d in range(3)]
    hi = [max(xyz[i][d] for i in used) * radius for d in range(3)]
    with open(path, "w") as f:
        f.write("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
        f.write('$PhysicalNames\n1\n3 1 "cytoplasm"\n$EndPhysicalNames\n')
        f.write("$Entities\n0 0 0 1\n1 %s %s 1 1 0\n$EndEntities\n"
                % (" ".join("%.9g" % v for v in lo), " ".join("%.9g" % v for v in hi)))
        f.write("$Nodes\n1 %d 1 %d\n3 1 0 %d\n" % (len(used), len(used), len(used)))
        f.write("".join("%d\n" % tag[i] for i in used))
        f.write("".join("%.12g %.12g %.12g\n" % tuple(v * radius for v in xyz[i]) for i in used))
        f.write("$EndNodes\n$Elements\n1 %d 1 %d\n3 1 4 %d\n" % (len(tets), len(tets), len(tets)))
        f.write("".join("%d %s\n" % (k + 1, " ".join(str(tag[i]) for i in t)) for k, t in enumerate(tets)))
        f.write("$EndElements\n")
    return len(used)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--radius", type=float, default=8.6e-6, help="sphere radius [m]")
    ap.add_argument("--n", type=int, default=3, help="hexes per O-grid block edge (4 n^3 per octant)")
    ap.add_argument("--pole-beta", type=float, default=0.0,
                    help="surface grading toward the symmetry planes (the 3-D check uses 0.5)")
    ap.add_argument("--jitter", type=float, default=0.0,
                    help="random vertex displacement, fraction of the vertex's shortest edge")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    mg, hexes = full_sphere(a.n, a.pole_beta)
    tets = tetrahedralise(mg, hexes)
    xyz = mg.nodes
    if a.jitter > 0:
        xyz = jitter(xyz, tets, a.jitter, a.seed)
        if any(tet_det(xyz, t) <= 0 for t in tets):
            raise SystemExit("the jitter inverted a tetrahedron: use a smaller --jitter")
    nv = write_msh(a.out, xyz, tets, a.radius)
    print("%s: %d hexes -> %d tetrahedra, %d vertices" % (a.out, len(hexes), len(tets), nv))


if __name__ == "__main__":
    main()
