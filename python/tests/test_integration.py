"""The Python client against a real server with two workers on loopback:
a compression and a shear-flow job submitted, watched, listed, downloaded
and read into numpy; one frame converted to VTU with meshio and read back;
cancel, delete, idempotent submit and refused calls."""

import os
import pathlib
import tempfile
import time
import unittest

import numpy as np

import harness  # noqa: F401  (puts the build tree's package on sys.path without ctest)
import cellflow

SERVICE = None


def setUpModule():
    global SERVICE
    SERVICE = harness.LocalService(workers=2).__enter__()


def tearDownModule():
    SERVICE.__exit__(None, None, None)


class ClientAgainstServer(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.client = cellflow.Client(SERVICE.address, token=SERVICE.token, timeout_s=10, reconnect_s=30)
        cls.folder = pathlib.Path(tempfile.mkdtemp(prefix="cellflow_python_out_", dir=SERVICE.folder))
        started = time.monotonic()
        # Both queued at once: the two workers run them side by side.
        cls.compression = cls.client.submit(harness.small_compression(load_points=5))
        cls.flow = cls.client.submit(harness.small_shear_flow())
        cls.compression_events = list(cls.client.watch(cls.compression.id))
        cls.flow_events = list(cls.client.watch(cls.flow.id))
        print(f"compression and flow job: submit -> last event {time.monotonic() - started:.2f} s")

    @classmethod
    def tearDownClass(cls):
        cls.client.close()

    # -- watch ---------------------------------------------------------------

    def test_watch_yields_typed_events_in_sequence_and_ends_at_success(self):
        for events in (self.compression_events, self.flow_events):
            self.assertEqual([e.sequence for e in events], list(range(1, len(events) + 1)))
            self.assertIsInstance(events[-1], cellflow.StateChange)
            self.assertEqual(events[-1].state, "SUCCEEDED")
            self.assertTrue(events[-1].terminal)
            self.assertIsNotNone(events[-1].time)
            self.assertTrue(any(isinstance(e, cellflow.Progress) for e in events))
        forces = [e for e in self.compression_events if isinstance(e, cellflow.ForceSample)]
        self.assertEqual([s.index for s in forces], [0, 1, 2, 3, 4])
        # The plates squeeze further each point and the reaction grows with it.
        self.assertTrue(np.all(np.diff([s.deformation for s in forces]) > 0))
        self.assertTrue(np.all(np.diff([s.force_n for s in forces]) > 0))
        self.assertAlmostEqual(forces[-1].deformation, 0.15, places=9)
        self.assertEqual(len(forces[-1].semi_axes_m), 3)
        shapes = [e for e in self.flow_events if isinstance(e, cellflow.DeformationSample)]
        self.assertGreater(len(shapes), 10)
        self.assertTrue(np.all(np.diff([s.strain for s in shapes]) > 0))

    def test_watch_after_a_sequence_resumes_there(self):
        k = len(self.compression_events) // 2
        rest = list(self.client.watch(self.compression.id, after_sequence=k))
        self.assertEqual(rest, self.compression_events[k:])

    def test_wait_returns_the_final_job(self):
        job = self.client.wait(self.compression.id)
        self.assertEqual(cellflow.state_name(job), "SUCCEEDED")
        self.assertEqual(job.fraction_done, 1.0)
        self.assertGreater(job.result_size_bytes, 0)

    # -- results -------------------------------------------------------------

    def test_compression_result_in_numpy(self):
        path = self.folder / "compression.h5"
        result = self.client.result(self.compression.id, path)
        self.assertEqual(path.stat().st_size, self.client.get(self.compression.id).result_size_bytes)
        self.assertEqual(result.scene, "compression")
        self.assertEqual(result.spec["compression"]["loadPoints"], 5)
        force = result["force_n"]
        deformation = result["deformation"]
        self.assertEqual(force.shape, (5,))
        self.assertEqual(result["semi_axes_m"].shape, (5, 3))
        self.assertEqual(result.observables["force_n"].unit, "N")
        samples = [e for e in self.compression_events if isinstance(e, cellflow.ForceSample)]
        np.testing.assert_array_equal(force, [s.force_n for s in samples])
        np.testing.assert_array_equal(deformation, [s.deformation for s in samples])
        self.assertTrue(np.all(np.diff(force) > 0))
        # Hertz is the small-strain limit: the first point (deformation 0.03)
        # is within the coarse 300-vertex mesh's few tens of percent of it.
        ratio = force[0] / result["hertz_force_n"][0]
        self.assertGreater(ratio, 0.8)
        self.assertLess(ratio, 1.5)
        # Nearly incompressible (nu = 0.45): the volume changes by well under 5 %.
        volume = result["volume_m3"]
        sphere = 4.0 / 3.0 * np.pi * (5e-6) ** 3
        self.assertLess(np.max(np.abs(volume / sphere - 1.0)), 0.05)
        # The reference state and one frame per load point.
        self.assertEqual(result.frame_count, 6)
        self.assertEqual(result.tetrahedra.shape[1], 4)
        vertices = result.positions(0).shape[0]
        self.assertGreater(vertices, 200)
        self.assertEqual(result.positions(-1).shape, (vertices, 3))
        # The last frame is squeezed: its height is 2R (1 - 0.15) within a mesh tolerance.
        height = np.ptp(result.positions(-1)[:, 2])
        self.assertAlmostEqual(height / (2 * 5e-6), 0.85, delta=0.02)
        self.assertEqual(result.cell_region.shape, (len(result.tetrahedra),))
        try:
            import pandas  # noqa: F401
        except ImportError:
            return
        frame = result.to_dataframe()
        self.assertEqual(len(frame), 5)
        self.assertIn("semi_axes_m_2", frame.columns)

    def test_flow_result_in_numpy(self):
        result = self.client.result(self.flow.id)  # a temporary file, removed with the Result
        self.assertEqual(result.scene, "shearFlow")
        shapes = [e for e in self.flow_events if isinstance(e, cellflow.DeformationSample)]
        d = result["taylor_deformation"]
        self.assertEqual(d.shape, (len(shapes),))
        np.testing.assert_array_equal(d, [s.taylor_deformation for s in shapes])
        np.testing.assert_array_equal(result["strain"], [s.strain for s in shapes])
        self.assertEqual(result.observables["taylor_deformation"].time.shape, d.shape)
        # The cell deforms (D > 0) but stays below twice Roscoe's steady 5/4 Ca at Ca = 0.2.
        self.assertGreater(d[-1], 0.01)
        self.assertLess(np.max(d), 2 * 1.25 * 0.2)
        self.assertAlmostEqual(result.setup["capillary_number"], 0.2, places=12)
        self.assertEqual(result.summary["stop"], "max_strain")
        # Snapshots every 0.5 strain over 2: 5 frames, the fluid with each.
        self.assertEqual(result.frame_count, 5)
        self.assertIn("fluid_velocity", result.field_names)
        velocity, t, grid = result.field("fluid_velocity", -1)
        nx, ny, nz = (int(n) for n in grid["dimensions"])
        self.assertEqual(velocity.shape, (nz, ny, nx, 3))
        self.assertAlmostEqual(t, result.frame_times[-1])
        # Couette flow: u_x grows from the bottom wall (y = 0) to the top one.
        u_x = velocity[..., 0].mean(axis=(0, 2))
        self.assertGreater(u_x[-1], u_x[0])

    def test_frame_to_vtu_with_meshio_and_back(self):
        import meshio

        result = self.client.result(self.compression.id)
        path = self.folder / "last.vtu"
        result.write_mesh(path, frame=-1)
        mesh = meshio.read(path)
        np.testing.assert_array_equal(mesh.points, result.positions(-1))
        tetra = mesh.cells_dict["tetra"]
        np.testing.assert_array_equal(tetra, result.tetrahedra)
        np.testing.assert_array_equal(mesh.cell_data_dict["cell_region"]["tetra"], result.cell_region)
        # The surface as STL: a closed triangulated sphere (V - E + F = 2 with E = 3F/2).
        stl = meshio.read(result.write_mesh(self.folder / "last.stl"))
        faces = len(stl.cells_dict["triangle"])
        self.assertEqual(len(np.unique(stl.cells_dict["triangle"])) - faces // 2, 2)

    def test_example_sweep_and_plot_with_separate_jobs(self):
        figure = self.folder / "sweep.png"
        run = harness.run_example(SERVICE, "--quick", "--separate", "--ca", "0.1,0.2", "-o", str(figure))
        self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
        self.assertEqual(figure.read_bytes()[:8], b"\x89PNG\r\n\x1a\n")
        steady = harness.steady_values(run.stdout)
        self.assertEqual(sorted(steady), [0.1, 0.2])
        # A softer cell (larger Ca) deforms more.
        self.assertGreater(steady[0.2], steady[0.1])
        self.assertGreater(steady[0.1], 0.0)

    # -- jobs ----------------------------------------------------------------

    def test_get_and_list_with_paging(self):
        job = self.client.get(self.flow.id)
        self.assertEqual(job.id, self.flow.id)
        self.assertEqual(job.spec.shear_flow.capillary_number, 0.2)
        jobs, token = self.client.list_page(page_size=1)
        self.assertEqual(len(jobs), 1)
        self.assertTrue(token)
        ids = [j.id for j in self.client.list(page_size=1)]
        self.assertIn(self.compression.id, ids)
        self.assertIn(self.flow.id, ids)
        self.assertEqual(len(ids), len(set(ids)))
        succeeded = {j.id for j in self.client.list(state="succeeded")}
        self.assertTrue({self.compression.id, self.flow.id} <= succeeded)

    def test_submit_from_a_spec_file_is_idempotent_with_a_request_id(self):
        spec_file = harness.CHECKOUT / "examples" / "compression.json"
        first = self.client.submit(spec_file, request_id="python-same")
        again = self.client.submit(str(spec_file), request_id="python-same")
        self.assertEqual(first.id, again.id)
        self.assertEqual(first.spec.compression.cell.target_vertex_count, 1000)
        self.client.cancel(first.id)

    def test_cancel(self):
        job = self.client.submit(harness.small_compression(load_points=40, vertices=3000))
        cancelled = self.client.cancel(job.id)
        self.assertEqual(cellflow.state_name(cancelled), "CANCELLED")
        events = list(self.client.watch(job.id))
        self.assertEqual(events[-1].state, "CANCELLED")

    def test_delete_a_finished_job(self):
        job = self.client.wait(self.client.submit(harness.small_compression(load_points=2)).id)
        self.assertEqual(cellflow.state_name(job), "SUCCEEDED")
        self.client.delete(job.id)
        with self.assertRaises(cellflow.CellflowError) as caught:
            self.client.get(job.id)
        self.assertEqual(caught.exception.code.name, "NOT_FOUND")
        self.assertNotIn(job.id, [j.id for j in self.client.list()])

    def test_refusals(self):
        bad = harness.small_compression()
        bad["compression"]["maxDeformation"] = 5.0
        with self.assertRaises(cellflow.CellflowError) as caught:
            self.client.submit(bad)
        self.assertEqual(caught.exception.code.name, "INVALID_ARGUMENT")
        self.assertIn("max_deformation", str(caught.exception))
        with self.assertRaises(cellflow.CellflowError) as caught:
            self.client.submit({"compression": {"maxDeformationTypo": 0.1}})
        self.assertIsNone(caught.exception.code)
        stranger = cellflow.Client(SERVICE.address, token="not-a-token")
        with self.assertRaises(cellflow.CellflowError) as caught:
            stranger.get(self.compression.id)
        self.assertEqual(caught.exception.code.name, "UNAUTHENTICATED")

    def test_address_and_token_from_the_environment(self):
        saved = {k: os.environ.get(k) for k in ("CELLFLOW_SERVER", "CELLFLOW_TOKEN")}
        os.environ["CELLFLOW_SERVER"] = SERVICE.address
        os.environ["CELLFLOW_TOKEN"] = SERVICE.token
        try:
            with cellflow.Client() as client:
                self.assertEqual(client.get(self.compression.id).id, self.compression.id)
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v


class MutualTls(unittest.TestCase):
    """A server with --tls-cert/--tls-key/--tls-client-ca: the client with the
    CA and a client certificate (arguments, or CELLFLOW_TLS_* as the CLI)
    gets in; without the certificate, or trusting another CA, it does not."""

    def test_client_certificate_and_ca(self):
        with tempfile.TemporaryDirectory(prefix="cellflow_python_tls_") as folder:
            d = harness.make_certificates(folder)
            args = ["--tls-cert", d / "server.pem", "--tls-key", d / "server.key", "--tls-client-ca", d / "ca.pem"]
            with harness.LocalService(workers=1, extra_args=map(str, args), folder=d / "service") as service:
                files = dict(tls_ca_file=str(d / "ca.pem"), tls_cert_file=str(d / "client.pem"),
                             tls_key_file=str(d / "client.key"))
                with cellflow.Client(service.address, token=service.token, **files) as client:
                    job = client.wait(client.submit(harness.small_compression(load_points=2)).id)
                    self.assertEqual(cellflow.state_name(job), "SUCCEEDED")
                    self.assertEqual(client.result(job.id)["force_n"].shape, (2,))
                saved = dict(os.environ)
                os.environ.update(CELLFLOW_TLS_CA=files["tls_ca_file"], CELLFLOW_TLS_CERT=files["tls_cert_file"],
                                  CELLFLOW_TLS_KEY=files["tls_key_file"])
                try:
                    with cellflow.Client(service.address, token=service.token) as client:
                        self.assertEqual(client.get(job.id).id, job.id)
                finally:
                    os.environ.clear()
                    os.environ.update(saved)
                refused = [
                    dict(tls_ca_file=files["tls_ca_file"]),  # no client certificate
                    dict(files, tls_ca_file=str(d / "other.pem")),  # the server's certificate not trusted
                ]
                for options in refused:
                    with cellflow.Client(service.address, token=service.token, max_attempts=1, timeout_s=3,
                                         **options) as client:
                        with self.assertRaises(cellflow.CellflowError) as caught:
                            client.get(job.id)
                        self.assertEqual(caught.exception.code.name, "UNAVAILABLE", options)
                with cellflow.Client(service.address, token=service.token, max_attempts=1, timeout_s=3) as plain:
                    with self.assertRaises(cellflow.CellflowError):
                        plain.get(job.id)


if __name__ == "__main__":
    unittest.main()
