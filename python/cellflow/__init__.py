"""Python client of the cellflow service.

    import cellflow
    client = cellflow.Client()                 # CELLFLOW_SERVER, CELLFLOW_TOKEN as the C++ CLI
    job = client.submit("examples/compression.json")
    for event in client.watch(job.id):
        if isinstance(event, cellflow.ForceSample):
            print(event.deformation, event.force_n)
    result = client.result(job.id)             # numpy arrays from the HDF5 (H5MD) file
    result.observables["force_n"].value

The stubs generated from proto/ are importable as cellflow.v1 (spec_pb2,
service_pb2, service_pb2_grpc, ...). SI units in every field name.
"""

from cellflow.errors import CellflowError
from cellflow.events import (
    ChildUpdate,
    DeformationSample,
    Event,
    ForceSample,
    Progress,
    StateChange,
    SuspendedCellState,
    SuspensionSample,
    event_from_proto,
)
from cellflow.results import Observable, Result, read_result
from cellflow.client import Client, TERMINAL_STATES, state_name, parse_spec

__all__ = [
    "CellflowError",
    "ChildUpdate",
    "Client",
    "DeformationSample",
    "Event",
    "ForceSample",
    "Observable",
    "Progress",
    "Result",
    "StateChange",
    "SuspendedCellState",
    "SuspensionSample",
    "TERMINAL_STATES",
    "event_from_proto",
    "parse_spec",
    "read_result",
    "state_name",
]
