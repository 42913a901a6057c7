#!/usr/bin/env python3
"""cellflow's default compression curves against the CalculiX references.

Runs build/bin/cellflow-run on the issue's plate cases (R = 8.6 um, E = 150 Pa,
nu = 0.48, w = 1, 0.5, 0.25, 40 load points to deformation 0.8, default
numerics) and prints the relative force difference against
validation/fe/curves/plates_w*.csv (linear interpolation in deformation),
from deformation 0.02 on.

    python3 validation/fe/compare_cellflow.py [build-dir]
"""
import bisect
import csv
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))


def reference(name):
    with open(os.path.join(HERE, "curves", name + ".csv")) as f:
        rows = [(float(r["deformation"]), float(r["force_n"])) for r in csv.DictReader(f)]
    xs = [d for d, _ in rows]
    ys = [f for _, f in rows]

    def at(x):
        i = bisect.bisect_left(xs, x)
        if i <= 0 or i >= len(xs):
            return None
        t = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
        return ys[i - 1] + t * (ys[i] - ys[i - 1])

    return at


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else "build"
    runner = os.path.join(build, "bin", "cellflow-run")
    env = dict(os.environ, OMP_WAIT_POLICY="passive")
    for w, name in (("1", "plates_w1"), ("0.5", "plates_w0.5"), ("0.25", "plates_w0.25")):
        spec = {"compression": {"cell": {"radiusM": 8.6e-6, "material": {
            "youngsModulusPa": 150, "poissonRatio": 0.48, "mooneyRivlinW": float(w)}},
            "maxDeformation": 0.8, "loadPoints": 40}}
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(spec, f)
        run = subprocess.run([runner, "-q", "-j", "1", f.name], capture_output=True, text=True, env=env)
        os.unlink(f.name)
        at = reference(name)
        errors = []
        for r in csv.DictReader(run.stdout.splitlines()):
            d, force = float(r["deformation"]), float(r["force_n"])
            ref = at(d)
            if ref and d >= 0.02 - 1e-12:
                errors.append((d, force / ref - 1.0))
        if not errors:
            print(f"w = {w}: no points ({run.stderr.strip()})")
            continue
        worst = max(errors, key=lambda e: abs(e[1]))
        last = errors[-1][0]
        status = "reached 0.8" if last > 0.799 else f"stopped at {last:.3f}: {run.stderr.strip()}"
        print(f"w = {w}: largest |error| {100 * abs(worst[1]):.2f} % at {worst[0]:.3f}; {status}")
        print("   " + "  ".join(f"{d:.2f}: {100 * e:+.2f} %" for d, e in errors if round(d * 40) % 4 == 0))


if __name__ == "__main__":
    main()
