#!/usr/bin/python3
"""Result files open in the tools users have: h5py checks the H5MD 1.1 rules
and MDAnalysis's H5MD reader reads frames.

Runs cellflow-run --result on a small compression spec and a small shear-flow
spec (the real recorders, as a worker runs them), then checks each file:
required groups and attributes, version {1, 1}, the units module and its unit
syntax, integer counts, the object reference of connectivity/cell, the box
boundary and edges, one time series per element, no duplicate positions, and
the XDMF sidecar's HyperSlab items. The MDAnalysis part is skipped only when
MDAnalysis cannot be imported.

usage: h5md_portability_test.py CELLFLOW_RUN WORK_DIR
"""
import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

import h5py
import numpy as np

FAILURES = []


def check(condition, what):
    if not condition:
        FAILURES.append(what)
        print("FAIL: " + what)


def text(value):
    return value.decode("ascii") if isinstance(value, bytes) else str(value)


# H5MD units module: unit factors separated by one space, at most one numeric
# factor (first), each symbol once, optionally followed by a non-zero signed
# integer power ("m", "m s-1", "kg m-3", "m+3").
UNIT_FACTOR = re.compile(r"^(?P<symbol>[A-Za-z]+)(?P<power>[+-][1-9][0-9]*)?$")
NUMBER = re.compile(r"^[0-9]+(\.[0-9]+)?$")
SI_SYMBOLS = {"m", "s", "kg", "N", "J", "Pa", "rad", "K", "W"}


def valid_unit(unit):
    factors = unit.split(" ")
    symbols = []
    for i, factor in enumerate(factors):
        if NUMBER.match(factor):
            if i != 0:
                return False
            continue
        match = UNIT_FACTOR.match(factor)
        if not match or match.group("symbol") not in SI_SYMBOLS:
            return False
        symbols.append(match.group("symbol"))
    return len(symbols) == len(set(symbols)) and len(symbols) > 0


def run(cellflow_run, spec, h5_path):
    spec_path = h5_path[:-3] + ".json"
    with open(spec_path, "w") as out:
        json.dump(spec, out)
    env = dict(os.environ, OMP_NUM_THREADS="1", USER="h5md-test-user")
    done = subprocess.run([cellflow_run, spec_path, "--result", h5_path, "--quiet"], env=env,
                          capture_output=True, text=True, timeout=240)
    if done.returncode != 0:
        sys.exit("cellflow-run failed (%d): %s" % (done.returncode, done.stderr))


def check_units(f):
    def visit(name, obj):
        if "unit" in obj.attrs:
            attr_type = obj.attrs.get_id("unit").dtype
            check(attr_type.kind == "S", "%s: unit is a fixed-length ASCII string (got %s)" % (name, attr_type))
            unit = text(obj.attrs["unit"])
            check(valid_unit(unit), "%s: unit %r in the H5MD units syntax" % (name, unit))
        if isinstance(obj, h5py.Group) and {"step", "time", "value"} <= set(obj.keys()):
            # One H5MD time-dependent element: integer step, float time, the same number of records.
            check(obj["step"].dtype.kind == "i", name + "/step is an integer")
            check(obj["time"].dtype.kind == "f", name + "/time is a float")
            n = obj["step"].shape[0]
            check(obj["time"].shape == (n,) and obj["value"].shape[0] == n, name + ": step, time, value agree")
            check("unit" not in obj["step"].attrs, name + "/step has no unit")

    f.visititems(visit)


def check_common(f, h5_path, frames_expected):
    check(list(f["h5md"].attrs["version"]) == [1, 1], "/h5md version {1, 1}")
    check(text(f["h5md/author"].attrs["name"]) == "h5md-test-user", "/h5md/author name from $USER")
    check(text(f["h5md/creator"].attrs["name"]) == "cellflow", "/h5md/creator name")
    check("(git " in text(f["h5md/creator"].attrs["version"]), "/h5md/creator version names the commit")
    units = f["h5md/modules/units"]
    check(list(units.attrs["version"]) == [1, 0], "units module version {1, 0}")
    check(text(units.attrs["system"]) == "SI", "units module system SI")
    check("xdmf" not in f, "positions are stored once (no /xdmf copies)")
    position = f["particles/cell/position"]
    value = position["value"]
    check(value.ndim == 3 and value.shape[2] == 3, "position value [frames][N][3]")
    check(value.shape[0] == frames_expected, "%d position frames (got %d)" % (frames_expected, value.shape[0]))
    check(text(value.attrs["unit"]) == "m", "positions in m")
    connectivity = f["connectivity/cell"]
    reference = connectivity.attrs["particles_group"]
    check(isinstance(reference, h5py.Reference), "connectivity/cell@particles_group is an object reference")
    check(f[reference] == f["particles/cell"], "particles_group resolves to /particles/cell")
    check(connectivity.dtype.kind == "i" and connectivity.shape[1] == 4, "tetrahedra [M][4] integers")
    check(int(np.max(connectivity[()])) < value.shape[1], "tetrahedra index the particles")
    box = f["particles/cell/box"]
    check(int(box.attrs["dimension"]) == 3, "box dimension 3")
    check_units(f)
    return box


def check_xdmf(h5_path, names):
    xdmf_path = h5_path[:-3] + ".xdmf"
    tree = ElementTree.parse(xdmf_path)
    base = os.path.basename(h5_path)
    seen = set()
    with h5py.File(h5_path, "r") as f:
        for item in tree.iter("DataItem"):
            if item.get("Format") != "HDF":
                continue
            file_part, dataset = item.text.strip().split(":")
            check(file_part == "./" + base, "XDMF names the HDF5 file as ./%s (got %s)" % (base, file_part))
            check(dataset in f, "XDMF dataset %s exists" % dataset)
            dims = [int(d) for d in item.get("Dimensions").split()]
            check(list(f[dataset].shape) == dims, "XDMF dimensions of %s" % dataset)
        for slab in tree.iter("DataItem"):
            if slab.get("ItemType") != "HyperSlab":
                continue
            selection, source = list(slab)
            rank = len(source.get("Dimensions").split())
            numbers = [int(v) for v in selection.text.split()]
            start, stride, count = numbers[:rank], numbers[rank:2 * rank], numbers[2 * rank:]
            shape = f[source.text.strip().split(":")[1]].shape
            check(all(s + (c - 1) * t < d for s, t, c, d in zip(start, stride, count, shape)),
                  "HyperSlab inside %s" % source.text)
    for grid in tree.iter("Grid"):
        if grid.get("GridType") == "Uniform":
            seen.add(grid.get("Name"))
    check(seen == set(names), "XDMF blocks named %s (got %s)" % (sorted(names), sorted(seen)))


def check_compression(path):
    with h5py.File(path, "r") as f:
        box = check_common(f, path, frames_expected=4)
        check([text(b) for b in box.attrs["boundary"]] == ["none"] * 3, "quasi-static boundary none x3")
        check("edges" not in box, "quasi-static box without edges")
        for name in ("newton_iterations", "cg_iterations", "step_splits"):
            check(f["observables/%s/value" % name].dtype == np.int64, name + " is int64")
        time = f["observables/force_n/time"]
        check("unit" not in time.attrs, "load parameter without unit")
        check("deformation" in text(time.attrs["meaning"]), "load parameter named in attribute meaning")
        check(text(f["observables/force_n/value"].attrs["unit"]) == "N", "force in N")
        check("unit" not in f["observables/deformation/value"].attrs, "deformation dimensionless")
    check_xdmf(path, {"cell"})


def check_flow(path):
    with h5py.File(path, "r") as f:
        box = check_common(f, path, frames_expected=f["particles/cell/position/step"].shape[0])
        check([text(b) for b in box.attrs["boundary"]] == ["periodic", "none", "periodic"],
              "flow box periodic in x and z, walls in y")
        edges = box["edges/value"]
        setup = f["parameters/setup"]
        for axis in ("nx", "ny", "nz"):
            check(setup[axis].dtype.kind == "i", "setup/%s is an integer" % axis)
        check(f["summary/time_steps"].dtype.kind == "i", "summary/time_steps is an integer")
        dx = float(setup["lattice_spacing_m"][()])
        lengths = np.array([int(setup[a][()]) for a in ("nx", "ny", "nz")]) * dx
        check(edges.shape == (f["particles/cell/position/value"].shape[0], 3, 3), "edges [frames][3][3]")
        check(np.allclose(edges[0], np.diag(lengths), rtol=1e-12), "edges: the box lengths n dx")
        check(text(edges.attrs["unit"]) == "m", "edges in m")
        check(text(f["particles/cell/position/time"].attrs["unit"]) == "s", "flow time in s")
        field = f["fields/fluid_velocity"]
        value = field["value"]
        nx, ny, nz = (int(v) for v in field.attrs["dimensions"])
        check(value.shape == (field["step"].shape[0], nz, ny, nx, 3) and value.dtype == np.float32,
              "fluid frames one series [frames][nz][ny][nx][3] float32")
        check(text(value.attrs["unit"]) == "m s-1", "fluid velocity in m s-1")
        check(not any(k.startswith("frame_") for k in field.keys()), "no per-frame field datasets")
    check_xdmf(path, {"cell", "fluid_velocity"})


def check_mdanalysis(path, frames_to_read):
    try:
        from MDAnalysis.coordinates.H5MD import H5MDReader
    except ImportError as error:
        print("SKIP MDAnalysis part: MDAnalysis not importable (%s)" % error)
        return
    try:
        reader = H5MDReader(path, convert_units=False)
    except RuntimeError as error:
        # MDAnalysis 2.4 knows lengths in A, nm, pm, fm only, and matches
        # units as Python str, while H5MD mandates fixed-length (bytes)
        # strings: SI metres need the two table entries a user adds.
        check("not recognized" in str(error), "MDAnalysis refuses only the unit (%s)" % error)

        class SIReader(H5MDReader):
            _unit_translation = {kind: {**table, **{k.encode(): v for k, v in table.items()}}
                                 for kind, table in H5MDReader._unit_translation.items()}
            _unit_translation["length"].update({"m": "m", b"m": "m"})

        reader = SIReader(path, convert_units=False)
    with h5py.File(path, "r") as f:
        positions = f["particles/cell/position/value"]
        check(reader.n_atoms == positions.shape[1], "MDAnalysis: particle count")
        check(reader.n_frames == positions.shape[0], "MDAnalysis: frame count")
        edges = f["particles/cell/box/edges/value"][0] if "edges" in f["particles/cell/box"] else None
        for frame in range(frames_to_read):
            ts = reader[frame]
            check(np.allclose(ts.positions, positions[frame], rtol=1e-6, atol=0),
                  "MDAnalysis frame %d positions equal h5py's" % frame)
            check(ts.time == f["particles/cell/position/time"][frame], "MDAnalysis frame %d time" % frame)
            if edges is not None:
                check(np.allclose(ts.dimensions[:3], np.diag(edges), rtol=1e-6) and
                      np.allclose(ts.dimensions[3:], 90.0), "MDAnalysis box of frame %d" % frame)
            else:
                check(ts.dimensions is None, "MDAnalysis: no box for the quasi-static cell")
    reader.close()
    print("MDAnalysis read %d frame(s) of %s" % (frames_to_read, os.path.basename(path)))


def main():
    cellflow_run, work = sys.argv[1], sys.argv[2]
    os.makedirs(work, exist_ok=True)
    cell = {"radiusM": 4e-6, "material": {"youngsModulusPa": 50}, "targetVertexCount": 300}
    compression = os.path.join(work, "compression.h5")
    run(cellflow_run, {"compression": {"cell": cell, "maxDeformation": 0.1, "loadPoints": 3}}, compression)
    flow = os.path.join(work, "flow.h5")
    run(cellflow_run, {"shearFlow": {"cell": cell, "capillaryNumber": 0.2, "numerics": {
        "cellsPerRadius": 3, "boxXRadii": 5, "boxYRadii": 6, "boxZRadii": 4, "maxStrain": 1.0,
        "fluidSnapshots": True}}}, flow)
    check_compression(compression)
    check_flow(flow)
    # MDAnalysis takes observable record k for position frame k: the
    # compression file has the reference frame beyond its 3 load points, so
    # frames 0-2 are read; every frame of the flow file.
    check_mdanalysis(compression, frames_to_read=3)
    with h5py.File(flow, "r") as f:
        flow_frames = f["particles/cell/position/value"].shape[0]
    check_mdanalysis(flow, frames_to_read=flow_frames)
    if FAILURES:
        sys.exit("%d check(s) failed" % len(FAILURES))
    print("all H5MD checks passed")


if __name__ == "__main__":
    main()
