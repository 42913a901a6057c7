"""pip install ./python (from a checkout): the package plus the stubs
generated from ../proto with protoc and grpc_python_plugin (Debian
protobuf-compiler and protobuf-compiler-grpc) and the result schemas of
../jobs/*/result_schema.json. Metadata: pyproject.toml."""

import pathlib
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = pathlib.Path(__file__).resolve().parent
CHECKOUT = HERE.parent


def generate(package_dir: pathlib.Path):
    """Writes cellflow/v1/*_pb2.py, *_pb2_grpc.py and cellflow/schemas/*.json under package_dir."""
    protos = sorted((CHECKOUT / "proto" / "cellflow" / "v1").glob("*.proto"))
    if not protos:
        raise SystemExit(f"no protos in {CHECKOUT / 'proto'}: install from a cellflow checkout")
    protoc = shutil.which("protoc")
    plugin = shutil.which("grpc_python_plugin")
    if not protoc or not plugin:
        raise SystemExit("protoc and grpc_python_plugin are needed (Debian: protobuf-compiler protobuf-compiler-grpc)")
    out = package_dir.parent
    (package_dir / "v1").mkdir(parents=True, exist_ok=True)
    subprocess.run([protoc, f"--proto_path={CHECKOUT / 'proto'}", f"--python_out={out}", f"--grpc_python_out={out}",
                    f"--plugin=protoc-gen-grpc_python={plugin}", *map(str, protos)], check=True)
    (package_dir / "v1" / "__init__.py").write_text("# Generated from proto/cellflow/v1 by protoc and grpc_python_plugin.\n")
    schemas = package_dir / "schemas"
    schemas.mkdir(exist_ok=True)
    for schema in sorted(CHECKOUT.glob("jobs/*/result_schema.json")):
        shutil.copyfile(schema, schemas / f"{schema.parent.name}.json")


class BuildPyWithStubs(build_py):
    def run(self):
        super().run()
        generate(pathlib.Path(self.build_lib) / "cellflow")


setup(cmdclass={"build_py": BuildPyWithStubs})
