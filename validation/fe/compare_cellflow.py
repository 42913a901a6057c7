#!/usr/bin/env python3
"""cellflow's default contact curves against the CalculiX references.

Runs build/bin/cellflow-run on the issue's cases at default numerics and
prints the relative force difference against validation/fe/curves/*.csv
(linear interpolation in deformation or indentation) and the run time:
  plates_w1, plates_w0.5, plates_w0.25: R = 8.6 um, E = 150 Pa, nu = 0.48,
      40 load points to deformation 0.8, errors from deformation 0.02 on;
  colloidal_probe: R = 40 um, Rp = 26.5 um, E = 580 Pa, 40 points to 20 um,
      errors from 0.25 um on;
  small_probe: R = 8 um, Rp = 2.5 um, E = 1000 Pa, 40 points to 2 um,
      errors from 0.1 um on.

    python3 validation/fe/compare_cellflow.py [build-dir] [--numerics JSON]
        [--cases NAME ...] [--vertices N]

--numerics merges a QuasiStaticNumerics JSON object into every spec (e.g.
'{"contactEnforcement": "CONTACT_ENFORCEMENT_PENALTY",
  "probeContact": "PROBE_CONTACT_VERTICES"}' for the contact before issue 11,
'{"element": "ELEMENT_QUADRATIC_TET"}' for the 10-node tetrahedron).
"""
import argparse
import bisect
import csv
import json
import os
import subprocess
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def reference_rows(name, column):
    """(x, F) of every row of curves/<name>.csv, x from `column`."""
    with open(os.path.join(HERE, "curves", name + ".csv")) as f:
        return [(float(r[column]), float(r["force_n"])) for r in csv.DictReader(f)]


def reference(name, column):
    rows = reference_rows(name, column)
    xs = [d for d, _ in rows]
    ys = [f for _, f in rows]

    def at(x):
        i = bisect.bisect_left(xs, x)
        if i <= 0 or i >= len(xs):
            return None
        t = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
        return ys[i - 1] + t * (ys[i] - ys[i - 1])

    return at


def polynomial_fit(pts, degree):
    """Coefficients c_0 ... c_degree of the least-squares polynomial through
    the points (u, v)."""
    n = degree + 1
    # normal equations A c = b, A_jk = sum u^(j+k), b_j = sum u^j v
    a = [[sum(u ** (j + k) for u, _ in pts) for k in range(n)] for j in range(n)]
    b = [sum(u ** j * v for u, v in pts) for j in range(n)]
    for i in range(n):  # Gauss-Jordan with partial pivoting
        p = max(range(i, n), key=lambda r: abs(a[r][i]))
        a[i], a[p], b[i], b[p] = a[p], a[i], b[p], b[i]
        for r in range(n):
            if r != i:
                f = a[r][i] / a[i][i]
                a[r] = [x - f * y for x, y in zip(a[r], a[i])]
                b[r] -= f * b[i]
    return [b[i] / a[i][i] for i in range(n)]


def smooth_reference(name, column, first, end, degree=3):
    """ln F of the reference as a least-squares polynomial of ln x over
    [first/2, end]: the reference without the steps of its own node-to-surface
    contact (its local exponent d ln F / d ln x wiggles by about +-0.05 from
    row to row), for the step ratio against a smooth curve."""
    import math
    rows = reference_rows(name, column)
    pts = [(math.log(x), math.log(y)) for x, y in rows if 0.5 * first <= x <= end * (1 + 1e-9) and y > 0]
    c = polynomial_fit(pts, degree)
    return lambda x: math.exp(sum(ci * math.log(x) ** i for i, ci in enumerate(c)))


def local_smooth_reference(name, column, rows_each_side=3):
    """ln F of the reference as a quadratic in ln x fitted to the 2 k + 1 rows
    nearest x (least squares; reference_zigzag.py measures the rows against
    the same fit): follows the reference over the whole range, also at small
    deformation where one cubic over the curve does not, without the
    alternation of its rows."""
    import math
    pts = [(math.log(x), math.log(y)) for x, y in reference_rows(name, column) if x > 0 and y > 0]
    log_xs = [p for p, _ in pts]

    def at(x):
        u = math.log(x)
        i = bisect.bisect_left(log_xs, u)
        lo = max(0, min(i - rows_each_side - 1, len(pts) - 2 * rows_each_side - 1))
        window = [(p - u, v) for p, v in pts[lo:lo + 2 * rows_each_side + 1]]
        return math.exp(polynomial_fit(window, 2)[0])

    return at


def cell(radius, modulus, w):
    return {"radiusM": radius, "material": {"youngsModulusPa": modulus, "poissonRatio": 0.48,
                                            "mooneyRivlinW": w}}


# name: (spec, x column in the reference, x of a cellflow row, smallest x compared, end, unit, scale)
CASES = {
    "plates_w1": ({"compression": {"cell": cell(8.6e-6, 150, 1.0), "maxDeformation": 0.8, "loadPoints": 40}},
                  "deformation", "deformation", 0.02, 0.8, "", 1.0),
    "plates_w0.5": ({"compression": {"cell": cell(8.6e-6, 150, 0.5), "maxDeformation": 0.8, "loadPoints": 40}},
                    "deformation", "deformation", 0.02, 0.8, "", 1.0),
    "plates_w0.25": ({"compression": {"cell": cell(8.6e-6, 150, 0.25), "maxDeformation": 0.8,
                                      "loadPoints": 40}}, "deformation", "deformation", 0.02, 0.8, "", 1.0),
    "colloidal_probe": ({"indentation": {"cell": cell(40e-6, 580, 1.0), "probeRadiusM": 26.5e-6,
                                         "maxIndentationM": 20e-6, "loadPoints": 40}},
                        "indentation_m", "displacement_m", 0.25e-6, 20e-6, " um", 1e6),
    "small_probe": ({"indentation": {"cell": cell(8e-6, 1000, 1.0), "probeRadiusM": 2.5e-6,
                                     "maxIndentationM": 2e-6, "loadPoints": 40}},
                    "indentation_m", "displacement_m", 0.1e-6, 2e-6, " um", 1e6),
}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("build", nargs="?", default="build")
    parser.add_argument("--numerics", default="{}")
    parser.add_argument("--cases", nargs="*", default=list(CASES))
    parser.add_argument("--vertices", type=int, default=0)
    parser.add_argument("--all-points", action="store_true", help="print the error at every load point, not every fourth")
    parser.add_argument("--mesh-file", default="", help="a Gmsh .msh v4 mesh in metres instead of the generated sphere "
                        "(e.g. structured_sphere.py's, with the case's radius)")
    args = parser.parse_args()
    runner = os.path.join(args.build, "bin", "cellflow-run")
    env = dict(os.environ, OMP_WAIT_POLICY="passive")
    numerics = json.loads(args.numerics)
    for name in args.cases:
        spec, ref_col, row_col, first, end, unit, scale = CASES[name]
        spec = json.loads(json.dumps(spec))
        scene = next(iter(spec))
        if numerics:
            spec[scene]["numerics"] = numerics
        if args.vertices:
            spec[scene]["cell"]["targetVertexCount"] = args.vertices
        if args.mesh_file:
            spec[scene]["cell"]["meshFile"] = os.path.abspath(args.mesh_file)
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(spec, f)
        start = time.time()
        cpu_start = os.times()
        run = subprocess.run([runner, "-q", "-j", "1", f.name], capture_output=True, text=True, env=env)
        seconds = time.time() - start
        cpu_end = os.times()
        cpu = (cpu_end.children_user - cpu_start.children_user) + (cpu_end.children_system -
                                                                    cpu_start.children_system)
        os.unlink(f.name)
        at = reference(name, ref_col)
        errors = []
        points = []
        for r in csv.DictReader(run.stdout.splitlines()):
            x, force = float(r[row_col]), float(r["force_n"])
            ref = at(x)
            if ref and x >= first * (1 - 1e-9):
                errors.append((x, force / ref - 1.0, float(r["max_penetration_m"])))
                points.append((force, ref))
        if not errors:
            print(f"{name}: no points ({run.stderr.strip()})")
            continue
        worst = max(errors, key=lambda e: abs(e[1]))
        # Raggedness: each step of the force against the reference's step
        # over the same interval (1: the same step; > 1: a jump).
        steps = [(f1 - f0) / (r1 - r0) for (f0, r0), (f1, r1) in zip(points, points[1:])]

        def steps_against(fit):
            """Each step of cellflow's force and of the reference's against
            the same step of a fitted curve."""
            intervals = list(zip(errors, errors[1:], points, points[1:]))
            own = [(f1 - f0) / (fit(x1) - fit(x0)) for (x0, _, _), (x1, _, _), (f0, _), (f1, _) in intervals]
            ref = [(r1 - r0) / (fit(x1) - fit(x0)) for (x0, _, _), (x1, _, _), (_, r0), (_, r1) in intervals]
            return own, ref

        smooth_steps, ref_steps = steps_against(smooth_reference(name, ref_col, first, end))
        local_steps, local_ref_steps = steps_against(local_smooth_reference(name, ref_col))
        monotone = all(s > 0 for s in steps)
        # Where the largest step ends (the x of its second point).
        step_at = errors[1 + steps.index(max(steps))][0] if steps else 0.0
        last = errors[-1][0]
        status = (f"reached {end * scale:g}{unit}" if last > end * (1 - 1e-3)
                  else f"stopped at {last * scale:.3f}{unit}: {run.stderr.strip()}")
        print(f"{name}: largest |error| {100 * abs(worst[1]):.2f} % at {worst[0] * scale:.3f}{unit}; "
              f"{status}; {'monotone' if monotone else 'NOT monotone'}, largest step / reference step "
              f"{max(steps, default=0):.3f} (to {step_at * scale:.3g}{unit}), against the smoothed reference "
              f"{max(smooth_steps, default=0):.3f} (the reference's own steps against it "
              f"{min(ref_steps, default=0):.3f}-{max(ref_steps, default=0):.3f}), against a local fit "
              f"{max(local_steps, default=0):.3f} (the reference's own {min(local_ref_steps, default=0):.3f}-"
              f"{max(local_ref_steps, default=0):.3f}); {seconds:.1f} s wall, {cpu:.1f} s CPU; max penetration {max(e[2] for e in errors):.2e} m")
        print("   " + "  ".join(f"{d * scale:.3g}: {100 * e:+.2f} %"
                                for i, (d, e, _) in enumerate(errors)
                                if args.all_points or i % 4 == 0 or i < 4 or i == len(errors) - 1))


if __name__ == "__main__":
    main()
