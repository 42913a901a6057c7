#!/usr/bin/env python3
"""Draw the deformed (r, z) mesh of a run as a PNG (standard library only).

  python3 validation/fe/plot_mesh.py validation/fe/runs/<run> [block index, default last] [out.png]
"""
import os
import struct
import sys
import zlib


def read_inp(path):
    nodes, elems, mode = {}, [], None
    for ln in open(path):
        if ln.startswith("*"):
            u = ln.upper()
            mode = "N" if u.startswith("*NODE,") or u.startswith("*NODE\n") else ("E" if u.startswith("*ELEMENT") else None)
            continue
        v = [x for x in ln.replace(",", " ").split()]
        if mode == "N" and len(v) >= 3:
            nodes[int(v[0])] = (float(v[1]), float(v[2]))
        elif mode == "E" and len(v) >= 9:
            elems.append([int(x) for x in v[1:9]])
    return nodes, elems


def read_disp(path):
    blocks, cur = [], None
    for ln in open(path):
        if ln.startswith(" -4  DISP"):
            cur = {}
            blocks.append(cur)
        elif ln.startswith(" -3"):
            cur = None
        elif cur is not None and ln.startswith(" -1"):
            n = int(ln[3:13])
            cur[n] = (float(ln[13:25]), float(ln[25:37]))
    return blocks


def png(path, W, H, pix):
    raw = b"".join(b"\x00" + bytes(pix[y * W * 3:(y + 1) * W * 3]) for y in range(H))

    def chunk(t, d):
        c = struct.pack(">I", len(d)) + t + d
        return c + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def main():
    run = sys.argv[1]
    k = int(sys.argv[2]) if len(sys.argv) > 2 else -1
    out = sys.argv[3] if len(sys.argv) > 3 else os.path.join(run, "mesh.png")
    nodes, elems = read_inp(os.path.join(run, "job.inp"))
    blocks = read_disp(os.path.join(run, "job.frd"))
    d = blocks[k] if blocks else {}
    P = {n: (x + d.get(n, (0, 0))[0], y + d.get(n, (0, 0))[1]) for n, (x, y) in nodes.items()}
    xs = [p[0] for p in P.values()]; ys = [p[1] for p in P.values()]
    if len(sys.argv) > 4:
        x0, x1, y0, y1 = [float(v) for v in sys.argv[4].split(":")]
    else:
        x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    W = 1000
    H = int(W * (y1 - y0) / max(x1 - x0, 1e-12)) + 1
    H = max(50, min(H, 1600))
    s = min((W - 20) / (x1 - x0), (H - 20) / (y1 - y0))
    pix = bytearray([255]) * (W * H * 3)

    def put(x, y):
        i, j = int(10 + (x - x0) * s), int(H - 10 - (y - y0) * s)
        if 0 <= i < W and 0 <= j < H:
            pix[(j * W + i) * 3:(j * W + i) * 3 + 3] = b"\x00\x00\x00"

    for e in elems:
        seq = [e[0], e[4], e[1], e[5], e[2], e[6], e[3], e[7], e[0]]
        for a, b in zip(seq, seq[1:]):
            (xa, ya), (xb, yb) = P[a], P[b]
            n = int(max(abs(xb - xa), abs(yb - ya)) * s) + 1
            for t in range(n + 1):
                put(xa + (xb - xa) * t / n, ya + (yb - ya) * t / n)
    png(out, W, H, pix)
    print(out, len(blocks), "blocks")


if __name__ == "__main__":
    main()


def jacobians(run, k=-1, elset_first=None):
    """J = det F at the centre of each cell element (quadratic serendipity map, hoop stretch r / R)
    for frd block k; returns (min J, max J)."""
    nodes, elems = read_inp(os.path.join(run, "job.inp"))
    d = read_disp(os.path.join(run, "job.frd"))[k]
    cell = []
    mode = None
    for ln in open(os.path.join(run, "job.inp")):
        if ln.startswith("*"):
            mode = "CELL" if (ln.upper().startswith("*ELEMENT") and "ELSET=CELL" in ln.upper()) else None
            continue
        if mode == "CELL":
            v = [int(x) for x in ln.replace(",", " ").split()]
            cell.append(v[1:9])
    # quad8 shape function derivatives at the centre (xi = eta = 0)
    dN = [(-0.0, -0.0)] * 8
    dxi = [0, 0, 0, 0, 0, 0.5, 0, -0.5]
    deta = [0, 0, 0, 0, -0.5, 0, 0.5, 0]
    N = [-0.25, -0.25, -0.25, -0.25, 0.5, 0.5, 0.5, 0.5]
    Js = []
    for e in cell:
        X = [nodes[n] for n in e]
        x = [(nodes[n][0] + d.get(n, (0, 0))[0], nodes[n][1] + d.get(n, (0, 0))[1]) for n in e]

        def jac(P):
            a = sum(dxi[i] * P[i][0] for i in range(8)); b = sum(deta[i] * P[i][0] for i in range(8))
            c = sum(dxi[i] * P[i][1] for i in range(8)); dd = sum(deta[i] * P[i][1] for i in range(8))
            return a * dd - b * c
        R0 = sum(N[i] * X[i][0] for i in range(8)); r = sum(N[i] * x[i][0] for i in range(8))
        Js.append((jac(x) / jac(X) * (r / R0 if R0 > 1e-12 else 1.0), R0, sum(N[i] * X[i][1] for i in range(8))))
    jm = min(Js)
    return jm[0], max(Js)[0], (round(jm[1], 3), round(jm[2], 3))
