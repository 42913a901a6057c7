"""The package without a server: typed events against the protos, spec
parsing, token files, the result reader on files written here (the layout
of jobs/*/result_schema.json, and hostile ones), surface extraction."""

import dataclasses
import json
import os
import pathlib
import tempfile
import unittest

import grpc
import h5py
import numpy as np

import harness
import cellflow
from cellflow import events, results
from cellflow.client import _read_secret
from cellflow.mesh import surface_triangles
from cellflow.v1 import service_pb2, spec_pb2


class Events(unittest.TestCase):
    def test_each_event_class_has_the_fields_of_its_proto_message(self):
        # A field added to a proto message without the dataclass (or the other way) fails here.
        kinds = service_pb2.JobEvent.DESCRIPTOR.oneofs_by_name["kind"].fields
        self.assertEqual({f.name for f in kinds}, set(events.EVENT_CLASSES))
        base = {f.name for f in dataclasses.fields(cellflow.Event)}
        for field in kinds:
            cls = events.EVENT_CLASSES[field.name]
            own = [f.name for f in dataclasses.fields(cls) if f.name not in base]
            self.assertEqual(own, [f.name for f in field.message_type.fields], cls.__name__)

    def test_conversion_of_a_force_sample_and_a_state_change(self):
        e = service_pb2.JobEvent(job_id="job-1", sequence=7, attempt=2)
        e.time.FromSeconds(1_700_000_000)
        e.force_sample.index = 3
        e.force_sample.force_n = 1.5e-9
        e.force_sample.semi_axes_m.extend([1e-6, 2e-6, 3e-6])
        sample = cellflow.event_from_proto(e)
        self.assertIsInstance(sample, cellflow.ForceSample)
        self.assertEqual((sample.job_id, sample.sequence, sample.attempt, sample.index), ("job-1", 7, 2, 3))
        self.assertEqual(sample.force_n, 1.5e-9)
        self.assertEqual(sample.semi_axes_m, (1e-6, 2e-6, 3e-6))
        self.assertEqual(sample.time.timestamp(), 1_700_000_000)
        change = service_pb2.JobEvent(sequence=8)
        change.state_change.state = service_pb2.Job.FAILED
        change.state_change.reason = "numerical failure"
        converted = cellflow.event_from_proto(change)
        self.assertEqual((converted.state, converted.reason, converted.terminal), ("FAILED", "numerical failure", True))
        child = service_pb2.JobEvent(sequence=9)
        child.child_update.child_job_id = "job-4"
        child.child_update.state = service_pb2.Job.SUCCEEDED
        self.assertEqual(cellflow.event_from_proto(child).state, "SUCCEEDED")
        self.assertIs(type(cellflow.event_from_proto(service_pb2.JobEvent(sequence=1))), cellflow.Event)
        suspension = service_pb2.JobEvent(sequence=10)
        s = suspension.suspension_sample
        s.index, s.cell_count, s.mean_taylor_deformation = 4, 300, 0.125
        for i in range(2):
            cell = s.cells.add(cell=i, taylor_deformation=0.1 * i)
            cell.centroid_m.extend([1e-6 * i, 2e-6, 3e-6])
        converted = cellflow.event_from_proto(suspension)
        self.assertIsInstance(converted, cellflow.SuspensionSample)
        self.assertEqual((converted.index, converted.cell_count, converted.mean_taylor_deformation), (4, 300, 0.125))
        self.assertEqual(len(converted.cells), 2)
        self.assertIsInstance(converted.cells[1], cellflow.SuspendedCellState)
        self.assertEqual(converted.cells[1].centroid_m, (1e-6, 2e-6, 3e-6))
        self.assertEqual(converted.cells[1].taylor_deformation, 0.1)


class Specs(unittest.TestCase):
    def test_dict_json_text_file_and_message(self):
        spec = harness.small_compression()
        parsed = cellflow.parse_spec(spec)
        self.assertEqual(parsed.compression.cell.target_vertex_count, 300)
        self.assertEqual(cellflow.parse_spec(json.dumps(spec)), parsed)
        self.assertIs(cellflow.parse_spec(parsed), parsed)
        example = cellflow.parse_spec(harness.CHECKOUT / "examples" / "shear_flow.json")
        self.assertEqual(example.shear_flow.capillary_number, 0.2)
        # The proto's own field names are accepted too.
        self.assertEqual(cellflow.parse_spec({"compression": {"max_deformation": 0.2}}).compression.max_deformation, 0.2)

    def test_refusals_name_the_problem(self):
        with self.assertRaisesRegex(cellflow.CellflowError, "maxDeformatio"):
            cellflow.parse_spec({"compression": {"maxDeformatio": 0.1}})
        with self.assertRaisesRegex(cellflow.CellflowError, "expected a dict"):
            cellflow.parse_spec(42)

    def test_study_request(self):
        # What submit_study sends, without a server: values as JSON text.
        client = cellflow.Client("127.0.0.1:1", token="")
        sent = {}
        client.submit = lambda spec, request_id=None: sent.setdefault("spec", spec)
        client.submit_study(harness.small_shear_flow(), {"shearFlow.capillaryNumber": [0.05, 0.1],
                                                         "shearFlow.numerics.precision": ["FLOAT"]},
                            combination="zip", name="sweep")
        study = sent["spec"].study
        self.assertEqual(sent["spec"].name, "sweep")
        self.assertEqual(study.combination, spec_pb2.StudySpec.ZIP)
        self.assertEqual([(a.path, list(a.values)) for a in study.axes],
                         [("shearFlow.capillaryNumber", ["0.05", "0.1"]), ("shearFlow.numerics.precision", ['"FLOAT"'])])
        self.assertEqual(study.base.shear_flow.capillary_number, 0.2)
        with self.assertRaises(cellflow.CellflowError):
            client.submit_study(harness.small_shear_flow(), {"shearFlow.capillaryNumber": 0.05})
        with self.assertRaises(cellflow.CellflowError):
            client.submit_study(harness.small_shear_flow(), {"shearFlow.capillaryNumber": [0.05]}, combination="star")


class Unavailable(grpc.RpcError):
    def code(self):
        return grpc.StatusCode.UNAVAILABLE


class FakeWatchStub:
    """WatchJob that breaks with UNAVAILABLE after the events of its first
    script, then serves the next script; records each request."""

    def __init__(self, scripts):
        self.scripts = list(scripts)
        self.requests = []

    def WatchJob(self, request, metadata=None):
        self.requests.append(request)
        events, breaks = self.scripts.pop(0)
        stub = self

        class Stream:
            def __iter__(self):
                for sequence in events:
                    if sequence > request.after_sequence:
                        e = service_pb2.JobEvent(job_id=request.job_id, sequence=sequence)
                        if sequence == 4:
                            e.state_change.state = service_pb2.Job.SUCCEEDED
                        else:
                            e.progress.fraction_done = sequence / 4
                        yield e
                if breaks:
                    raise Unavailable()

            def cancel(self):
                stub.cancelled = True

        return Stream()


class Watch(unittest.TestCase):
    def test_a_broken_stream_resumes_after_the_last_sequence(self):
        client = cellflow.Client("127.0.0.1:1", token="")
        # The server replays from the start, breaks after 2; the second stream is asked for > 2.
        client.stub = FakeWatchStub([([1, 2], True), ([1, 2, 3, 4], False)])
        seen = list(client.watch("job-9"))
        self.assertEqual([e.sequence for e in seen], [1, 2, 3, 4])
        self.assertEqual([r.after_sequence for r in client.stub.requests], [0, 2])
        self.assertEqual(seen[-1].state, "SUCCEEDED")

    def test_an_unreachable_server_ends_the_watch_after_reconnect_s(self):
        client = cellflow.Client("127.0.0.1:1", token="", reconnect_s=0.0)
        client.stub = FakeWatchStub([([1], True), ([], True)])
        with self.assertRaises(cellflow.CellflowError) as caught:
            list(client.watch("job-9"))
        self.assertEqual(caught.exception.code, grpc.StatusCode.UNAVAILABLE)


class Tokens(unittest.TestCase):
    def test_a_token_file_others_can_read_is_refused(self):
        with tempfile.TemporaryDirectory() as folder:
            path = pathlib.Path(folder, "token")
            path.write_text("secret-token\n")
            os.chmod(path, 0o644)
            with self.assertRaisesRegex(cellflow.CellflowError, "chmod 600"):
                _read_secret(path)
            os.chmod(path, 0o600)
            self.assertEqual(_read_secret(path), "secret-token")
            self.assertEqual(cellflow.Client("127.0.0.1:1", token_file=str(path))._token, "secret-token")


def write_compression_file(path, frames=3, vertices=4, tets=None, observable_rows=2):
    """A small file in the layout the reader expects (results.LAYOUT)."""
    tets = np.array([[0, 1, 2, 3]]) if tets is None else tets
    with h5py.File(path, "w") as f:
        f.create_group("h5md").attrs["version"] = [1, 1]
        f[results.LAYOUT["job_spec"]] = json.dumps(harness.small_compression())
        base = results.LAYOUT["positions"]
        f[base + "/value"] = np.arange(frames * vertices * 3, dtype=float).reshape(frames, vertices, 3)
        f[base + "/step"] = np.arange(frames)
        f[base + "/time"] = np.linspace(0, 0.1, frames)
        f[results.LAYOUT["tetrahedra"]] = tets.astype(np.int32)
        f[results.LAYOUT["cell_region"]] = np.zeros(len(tets), dtype=np.uint8)
        for name in ("force_n", "deformation"):
            group = results.LAYOUT["observables"] + "/" + name
            f[group + "/value"] = np.linspace(1, 2, observable_rows)
            f[group + "/step"] = np.arange(1, 3)
            f[group + "/time"] = np.linspace(0.05, 0.1, 2)
        f[results.LAYOUT["summary"] + "/stop"] = "done"


class Reader(unittest.TestCase):
    def setUp(self):
        self.folder = tempfile.TemporaryDirectory()
        self.path = pathlib.Path(self.folder.name, "r.h5")

    def tearDown(self):
        self.folder.cleanup()

    def test_every_layout_path_is_in_the_result_schemas(self):
        # The reader and the files the workers write follow the same schemas.
        schemas = results.load_schemas()  # the copies shipped in the package
        for path in harness.CHECKOUT.glob("jobs/*/result_schema.json"):
            source = json.loads(path.read_text())
            self.assertEqual(schemas[source["scenes"][0]], source, path)
        self.assertTrue({"compression", "indentation", "shear_flow", "fit"} <= set(schemas))
        for scene in ("compression", "shear_flow"):
            paths = {e["path"] for e in schemas[scene]["entries"]}
            for key in ("job_spec", "tetrahedra", "cell_region"):
                self.assertIn(results.LAYOUT[key], paths, (scene, key))
            for suffix in ("value", "step", "time"):
                self.assertIn(results.LAYOUT["positions"] + "/" + suffix, paths, scene)
            self.assertTrue(any(p.startswith(results.LAYOUT["observables"] + "/") for p in paths))
            self.assertTrue(any(p.startswith(results.LAYOUT["summary"] + "/") for p in paths) or scene != "shear_flow")
        self.assertTrue(any(e["path"].startswith(results.LAYOUT["setup"] + "/") for e in schemas["shear_flow"]["entries"]))
        suspension = {e["path"] for e in schemas["suspension"]["entries"]}
        for key in ("job_spec", "tetrahedra", "cell_region", "cell_kind", "cell_vertex_offset", "cell_tet_offset"):
            self.assertIn(results.LAYOUT[key], suspension, key)
        self.assertIn(results.LAYOUT["positions"] + "/value", suspension)

    def test_a_suspension_splits_into_its_cells(self):
        # Two cells of kind 0 (one tetrahedron, 4 vertices) and one of kind 1 (2 tetrahedra, 5 vertices).
        tets = np.array([[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11], [8, 9, 10, 12]])
        write_compression_file(self.path, vertices=13, tets=tets)
        with h5py.File(self.path, "a") as f:
            f[results.LAYOUT["cell_kind"]] = np.array([0, 0, 1], dtype=np.int64)
            f[results.LAYOUT["cell_vertex_offset"]] = np.array([0, 4, 8, 13], dtype=np.int64)
            f[results.LAYOUT["cell_tet_offset"]] = np.array([0, 1, 2, 4], dtype=np.int64)
        r = cellflow.read_result(self.path)
        self.assertEqual(r.cell_count, 3)
        self.assertEqual(r.cell_kind.tolist(), [0, 0, 1])
        np.testing.assert_array_equal(r.cell_positions(1, 0), r.positions(0)[4:8])
        self.assertEqual(r.cell_tetrahedra(2).tolist(), [[0, 1, 2, 3], [0, 1, 2, 4]])
        with self.assertRaises(IndexError):
            r.cell_positions(3)
        with h5py.File(self.path, "a") as f:
            del f[results.LAYOUT["cell_vertex_offset"]]
            f[results.LAYOUT["cell_vertex_offset"]] = np.array([0, 4, 14, 13], dtype=np.int64)
        with self.assertRaisesRegex(results.ResultFileError, "offsets"):
            cellflow.read_result(self.path)
        write_compression_file(self.path)  # a single cell: one cell of kind 0
        r = cellflow.read_result(self.path)
        self.assertEqual(r.cell_count, 1)
        self.assertEqual(r.cell_tetrahedra(0).tolist(), r.tetrahedra.tolist())

    def test_reads_arrays_units_from_the_schema_and_summary(self):
        write_compression_file(self.path)
        r = cellflow.read_result(self.path)
        self.assertEqual(r.scene, "compression")
        self.assertEqual(r.frame_count, 3)
        np.testing.assert_array_equal(r.positions(1), np.arange(12, 24, dtype=float).reshape(4, 3))
        np.testing.assert_array_equal(r["force_n"], [1.0, 2.0])
        self.assertEqual(r.observables["force_n"].unit, "N")  # no attribute in the file: the schema's
        self.assertIn("reaction", r.observables["force_n"].meaning)
        self.assertEqual(r.summary["stop"], "done")
        self.assertEqual(r.tetrahedra.tolist(), [[0, 1, 2, 3]])
        with self.assertRaises(IndexError):
            r.positions(3)

    def test_fluid_frames_as_one_series_or_one_dataset_each(self):
        velocity = np.arange(2 * 2 * 3 * 4 * 3, dtype=np.float32).reshape(2, 2, 3, 4, 3)  # frames, nz, ny, nx, 3
        for one_series in (True, False):
            write_compression_file(self.path)
            with h5py.File(self.path, "a") as f:
                base = results.LAYOUT["fields"] + "/fluid_velocity"
                f[base + "/step"] = [0, 10]
                f[base + "/time"] = [0.0, 1e-3]
                f[base].attrs["dimensions"] = [4, 3, 2]
                if one_series:
                    f[base + "/" + results.LAYOUT["field_value"]] = velocity
                else:
                    for k in range(2):
                        f[base + "/" + results.LAYOUT["field_frame"].format(k)] = velocity[k]
            r = cellflow.read_result(self.path)
            self.assertEqual(r.field_names, ["fluid_velocity"])
            values, time, grid = r.field("fluid_velocity", -1)
            np.testing.assert_array_equal(values, velocity[1])
            self.assertEqual(time, 1e-3)
            self.assertEqual(grid["dimensions"].tolist(), [4, 3, 2])
            with self.assertRaises(IndexError):
                r.field("fluid_velocity", 2)

    def test_hostile_files_are_refused(self):
        write_compression_file(self.path, tets=np.array([[0, 1, 2, 9]]))
        with self.assertRaisesRegex(results.ResultFileError, "outside"):
            cellflow.read_result(self.path)
        write_compression_file(self.path, observable_rows=3)
        with self.assertRaisesRegex(results.ResultFileError, "rows"):
            cellflow.read_result(self.path)
        write_compression_file(self.path)
        with self.assertRaisesRegex(results.ResultFileError, "bytes"):
            cellflow.read_result(self.path, max_dataset_bytes=64)
        with h5py.File(self.path, "w") as f:
            f["x"] = 1
        with self.assertRaisesRegex(results.ResultFileError, "H5MD"):
            cellflow.read_result(self.path)


class Surface(unittest.TestCase):
    def test_two_tetrahedra_share_one_face_and_the_rest_point_outward(self):
        points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
        tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
        # The second tetrahedron positively oriented.
        a, b, c, d = points[tets[1]]
        if np.dot(np.cross(b - a, c - a), d - a) < 0:
            tets[1] = tets[1][[0, 2, 1, 3]]
        faces = surface_triangles(tets)
        self.assertEqual(len(faces), 6)
        centre = points.mean(axis=0)
        for face in faces:
            p, q, r = points[face]
            self.assertGreater(np.dot(np.cross(q - p, r - p), (p + q + r) / 3 - centre), 0)


if __name__ == "__main__":
    unittest.main()
