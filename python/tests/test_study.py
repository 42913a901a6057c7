"""A study (sweep) from Python against a real server: two compression
children at E = 500 and 1000 Pa, watched as one (ChildUpdate events), the
children listed by their study, their results read. Needs a server that runs
studies (StudySpec, proto/cellflow/v1/spec.proto)."""

import unittest

import numpy as np

import harness
import cellflow

MODULI_PA = [500.0, 1000.0]
PATH = "compression.cell.material.youngsModulusPa"


class StudyFromPython(unittest.TestCase):
    def test_sweep_over_youngs_modulus(self):
        with harness.LocalService(workers=2) as service:
            client = cellflow.Client(service.address, token=service.token, reconnect_s=30)
            study = client.submit_study(harness.small_compression(load_points=4), {PATH: MODULI_PA},
                                        combination="grid", name="python sweep")
            self.assertFalse(study.parent_job_id)
            events = list(client.watch(study.id))
            self.assertIsInstance(events[-1], cellflow.StateChange)
            self.assertEqual(events[-1].state, "SUCCEEDED")
            updates = [e for e in events if isinstance(e, cellflow.ChildUpdate)]
            finished = {u.child_index: u for u in updates if u.state == "SUCCEEDED"}
            self.assertEqual(sorted(finished), [0, 1])

            final = client.get(study.id)
            self.assertEqual((final.child_count, final.children_done), (2, 2))
            children = client.children(study.id)
            self.assertEqual([c.child_index for c in children], [0, 1])
            self.assertEqual({c.id for c in children}, {u.child_job_id for u in finished.values()})
            for child, modulus in zip(children, MODULI_PA):
                self.assertEqual(child.parent_job_id, study.id)
                self.assertEqual(cellflow.state_name(child), "SUCCEEDED")
                self.assertEqual(child.spec.compression.cell.material.youngs_modulus_pa, modulus)
            # The elastic energy and the contact stiffness both scale with E:
            # at the same deformations the force doubles with E.
            soft, stiff = (client.result(c.id) for c in children)
            np.testing.assert_allclose(soft["deformation"], stiff["deformation"], rtol=1e-12)
            np.testing.assert_allclose(stiff["force_n"] / soft["force_n"], 2.0, rtol=1e-3)

            # The example script's study path: a capillary-number sweep, plotted.
            figure = service.folder / "sweep.png"
            run = harness.run_example(service, "--quick", "--ca", "0.1,0.2", "-o", str(figure))
            self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
            self.assertIn("study", run.stdout)
            self.assertEqual(figure.read_bytes()[:8], b"\x89PNG\r\n\x1a\n")
            steady = harness.steady_values(run.stdout)
            self.assertEqual(sorted(steady), [0.1, 0.2])
            self.assertGreater(steady[0.2], steady[0.1])


if __name__ == "__main__":
    unittest.main()
