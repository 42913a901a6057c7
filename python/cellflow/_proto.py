"""The generated stubs (cellflow.v1), imported in one place so that a
package without them says how to get them."""

try:
    from cellflow.v1 import service_pb2, service_pb2_grpc, spec_pb2  # noqa: F401 (re-exported)
except ImportError as error:  # pragma: no cover - depends on the installation
    raise ImportError(
        "cellflow.v1 (the stubs generated from proto/) is missing: install the package with "
        "`pip install ./python` from a checkout (runs protoc and grpc_python_plugin), or put "
        "build/python of a CMake build on PYTHONPATH; " + str(error)
    ) from error

__all__ = ["service_pb2", "service_pb2_grpc", "spec_pb2"]
