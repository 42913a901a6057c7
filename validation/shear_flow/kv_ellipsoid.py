#!/usr/bin/env python3
"""Independent reference for the shear-flow scene: the homogeneously deformed
neo-Hookean Kelvin-Voigt ellipsoid with viscosity ratio 1 in unbounded simple
shear, Stokes flow, integrated in time from the undeformed sphere.

Why this is exact: a homogeneously deformed sphere (x = F X) is an ellipsoid
x^T B^-1 x = R^2 with B = F F^T, so the incompressible neo-Hookean stress
mu (B - I) (paper eq. 7 at J = 1) is uniform inside it. An ellipsoid with a
uniform extra stress in a fluid of the same viscosity has a uniform interior
velocity gradient (Eshelby's inclusion result, velocity for displacement):

    L_in = L_inf + (S + Pi) : eps*,   eps* = -dev(sigma_el) / (2 eta),

S and Pi the Eshelby tensors of the current ellipsoid for Poisson ratio 1/2
(Mura, Micromechanics of Defects in Solids, sec. 11), evaluated in its
principal frame. Pi : eps* vanishes because sigma_el is coaxial with the
ellipsoid. So dF/dt = L_in F is the whole dynamics; its steady state is
Roscoe's (1967) lambda = 1 solution, which this script reproduces
(shared/validation/roscoe_elastic_sphere_shear.csv, column D_lambda1: 0.1216,
0.4384, 0.6136, 0.7068, 0.7656 at Ca 0.1, 0.5, 1, 1.5, 2). What it adds is
the transient: at Ca 2, D overshoots to 0.851 at strain 9 and undershoots to
0.754 at strain 24 before it settles, which a steady-state rule must not
take for the steady state.

Units: eta = 1, gammadot = 1 (time = strain), mu = 1 / Ca, R = 1.
Flow along x, gradient along y, vorticity along z (the scene's axes).

    python3 validation/shear_flow/kv_ellipsoid.py            # writes the CSV beside this file
    python3 validation/shear_flow/kv_ellipsoid.py --ca 2 --print

Needs numpy and scipy (Debian: python3-numpy python3-scipy).
"""
import argparse
import csv
import os

import numpy as np
from scipy.integrate import quad, solve_ivp

CAPILLARY_NUMBERS = [0.05, 0.1, 0.2, 0.4, 0.8, 1.0, 1.25, 1.6, 2.0]
SAMPLE_EVERY_STRAIN = 0.1  # as the scene's default sample_every_strain


def eshelby_integrals(a):
    """Mura's I_i and I_ij of the ellipsoid with semi-axes a (eq. 11.18-11.19)."""
    volume_factor = 2.0 * np.pi * a[0] * a[1] * a[2]
    delta = lambda s: np.sqrt((a[0] ** 2 + s) * (a[1] ** 2 + s) * (a[2] ** 2 + s))
    i1 = np.array([volume_factor * quad(lambda s: 1.0 / ((a[i] ** 2 + s) * delta(s)), 0.0, np.inf,
                                        limit=200)[0] for i in range(3)])
    i2 = np.array([[volume_factor * quad(lambda s: 1.0 / ((a[i] ** 2 + s) * (a[j] ** 2 + s) * delta(s)),
                                         0.0, np.inf, limit=200)[0] for j in range(3)] for i in range(3)])
    return i1, i2


def interior_strain_rate(a, eps_star):
    """S : eps* for Poisson ratio 1/2 in the principal frame (Mura eq. 11.16)."""
    _, i2 = eshelby_integrals(a)
    s = np.zeros((3, 3, 3, 3))
    for i in range(3):
        s[i, i, i, i] = 3.0 / (4.0 * np.pi) * a[i] ** 2 * i2[i, i]
        for j in range(3):
            if i != j:
                s[i, i, j, j] = 1.0 / (4.0 * np.pi) * a[j] ** 2 * i2[i, j]
                s[i, j, i, j] = s[i, j, j, i] = (a[i] ** 2 + a[j] ** 2) / (8.0 * np.pi) * i2[i, j]
    return np.einsum("ijkl,kl->ij", s, eps_star)


def rate(_, y, ca):
    f = y.reshape(3, 3)
    b = f @ f.T
    w, q = np.linalg.eigh(b)
    # sigma_el = mu dev(B), mu = 1 / Ca (eta = gammadot = 1; paper eq. 17)
    sigma_local = np.diag(w - w.sum() / 3.0) / ca
    l_inf = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    l_in = l_inf + q @ interior_strain_rate(np.sqrt(w), -sigma_local / 2.0) @ q.T
    return (l_in @ f).ravel()


def shape(f):
    """Taylor deformation in the shear plane (paper eq. 13), inclination [deg], semi-axes."""
    b = f @ f.T
    w, v = np.linalg.eigh(b[:2, :2])
    long_axis, short_axis = np.sqrt(w[1]), np.sqrt(w[0])
    angle = np.degrees(np.arctan2(v[1, 1], v[0, 1])) % 180.0
    if angle > 90.0:
        angle -= 180.0
    return ((long_axis - short_axis) / (long_axis + short_axis), angle, np.sqrt(np.linalg.eigvalsh(b)))


def trajectory(ca, max_strain):
    sol = solve_ivp(rate, (0.0, max_strain), np.eye(3).ravel(), args=(ca,), rtol=1e-8, atol=1e-10,
                    dense_output=True)
    strains = np.arange(0.0, max_strain + 1e-9, SAMPLE_EVERY_STRAIN)
    return [(t,) + shape(sol.sol(t).reshape(3, 3)) for t in strains]


def max_strain_for(ca):
    # the transient's slowest part lasts about 20 Ca strain units; twice that
    return max(20.0, 40.0 * ca)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ca", type=float, action="append", help="capillary number (repeat); default: the set")
    parser.add_argument("--print", action="store_true", help="print every strain unit instead of writing the CSV")
    parser.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                      "kv_ellipsoid_lambda1.csv"))
    args = parser.parse_args()
    cas = args.ca or CAPILLARY_NUMBERS
    rows = []
    for ca in cas:
        traj = trajectory(ca, max_strain_for(ca))
        final = traj[-1]
        print(f"Ca {ca:g}: steady D {final[1]:.4f}, inclination {final[2]:.2f} deg, semi-axes "
              f"{final[3].round(4)} (strain {final[0]:.0f}); peak D {max(r[1] for r in traj):.4f}")
        for t, d, angle, axes in traj:
            if args.print and abs(t - round(t)) < 1e-9:
                print(f"  strain {t:5.1f} D {d:.4f} incl {angle:6.2f} net strain {axes[-1] - 1.0:.3f}")
            rows.append([f"{ca:g}", f"{t:.1f}", f"{d:.6f}", f"{angle:.4f}"] + [f"{x:.6f}" for x in axes])
    if not args.print:
        with open(args.out, "w", newline="") as out:
            w = csv.writer(out)
            w.writerow(["ca", "strain", "D", "inclination_deg", "a1_over_R", "a2_over_R", "a3_over_R"])
            w.writerows(rows)
        print(f"wrote {args.out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
