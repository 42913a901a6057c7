"""The result file of a job (HDF5, H5MD layout) read into numpy arrays.

Every path this module reads is in LAYOUT below, and the meaning and unit of
each observable, setup and summary entry come from the result schemas that
the workers write to (jobs/*/result_schema.json, shipped in
cellflow/schemas): a change of the file layout is a change here and in the
schemas, nowhere else in the client.

The file is treated as untrusted input: shapes are checked against each
other (positions frames x vertices x 3, tetrahedra x 4 with indices inside
the vertices) and no dataset larger than max_dataset_bytes is read.
"""

import dataclasses
import json
import os
import pathlib
from typing import Dict, Optional

import h5py
import numpy as np

# The paths of the result layout (schema_version 1 of jobs/*/result_schema.json).
LAYOUT = {
    "job_spec": "/parameters/job_spec_json",   # string: the JobSpec in the protobuf JSON mapping
    "setup": "/parameters/setup",              # scalars (shear flow)
    "summary": "/summary",                     # scalars and strings, written when the run ends
    "observables": "/observables",             # <name>/{value, step, time}: one sample per row
    "positions": "/particles/cell/position",   # {value (frames, vertices, 3) m, step, time}
    "tetrahedra": "/connectivity/cell",        # (tets, 4) vertex indices
    "cell_region": "/connectivity/cell_region",  # (tets,) 0 cytoplasm, 1 nucleus
    "fields": "/fields",                       # <name>/{step, time, ...}: vector fields on the lattice
    "field_value": "value",                    # (frames, nz, ny, nx, 3): one time series (result schema 2)
    "field_frame": "frame_{:06d}",             # (nz, ny, nx, 3): one dataset per frame (result schema 1)
    # A suspension: every cell's vertices in the one group above, cells in order.
    "cell_kind": "/parameters/setup/cell_kind",                    # (cells,) index into suspension.cells
    "cell_vertex_offset": "/parameters/setup/cell_vertex_offset",  # (cells + 1,) rows of the positions
    "cell_tet_offset": "/parameters/setup/cell_tet_offset",        # (cells + 1,) rows of the tetrahedra
}
# Attributes of a field group: node counts (nx, ny, nz), spacing and origin.
FIELD_ATTRIBUTES = {"dimensions": "dimensions", "spacing_m": "spacing_m", "origin_m": "origin_m"}

SCHEMA_DIR = pathlib.Path(__file__).resolve().parent / "schemas"
DEFAULT_MAX_DATASET_BYTES = 4 << 30


def _scene_json_names():
    """The JSON names of the JobSpec scene oneof ("compression", "shearFlow", ...):
    the spec's other fields (name, author) are not scenes."""
    from cellflow._proto import spec_pb2

    return {f.json_name for f in spec_pb2.JobSpec.DESCRIPTOR.oneofs_by_name["scene"].fields}


def load_schemas(folder: Optional[os.PathLike] = None) -> Dict[str, dict]:
    """The result schemas by scene name ("compression", "shear_flow", "fit", ...)."""
    schemas = {}
    for path in sorted(pathlib.Path(folder or SCHEMA_DIR).glob("*.json")):
        with open(path, encoding="utf-8") as f:
            schema = json.load(f)
        for scene in schema.get("scenes", []):
            schemas[scene] = schema
    return schemas


def schema_entries(schema: dict, prefix: str) -> Dict[str, dict]:
    """The schema's entries under `prefix`, by the rest of their path."""
    start = prefix.rstrip("/") + "/"
    return {e["path"][len(start):]: e for e in schema.get("entries", []) if e["path"].startswith(start)}


@dataclasses.dataclass
class Observable:
    """One time series: value[i] at step[i] and time[i] (time is the load
    parameter, the deformation, for a quasi-static curve; seconds in flow)."""

    name: str
    value: np.ndarray
    step: Optional[np.ndarray]
    time: Optional[np.ndarray]
    unit: Optional[str]
    meaning: Optional[str]

    def __len__(self):
        return len(self.value)


class ResultFileError(ValueError):
    """A result file that does not have the layout, or shapes that disagree."""


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray) and value.shape == ():
        return _text(value[()])
    return value


class Result:
    """A job's result file.

    scene: "compression", "indentation", "shear_flow", "suspension" or "fit"; spec: the job
    spec as a dict (protobuf JSON mapping); observables: {name: Observable};
    setup and summary: {name: float or str}; tetrahedra (tets, 4),
    cell_region (tets,); frame_steps and frame_times (frames,); positions(k)
    (vertices, 3) in m; field_names and field(name, k) for fluid frames.
    A suspension holds every cell's vertices in positions(k): cell_count,
    cell_kind, cell_positions(i, k) and cell_tetrahedra(i) split them.
    """

    def __init__(self, path, *, max_dataset_bytes: int = DEFAULT_MAX_DATASET_BYTES, schemas=None):
        self.path = pathlib.Path(path)
        self.max_dataset_bytes = max_dataset_bytes
        with h5py.File(self.path, "r") as f:
            if "h5md" not in f:
                raise ResultFileError(f"{self.path}: not an H5MD file (no /h5md group)")
            self.spec = json.loads(_text(self._read(f, LAYOUT["job_spec"]))) if LAYOUT["job_spec"] in f else {}
            self.scene = next((k for k in self.spec if k in _scene_json_names()), "")
            self.schema = (schemas or load_schemas()).get(_snake(self.scene), {})
            self.observables = self._read_observables(f)
            self.setup = self._read_scalars(f, LAYOUT["setup"])
            self.summary = self._read_scalars(f, LAYOUT["summary"])
            self._read_mesh(f)
            self._read_cells(f)
            self.field_names = sorted(f[LAYOUT["fields"]].keys()) if LAYOUT["fields"] in f else []

    # -- reading -------------------------------------------------------------

    def _read(self, f, path):
        dataset = f[path]
        if not isinstance(dataset, h5py.Dataset):
            raise ResultFileError(f"{self.path}: {path} is not a dataset")
        size = dataset.size * dataset.dtype.itemsize
        if size > self.max_dataset_bytes:
            raise ResultFileError(f"{self.path}: {path} holds {size} bytes, more than {self.max_dataset_bytes}")
        return dataset[()]

    def _read_observables(self, f):
        described = schema_entries(self.schema, LAYOUT["observables"])
        out = {}
        group = f.get(LAYOUT["observables"])
        for name in sorted(group.keys()) if group is not None else []:
            element = group[name]
            if not isinstance(element, h5py.Group) or "value" not in element:
                continue
            base = f"{LAYOUT['observables']}/{name}"
            value = np.asarray(self._read(f, base + "/value"))
            step = np.asarray(self._read(f, base + "/step")) if "step" in element else None
            time = np.asarray(self._read(f, base + "/time")) if "time" in element else None
            for label, series in (("step", step), ("time", time)):
                if series is not None and len(series) != len(value):
                    raise ResultFileError(f"{self.path}: {base}/{label} has {len(series)} rows, value {len(value)}")
            entry = described.get(name + "/value", {})
            unit = _text(element["value"].attrs.get("unit", entry.get("unit")))
            out[name] = Observable(name, value, step, time, unit, entry.get("meaning"))
        return out

    def _read_scalars(self, f, prefix):
        out = {}
        group = f.get(prefix)
        for name in sorted(group.keys()) if isinstance(group, h5py.Group) else []:
            item = group[name]
            if isinstance(item, h5py.Dataset) and item.shape in ((), (1,)):
                value = _text(self._read(f, f"{prefix}/{name}"))
                if isinstance(value, np.ndarray):
                    value = value.reshape(())[()]
                if isinstance(value, np.integer):
                    value = int(value)
                elif isinstance(value, np.floating):
                    value = float(value)
                out[name] = value
        return out

    def _read_mesh(self, f):
        self.tetrahedra = np.zeros((0, 4), dtype=np.int64)
        self.cell_region = np.zeros((0,), dtype=np.uint8)
        self.frame_steps = np.zeros((0,), dtype=np.int64)
        self.frame_times = np.zeros((0,), dtype=np.float64)
        self._positions = np.zeros((0, 0, 3))
        base = LAYOUT["positions"]
        if base + "/value" in f:
            self._positions = np.asarray(self._read(f, base + "/value"), dtype=np.float64)
            if self._positions.ndim != 3 or self._positions.shape[2] != 3:
                raise ResultFileError(f"{self.path}: {base}/value has shape {self._positions.shape}, not (frames, vertices, 3)")
            self.frame_steps = np.asarray(self._read(f, base + "/step"), dtype=np.int64)
            self.frame_times = np.asarray(self._read(f, base + "/time"), dtype=np.float64)
            frames = self._positions.shape[0]
            if self.frame_steps.shape != (frames,) or self.frame_times.shape != (frames,):
                raise ResultFileError(f"{self.path}: {base} step/time do not have one row per frame ({frames})")
        if LAYOUT["tetrahedra"] in f:
            tets = np.asarray(self._read(f, LAYOUT["tetrahedra"]), dtype=np.int64)
            if tets.ndim != 2 or tets.shape[1] != 4:
                raise ResultFileError(f"{self.path}: {LAYOUT['tetrahedra']} has shape {tets.shape}, not (tets, 4)")
            vertices = self._positions.shape[1]
            if tets.size and (tets.min() < 0 or tets.max() >= vertices):
                raise ResultFileError(f"{self.path}: tetrahedra name vertices outside [0, {vertices})")
            self.tetrahedra = tets
        if LAYOUT["cell_region"] in f:
            region = np.asarray(self._read(f, LAYOUT["cell_region"]))
            if region.shape != (len(self.tetrahedra),):
                raise ResultFileError(f"{self.path}: cell_region has {region.shape}, not one value per tetrahedron")
            self.cell_region = region

    def _read_cells(self, f):
        """A suspension's cells: which rows of the positions and tetrahedra are whose.
        Without them (a single cell) the whole mesh is cell 0 of kind 0."""
        vertices, tets = self._positions.shape[1], len(self.tetrahedra)
        self.cell_kind = np.zeros((1,), dtype=np.int64)
        self.cell_vertex_offset = np.array([0, vertices], dtype=np.int64)
        self.cell_tet_offset = np.array([0, tets], dtype=np.int64)
        if LAYOUT["cell_kind"] not in f:
            return
        kind = np.asarray(self._read(f, LAYOUT["cell_kind"]), dtype=np.int64)
        vertex_offset = np.asarray(self._read(f, LAYOUT["cell_vertex_offset"]), dtype=np.int64)
        tet_offset = np.asarray(self._read(f, LAYOUT["cell_tet_offset"]), dtype=np.int64)
        cells = len(kind)
        for name, offset, total in (("cell_vertex_offset", vertex_offset, vertices), ("cell_tet_offset", tet_offset, tets)):
            if offset.shape != (cells + 1,) or offset[0] != 0 or np.any(np.diff(offset) < 0) or offset[-1] != total:
                raise ResultFileError(f"{self.path}: {name} is not {cells + 1} rising offsets from 0 to {total}")
        if cells and kind.min() < 0:
            raise ResultFileError(f"{self.path}: cell_kind below 0")
        self.cell_kind, self.cell_vertex_offset, self.cell_tet_offset = kind, vertex_offset, tet_offset

    # -- access --------------------------------------------------------------

    @property
    def cell_count(self) -> int:
        """Cells in the result (1 for a single-cell scene)."""
        return len(self.cell_kind)

    def cell_positions(self, cell: int, frame: int = -1) -> np.ndarray:
        """The vertex positions (vertices of the cell, 3) in m of one cell at frame k."""
        if not 0 <= cell < self.cell_count:
            raise IndexError(f"cell {cell} of {self.cell_count}")
        return self.positions(frame)[self.cell_vertex_offset[cell]:self.cell_vertex_offset[cell + 1]]

    def cell_tetrahedra(self, cell: int) -> np.ndarray:
        """One cell's tetrahedra (tets, 4) with vertex indices into cell_positions(cell)."""
        if not 0 <= cell < self.cell_count:
            raise IndexError(f"cell {cell} of {self.cell_count}")
        rows = self.tetrahedra[self.cell_tet_offset[cell]:self.cell_tet_offset[cell + 1]]
        return rows - self.cell_vertex_offset[cell]

    @property
    def frame_count(self) -> int:
        return self._positions.shape[0]

    def positions(self, frame: int = -1) -> np.ndarray:
        """Vertex positions (vertices, 3) in m of frame k (negative: from the end)."""
        if not -self.frame_count <= frame < self.frame_count:
            raise IndexError(f"frame {frame} of {self.frame_count}")
        return self._positions[frame]

    def curves(self) -> Dict[str, np.ndarray]:
        """Every observable's values by name (the columns of `cellflow result --csv`)."""
        return {name: o.value for name, o in self.observables.items()}

    def __getitem__(self, name) -> np.ndarray:
        return self.observables[name].value

    def field(self, name: str, frame: int = -1):
        """Frame k of a vector field (e.g. "fluid_velocity"): (values
        (nz, ny, nx, 3) in the field's unit, time, attributes {dimensions,
        spacing_m, origin_m}). Read from the file on each call."""
        base = f"{LAYOUT['fields']}/{name}"
        with h5py.File(self.path, "r") as f:
            if base not in f:
                raise KeyError(f"no field {name} in {self.path}")
            times = np.asarray(self._read(f, base + "/time"))
            count = len(times)
            if not -count <= frame < count:
                raise IndexError(f"frame {frame} of {count}")
            frame %= count
            group = f[base]
            series = group.get(LAYOUT["field_value"])
            if isinstance(series, h5py.Dataset):
                if series.ndim != 5 or series.shape[0] != count:
                    raise ResultFileError(f"{self.path}: {base}/value has shape {series.shape}, not (frames, nz, ny, nx, 3)")
                size = series.size // max(count, 1) * series.dtype.itemsize
                if size > self.max_dataset_bytes:
                    raise ResultFileError(f"{self.path}: a frame of {base} holds {size} bytes, more than {self.max_dataset_bytes}")
                values = np.asarray(series[frame])
            else:
                values = np.asarray(self._read(f, f"{base}/{LAYOUT['field_frame'].format(frame)}"))
            attrs = {key: np.asarray(group.attrs[attr]) for key, attr in FIELD_ATTRIBUTES.items() if attr in group.attrs}
        return values, float(times[frame]), attrs

    def to_dataframe(self):
        """The observables as a pandas DataFrame (one row per sample; a
        vector observable gives columns name_0, name_1, ...). Needs pandas."""
        try:
            import pandas
        except ImportError as error:
            raise ImportError("Result.to_dataframe needs pandas (Debian: python3-pandas)") from error
        columns = {}
        for name, o in self.observables.items():
            if o.value.ndim == 1:
                columns[name] = o.value
            else:
                for i in range(o.value.reshape(len(o.value), -1).shape[1]):
                    columns[f"{name}_{i}"] = o.value.reshape(len(o.value), -1)[:, i]
        lengths = {len(v) for v in columns.values()}
        if len(lengths) > 1:
            raise ResultFileError(f"{self.path}: observables of different lengths {sorted(lengths)} (a fit: use curves())")
        return pandas.DataFrame(columns)

    def to_meshio(self, frame: int = -1):
        """Frame k of the cell as a meshio.Mesh (tetrahedra, cell_region as cell data)."""
        from cellflow.mesh import frame_mesh

        return frame_mesh(self, frame)

    def write_mesh(self, path, frame: int = -1, file_format: Optional[str] = None):
        """Writes frame k of the cell in any format meshio writes (.vtu, .stl, .msh, ...)."""
        from cellflow.mesh import write_frame

        return write_frame(self, path, frame, file_format)

    def __repr__(self):
        return (f"Result({str(self.path)!r}, scene={self.scene!r}, observables={list(self.observables)}, "
                f"frames={self.frame_count})")


def _snake(name: str) -> str:
    """shearFlow -> shear_flow (the JSON mapping names the scene in camelCase)."""
    return "".join("_" + c.lower() if c.isupper() else c for c in name)


def read_result(path, **options) -> Result:
    """Reads a job's result file (what `cellflow result JOB -o FILE` and Client.download write)."""
    return Result(path, **options)
