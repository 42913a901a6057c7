"""Typed events of a job's watch stream (cellflow.v1.JobEvent), as frozen
dataclasses: one class per kind of event, with the fields of the proto
message of that kind (enums as their names, repeated fields as tuples) and
the event's job_id, sequence, attempt and time."""

import dataclasses
import datetime
from typing import Optional, Tuple

from google.protobuf.descriptor import FieldDescriptor

from cellflow._proto import service_pb2


@dataclasses.dataclass(frozen=True)
class Event:
    """Any event; an event of a kind these stubs do not know comes as this
    base class (kind is the name of its oneof field, or "")."""

    job_id: str
    sequence: int
    attempt: int
    time: Optional[datetime.datetime]

    kind = ""


@dataclasses.dataclass(frozen=True)
class StateChange(Event):
    state: str  # QUEUED, RUNNING, SUCCEEDED, FAILED, CANCELLED
    reason: str
    worker_id: str

    kind = "state_change"

    @property
    def terminal(self):
        return self.state in ("SUCCEEDED", "FAILED", "CANCELLED")


@dataclasses.dataclass(frozen=True)
class Progress(Event):
    fraction_done: float
    elapsed_s: float
    estimated_remaining_s: float  # < 0: unknown
    stage: str

    kind = "progress"


@dataclasses.dataclass(frozen=True)
class ForceSample(Event):
    """One point of a quasi-static force curve (compression, indentation)."""

    index: int
    deformation: float  # delta / (2 R)
    displacement_m: float
    force_n: float
    hertz_force_n: float
    taylor_deformation: float
    semi_axes_m: Tuple[float, ...]
    volume_m3: float
    elastic_energy_j: float
    max_penetration_m: float
    newton_iterations: int
    step_splits: int
    residual: float
    cg_iterations: int

    kind = "force_sample"


@dataclasses.dataclass(frozen=True)
class DeformationSample(Event):
    """One shape sample of a cell in shear flow."""

    index: int
    time_s: float
    strain: float
    taylor_deformation: float
    semi_axes_m: Tuple[float, ...]
    inclination_rad: float
    net_strain: float
    volume_m3: float
    tank_treading_frequency_per_s: float

    kind = "deformation_sample"


@dataclasses.dataclass(frozen=True)
class SuspendedCellState:
    """One cell of a suspension sample (not an event)."""

    cell: int  # index in the suspension's order of cells
    taylor_deformation: float
    inclination_rad: float
    net_strain: float
    centroid_m: Tuple[float, ...]


@dataclasses.dataclass(frozen=True)
class SuspensionSample(Event):
    """A sample of a suspension (many cells in shear flow): the mean over the
    cells, the relative viscosity, the averages with their standard errors,
    and the first 256 cells (the result file holds every cell)."""

    index: int
    time_s: float
    strain: float
    cell_count: int
    mean_taylor_deformation: float
    mean_inclination_rad: float
    relative_viscosity: float
    contact_pairs: int
    cells: Tuple[SuspendedCellState, ...]
    average_taylor_deformation: float
    average_taylor_deformation_error: float
    average_relative_viscosity: float
    average_relative_viscosity_error: float

    kind = "suspension_sample"


@dataclasses.dataclass(frozen=True)
class ChildUpdate(Event):
    """A study's event: one of its children changed state."""

    child_job_id: str
    child_index: int
    state: str
    reason: str

    kind = "child_update"


EVENT_CLASSES = {
    cls.kind: cls for cls in (StateChange, Progress, ForceSample, DeformationSample, ChildUpdate, SuspensionSample)
}
# Repeated message fields of an event become tuples of these dataclasses.
MESSAGE_CLASSES = {"cellflow.v1.SuspendedCellState": SuspendedCellState}
_BASE_FIELDS = tuple(f.name for f in dataclasses.fields(Event))


def _message_value(message):
    cls = MESSAGE_CLASSES[message.DESCRIPTOR.full_name]
    fields = message.DESCRIPTOR.fields_by_name
    return cls(**{f.name: _field_value(message, fields[f.name]) for f in dataclasses.fields(cls)})


def _field_value(message, field):
    value = getattr(message, field.name)
    if field.label == FieldDescriptor.LABEL_REPEATED:
        if field.type == FieldDescriptor.TYPE_MESSAGE:
            return tuple(_message_value(m) for m in value)
        return tuple(value)
    if field.type == FieldDescriptor.TYPE_ENUM:
        return field.enum_type.values_by_number[value].name if value in field.enum_type.values_by_number else str(value)
    return value


def event_from_proto(event: "service_pb2.JobEvent") -> Event:
    """The typed event of a cellflow.v1.JobEvent."""
    time = event.time.ToDatetime(tzinfo=datetime.timezone.utc) if event.HasField("time") else None
    base = dict(job_id=event.job_id, sequence=event.sequence, attempt=event.attempt, time=time)
    kind = event.WhichOneof("kind")
    cls = EVENT_CLASSES.get(kind or "")
    if cls is None:
        return Event(**base)
    message = getattr(event, kind)
    fields = message.DESCRIPTOR.fields_by_name
    values = {}
    for f in dataclasses.fields(cls):
        if f.name in _BASE_FIELDS:
            continue
        values[f.name] = _field_value(message, fields[f.name])
    return cls(**base, **values)
