#!/usr/bin/env python3
"""Shape of a cellflow plate-compression state where w = 0.25 leaves the reference.

Reads a `cellflow-run -r FILE.h5` result of a compression (R = 8.6 um) with
h5dump (no numpy / h5py needed) and prints, per position frame from
deformation 0.5 on: each plate's contact vertices (within 2e-3 R of the
outermost surface vertex), the contact radius a (largest distance from the
axis; per 8 sectors), the nearest non-contact surface vertex (its gap to the
plate and radial position against a: negative = inside the rim), the surface
triangles within 0.05 R of a plate whose outward normal points away from it
(a surface rolled in or folded under), the bulge (largest radius per 16
azimuthal sectors) and the top contact rim radius per sector with their
Fourier amplitudes |c_n| / mean (n = 1..6), and the upper / lower halves'
largest radius (modes antisymmetric about the mid plane). For a quadratic-tet
result (more positions than corner vertices: the mid-edge nodes follow) also
the deepest dip of a surface edge's quadratic interpolant below the plate
(the outermost node's height) and where it is.

    python3 validation/fe/departure_state.py RESULT.h5
"""
import math, re, subprocess, sys, collections

def ds(path, name):
    out = subprocess.run(["h5dump", "-w", "0", "-d", name, path], capture_output=True, text=True).stdout
    body = out.split("DATA {", 1)[1].split("}", 1)[0]
    body = re.sub(r"\(\d+(,\d+)*\):", "", body)
    return [float(x) for x in body.replace(",", " ").split()]

f = sys.argv[1]
R = 8.6e-6  # the cell (plates_w0.25)
times = ds(f, "/particles/cell/position/time")
P = ds(f, "/particles/cell/position/value")
T = [int(x) for x in ds(f, "/connectivity/cell")]
nf = len(times); nv = len(P) // (3 * nf)
tets = [T[i:i + 4] for i in range(0, len(T), 4)]
faces = collections.Counter()
fo = {}
for t in tets:
    for (a, b, c, d) in ((t[0], t[1], t[2], t[3]), (t[0], t[1], t[3], t[2]), (t[0], t[2], t[3], t[1]), (t[1], t[2], t[3], t[0])):
        k = tuple(sorted((a, b, c))); faces[k] += 1; fo[k] = (a, b, c, d)
surf = [fo[k] for k, n in faces.items() if n == 1]
sv = sorted({v for s in surf for v in s[:3]})
def sub(a, b): return [a[i] - b[i] for i in range(3)]
def cross(a, b): return [a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0]]
def dot(a, b): return sum(a[i]*b[i] for i in range(3))
print(f"{nv} vertices, {len(tets)} tets, {len(sv)} surface vertices, {len(surf)} surface triangles")
for fr in range(nf):
    if times[fr] < 0.5 and fr != nf - 1: continue
    Y = [P[3*(fr*nv+v):3*(fr*nv+v)+3] for v in range(nv)]
    zt = max(Y[v][2] for v in sv); zb = min(Y[v][2] for v in sv)
    tol = 2e-3 * R
    cx = sum(Y[v][0] for v in range(nv)) / nv; cy = sum(Y[v][1] for v in range(nv)) / nv
    cz = sum(Y[v][2] for v in range(nv)) / nv
    line = [f"eps {times[fr]:.2f}: height/2R {(zt-zb)/(2*R):.4f}, centroid z {(cz-(zt+zb)/2)/R:+.1e} R"]
    for name, zp, sgn in (("top", zt, 1), ("bottom", zb, -1)):
        cv = [v for v in sv if sgn * (zp - Y[v][2]) < tol]
        rho = lambda v: math.hypot(Y[v][0]-cx, Y[v][1]-cy)
        sect = collections.defaultdict(float)
        for v in cv:
            s = int(((math.atan2(Y[v][1]-cy, Y[v][0]-cx) + math.pi) / (2*math.pi)) * 8) % 8
            sect[s] = max(sect[s], rho(v))
        a = max(rho(v) for v in cv)
        # free surface just outside the rim: gap to the plate of non-contact surface vertices within 0.25 R of it
        free = [v for v in sv if v not in set(cv) and rho(v) < a + 0.25*R and sgn*(zp-Y[v][2]) < 0.3*R]
        gaps = sorted((sgn*(zp-Y[v][2]) / R, (rho(v)-a)/R) for v in free)
        # surface triangles within 0.05 R of the plate whose outward normal points away from the plate's side
        inv = 0; near = 0
        for (p, q, r_, d) in surf:
            n = cross(sub(Y[q], Y[p]), sub(Y[r_], Y[p]))
            if dot(n, sub(Y[d], Y[p])) > 0: n = [-x for x in n]
            zc = (Y[p][2]+Y[q][2]+Y[r_][2]) / 3
            if sgn*(zp - zc) < 0.05*R:
                near += 1
                if sgn*n[2] < 0: inv += 1
        line.append(f"{name}: {len(cv)} contact v, a/R {a/R:.3f} (8 sectors {min(sect.values())/R:.3f}-{max(sect.values())/R:.3f}), "
                    f"nearest free v gap/R {gaps[0][0]:.4f} at rho-a {gaps[0][1]:+.3f} R; tri near plate {near}, normal away {inv}")
    NS = 16
    def sector_fourier(vals):
        m = sum(vals) / len(vals)
        out = []
        for n in range(1, 7):
            c = sum(x*math.cos(2*math.pi*n*(k+0.5)/NS) for k, x in enumerate(vals)) * 2/NS
            s_ = sum(x*math.sin(2*math.pi*n*(k+0.5)/NS) for k, x in enumerate(vals)) * 2/NS
            out.append(f"{n}:{math.hypot(c, s_)/m:.3f}")
        return m, " ".join(out)
    bul = [0.0]*NS; rim = [0.0]*NS
    for v in sv:
        k = int(((math.atan2(Y[v][1]-cy, Y[v][0]-cx) + math.pi) / (2*math.pi)) * NS) % NS
        r = math.hypot(Y[v][0]-cx, Y[v][1]-cy)
        bul[k] = max(bul[k], r)
        if zt - Y[v][2] < tol: rim[k] = max(rim[k], r)
    m, fs = sector_fourier(bul); line.append(f"bulge max radius (16 sectors) mean {m/R:.3f} R, min {min(bul)/R:.3f} max {max(bul)/R:.3f}, modes {fs}")
    m, fs = sector_fourier(rim); line.append(f"top rim radius (16 sectors) mean {m/R:.3f} R, min {min(rim)/R:.3f} max {max(rim)/R:.3f}, modes {fs}")
    # mid-plane antisymmetry: max radius in upper half vs lower half
    up = max(math.hypot(Y[v][0]-cx, Y[v][1]-cy) for v in sv if Y[v][2] > (zt+zb)/2)
    lo = max(math.hypot(Y[v][0]-cx, Y[v][1]-cy) for v in sv if Y[v][2] <= (zt+zb)/2)
    line.append(f"max radius upper/lower half {up/R:.4f}/{lo/R:.4f}")
    print("\n  ".join(line))

nc = 1 + max(T)
if nv > nc:  # quadratic tets: find each surface edge's mid-edge node in the reference frame
    X0 = [P[3*v:3*v+3] for v in range(nv)]
    grid = collections.defaultdict(list); h = 0.3e-6
    for v in range(nc, nv):
        grid[tuple(int(math.floor(x / h)) for x in X0[v])].append(v)
    def nearest(p):
        k = [int(math.floor(x / h)) for x in p]
        return min((math.dist(p, X0[v]), v) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                   for v in grid.get((k[0]+dx, k[1]+dy, k[2]+dz), []))
    mid = {}
    for s_ in surf:
        for a, b in ((s_[0], s_[1]), (s_[1], s_[2]), (s_[0], s_[2])):
            a, b = min(a, b), max(a, b)
            if (a, b) in mid: continue
            m = [(X0[a][i] + X0[b][i]) / 2 for i in range(3)]
            r = (math.hypot(*X0[a]) + math.hypot(*X0[b])) / 2; n = math.hypot(*m)
            mid[(a, b)] = nearest([x * r / n for x in m])[1]  # surface mid nodes lie on the sphere
    for fr in range(nf):
        if times[fr] < 0.3: continue
        Y = [P[3*(fr*nv+v):3*(fr*nv+v)+3] for v in range(nv)]
        zt = max(y[2] for y in Y); zb = min(y[2] for y in Y)
        deep = []
        for (a, b), m in mid.items():
            for zp, sg in ((zt, 1), (zb, -1)):
                g0, gm, g1 = (sg * (zp - Y[v][2]) for v in (a, m, b))
                # g(s) = g0 + B s + A s^2 through the gaps at s = 0, 1/2, 1
                A = 2*g0 - 4*gm + 2*g1; B = -3*g0 + 4*gm - g1
                cands = [0, 1] + ([-B / (2*A)] if A > 0 and 0 < -B / (2*A) < 1 else [])
                dip = -min(g0 + B*x + A*x*x for x in cands)
                if dip > 1e-3 * R: deep.append((dip / R, math.hypot(Y[m][0], Y[m][1]) / R, max(g0, g1) / R))
        deep.sort(reverse=True)
        rim = max(math.hypot(Y[v][0], Y[v][1]) for v in range(nv) if zt - Y[v][2] < 2e-3*R)
        d = deep[0] if deep else (0.0, 0.0, 0.0)
        print(f"eps {times[fr]:.2f}: {len(deep)} surface edges dip > 1e-3 R below a plate; deepest {d[0]:.4f} R "
              f"at rho {d[1]:.3f} R (outermost top contact node {rim/R:.3f} R), its far corner {d[2]:.4f} R off")
