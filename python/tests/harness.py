"""A real cellflow-server with its local workers on loopback, for the
Python tests: an ephemeral port, a temporary data directory, a user token
made with `cellflow-server token create` (authentication on, as in
production). Executables from CELLFLOW_SERVER_EXE / CELLFLOW_WORKER_EXE (set
by ctest) or build/bin of the checkout."""

import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
CHECKOUT = pathlib.Path(os.environ.get("CELLFLOW_SOURCE_DIR", HERE.parent.parent))
BUILD_BIN = CHECKOUT / "build" / "bin"
SERVER_EXE = os.environ.get("CELLFLOW_SERVER_EXE", str(BUILD_BIN / "cellflow-server"))
WORKER_EXE = os.environ.get("CELLFLOW_WORKER_EXE", str(BUILD_BIN / "cellflow-worker"))

# Without ctest: the package of the CMake build tree.
if not any(pathlib.Path(p, "cellflow", "v1").is_dir() for p in sys.path if p):
    sys.path.insert(0, str(CHECKOUT / "build" / "python"))


def small_compression(load_points=5, youngs_modulus_pa=1000.0, vertices=300):
    """A compression job of a few tenths of a second: 300 vertices to deformation 0.15."""
    return {
        "name": "python small compression",
        "compression": {
            "cell": {
                "radiusM": 5e-6,
                "material": {"youngsModulusPa": youngs_modulus_pa, "poissonRatio": 0.45},
                "targetVertexCount": vertices,
            },
            "maxDeformation": 0.15,
            "loadPoints": load_points,
        },
    }


def small_shear_flow(capillary_number=0.2, max_strain=2.0):
    """The tiny flow of tests/service/shear_flow_service_test.cc: 3 lattice
    nodes per radius, ~300 vertices, a 5 x 6 x 4 R box, 2 strain units
    (about 1100 time steps, under a second on one core)."""
    return {
        "name": "python small shear flow",
        "shearFlow": {
            "cell": {
                "radiusM": 4e-6,
                "material": {"youngsModulusPa": 50.0, "poissonRatio": 0.45},
                "targetVertexCount": 300,
            },
            "capillaryNumber": capillary_number,
            "numerics": {
                "cellsPerRadius": 3,
                "boxXRadii": 5,
                "boxYRadii": 6,
                "boxZRadii": 4,
                "maxStrain": max_strain,
                "sampleEveryStrain": 0.1,
                "snapshotEveryStrain": 0.5,
                "fluidSnapshots": True,
            },
        },
    }


class LocalService:
    """with LocalService(workers=2) as service: service.address, service.token, service.folder."""

    def __init__(self, workers=1, extra_args=(), folder=None):
        self.workers = workers
        self.extra_args = list(extra_args)
        self.given_folder = folder
        self.process = None

    def __enter__(self):
        self.folder = pathlib.Path(self.given_folder or tempfile.mkdtemp(prefix="cellflow_python_"))
        data = self.folder / "data"
        env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="passive", TMPDIR=str(self.folder))
        self.token = subprocess.run([SERVER_EXE, "token", "create", "--user", "python-test", "--data-dir", str(data)],
                                    check=True, capture_output=True, text=True, env=env).stdout.strip()
        port_file = self.folder / "port"
        self.log_path = self.folder / "server.log"
        with open(self.log_path, "wb") as log:
            self.process = subprocess.Popen(
                [SERVER_EXE, "--listen", "127.0.0.1:0", "--port-file", str(port_file), "--worker-listen",
                 "127.0.0.1:0", "--worker-port-file", str(self.folder / "worker-port"), "--data-dir", str(data),
                 "--workers", str(self.workers), "--worker-path", WORKER_EXE, "--worker-arg=--threads=1",
                 "--log-level", "info", *self.extra_args],
                stdout=log, stderr=subprocess.STDOUT, env=env)
        deadline = time.monotonic() + 20
        while not (port_file.exists() and port_file.read_text().strip()):
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("cellflow-server did not start:\n" + self.log())
            time.sleep(0.02)
        self.address = "127.0.0.1:" + port_file.read_text().strip()
        return self

    def log(self):
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def __exit__(self, kind, value, traceback):
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        # On stderr for ctest --output-on-failure (shown only when a test failed).
        sys.stderr.write("---- server log (end) ----\n" + self.log()[-6000:])
        shutil.rmtree(self.folder, ignore_errors=True)


def run_example(service, *args, timeout=120):
    """examples/python/sweep_and_plot.py against the service (address and
    token in the environment, as a user sets them); returns the finished process."""
    import cellflow

    env = dict(os.environ, CELLFLOW_SERVER=service.address, CELLFLOW_TOKEN=service.token,
               PYTHONPATH=str(pathlib.Path(cellflow.__file__).resolve().parent.parent), MPLBACKEND="Agg")
    return subprocess.run([sys.executable, str(CHECKOUT / "examples" / "python" / "sweep_and_plot.py"), *args],
                          capture_output=True, text=True, env=env, timeout=timeout)


def steady_values(stdout):
    """{Ca: steady D} from the example's output lines "Ca 0.1: steady D 0.0123 ..."."""
    out = {}
    for line in stdout.splitlines():
        if line.startswith("Ca ") and "steady D" in line:
            ca, rest = line[3:].split(":", 1)
            out[float(ca)] = float(rest.split()[2])
    return out


def make_certificates(folder):
    """A CA, a server certificate for localhost and 127.0.0.1 signed by it, a
    client certificate signed by it, and a second CA that signed nothing
    (Debian's openssl; the commands of tests/service/auth_test.cc)."""
    d = pathlib.Path(folder)
    (d / "san.ext").write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\nbasicConstraints=CA:FALSE\n")
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    for command in (
        ["req", "-x509", *ec, "-days", "2", "-subj", "/CN=cellflow-test-ca", "-keyout", d / "ca.key", "-out", d / "ca.pem"],
        ["req", "-x509", *ec, "-days", "2", "-subj", "/CN=other-ca", "-keyout", d / "other.key", "-out", d / "other.pem"],
        ["req", *ec, "-subj", "/CN=localhost", "-keyout", d / "server.key", "-out", d / "server.csr"],
        ["x509", "-req", "-in", d / "server.csr", "-CA", d / "ca.pem", "-CAkey", d / "ca.key", "-CAcreateserial",
         "-days", "2", "-extfile", d / "san.ext", "-out", d / "server.pem"],
        ["req", *ec, "-subj", "/CN=client", "-keyout", d / "client.key", "-out", d / "client.csr"],
        ["x509", "-req", "-in", d / "client.csr", "-CA", d / "ca.pem", "-CAkey", d / "ca.key", "-CAcreateserial",
         "-days", "2", "-out", d / "client.pem"],
    ):
        subprocess.run(["openssl", *map(str, command)], check=True, capture_output=True)
    return d
