"""A thin client of cellflow.v1.CellflowService, the Python twin of the C++
client (client/rpc_client.h): a deadline on every unary call, retries of
UNAVAILABLE only (the one status that says the call did not reach the
service), a watch that resumes after the last sequence it saw, and the same
sources of the address and the credentials as the `cellflow` CLI."""

import getpass
import json
import os
import pathlib
import stat
import tempfile
import time
import uuid
import weakref
from typing import Iterator, Mapping, Optional, Sequence, Union

import grpc
from google.protobuf import json_format

from cellflow._proto import service_pb2, service_pb2_grpc, spec_pb2
from cellflow.errors import CellflowError
from cellflow.events import Event, StateChange, event_from_proto
from cellflow.results import Result, read_result

DEFAULT_SERVER = "127.0.0.1:50051"
TERMINAL_STATES = ("SUCCEEDED", "FAILED", "CANCELLED")
# A spec file or a token larger than this is not a spec or a token.
MAX_SPEC_BYTES = 64 << 20
MAX_TOKEN_BYTES = 4096

SpecLike = Union[Mapping, "spec_pb2.JobSpec", str, os.PathLike]


def state_name(job_or_state) -> str:
    """QUEUED, RUNNING, SUCCEEDED, FAILED or CANCELLED, of a Job or a Job.State number."""
    number = job_or_state.state if hasattr(job_or_state, "state") else int(job_or_state)
    return service_pb2.Job.State.Name(number)


def _read_bounded(path, limit, what) -> bytes:
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise CellflowError(f"{what} {path}: larger than {limit} bytes")
    return data


def _read_secret(path) -> str:
    """A token file: mode 0600 or stricter (as the C++ client), not empty."""
    mode = os.stat(path).st_mode
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise CellflowError(f"token file {path} is readable or writable by others: chmod 600 {path}")
    token = _read_bounded(path, MAX_TOKEN_BYTES, "token file").decode("utf-8").strip()
    if not token:
        raise CellflowError(f"token file {path} is empty")
    return token


def _user_name() -> str:
    try:
        return getpass.getuser()  # USER, LOGNAME, ..., else the account's name
    except Exception:  # no name to be found: the server names the token's user
        return ""


def parse_spec(spec: SpecLike) -> "spec_pb2.JobSpec":
    """A cellflow.v1.JobSpec from a dict (protobuf JSON mapping: camelCase or
    the proto's field names), a JobSpec, JSON text starting with "{", or the
    path of a spec JSON file (what `cellflow submit --spec` and cellflow-run
    read). Unknown fields are refused."""
    if isinstance(spec, spec_pb2.JobSpec):
        return spec
    if isinstance(spec, Mapping):
        try:
            return json_format.ParseDict(spec, spec_pb2.JobSpec())
        except json_format.ParseError as error:
            raise CellflowError(f"job spec: {error}") from error
    if isinstance(spec, str) and spec.lstrip().startswith("{"):
        text, where = spec, "job spec"
    elif isinstance(spec, (str, os.PathLike)):
        text, where = _read_bounded(spec, MAX_SPEC_BYTES, "spec file").decode("utf-8"), f"spec file {spec}"
    else:
        raise CellflowError(f"job spec: expected a dict, a JobSpec, JSON text or a file name, got {type(spec).__name__}")
    try:
        return json_format.Parse(text, spec_pb2.JobSpec())
    except json_format.ParseError as error:
        raise CellflowError(f"{where}: {error}") from error


class Client:
    """A connection to a cellflow server.

    address: host:port or unix:PATH; default CELLFLOW_SERVER, else 127.0.0.1:50051.
    token: the bearer token sent on every call (`authorization: Bearer ...`);
      default: token_file if given, else CELLFLOW_TOKEN, else
      ~/.config/cellflow/token if it exists (mode 0600 or stricter). token=""
      sends none (a server with --auth none).
    TLS: on when tls_ca_file is given (or CELLFLOW_TLS_CA is set, or tls=True
      for the system's roots); tls_cert_file and tls_key_file (or
      CELLFLOW_TLS_CERT / CELLFLOW_TLS_KEY) add a client certificate (mTLS);
      tls_server_name overrides the name checked against the server's
      certificate.
    timeout_s: deadline of each unary call; max_attempts: tries of a call
      answered UNAVAILABLE; reconnect_s: how long watch and download keep
      reconnecting.
    """

    def __init__(
        self,
        address: Optional[str] = None,
        *,
        token: Optional[str] = None,
        token_file: Optional[str] = None,
        tls: Optional[bool] = None,
        tls_ca_file: Optional[str] = None,
        tls_cert_file: Optional[str] = None,
        tls_key_file: Optional[str] = None,
        tls_server_name: Optional[str] = None,
        timeout_s: float = 10.0,
        max_attempts: int = 4,
        reconnect_s: float = 60.0,
    ):
        self.address = address or os.environ.get("CELLFLOW_SERVER") or DEFAULT_SERVER
        self.timeout_s = max(timeout_s, 1e-3)
        self.max_attempts = max(1, int(max_attempts))
        self.reconnect_s = reconnect_s
        self._token = self._find_token(token, token_file)
        self._metadata = (("authorization", "Bearer " + self._token),) if self._token else ()
        options = [
            # gRPC's reconnect backoff, small as the C++ client's (rpc/rpc.h):
            # a restarted server is found again within a second.
            ("grpc.initial_reconnect_backoff_ms", 100),
            ("grpc.max_reconnect_backoff_ms", 1000),
            ("grpc.max_receive_message_length", 8 << 20),
        ]
        credentials = self._tls_credentials(tls, tls_ca_file, tls_cert_file, tls_key_file)
        if credentials is not None:
            if tls_server_name:
                options.append(("grpc.ssl_target_name_override", tls_server_name))
            self._channel = grpc.secure_channel(self.address, credentials, options=options)
        else:
            self._channel = grpc.insecure_channel(self.address, options=options)
        self.stub = service_pb2_grpc.CellflowServiceStub(self._channel)

    # -- connection -------------------------------------------------------

    @staticmethod
    def _find_token(token, token_file):
        if token is not None:
            return token
        if token_file:
            return _read_secret(token_file)
        if os.environ.get("CELLFLOW_TOKEN"):
            return os.environ["CELLFLOW_TOKEN"].strip()
        fallback = pathlib.Path.home() / ".config" / "cellflow" / "token"
        if fallback.exists():
            return _read_secret(fallback)
        return ""

    @staticmethod
    def _tls_credentials(tls, ca_file, cert_file, key_file):
        if tls is False:  # plaintext, whatever CELLFLOW_TLS_* say
            if ca_file or cert_file or key_file:
                raise CellflowError("TLS files given with tls=False")
            return None
        if ca_file is None and cert_file is None and not tls:
            ca_file = os.environ.get("CELLFLOW_TLS_CA") or None
            cert_file = os.environ.get("CELLFLOW_TLS_CERT") or None
            key_file = os.environ.get("CELLFLOW_TLS_KEY") or None
        if not tls and ca_file is None:
            if cert_file is not None:
                raise CellflowError("a client certificate needs TLS: give tls_ca_file (or tls=True)")
            return None
        if (cert_file is None) != (key_file is None):
            raise CellflowError("tls_cert_file and tls_key_file go together (both or neither)")
        read = lambda path: _read_bounded(path, 1 << 20, "TLS file") if path else None  # noqa: E731
        return grpc.ssl_channel_credentials(
            root_certificates=read(ca_file), private_key=read(key_file), certificate_chain=read(cert_file)
        )

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _call(self, method, request, what):
        """A unary call with a deadline, retried while UNAVAILABLE (0.25, 0.5, 1 s, ...)."""
        wait = 0.25
        for attempt in range(1, self.max_attempts + 1):
            try:
                return method(request, timeout=self.timeout_s, metadata=self._metadata)
            except grpc.RpcError as error:
                if error.code() != grpc.StatusCode.UNAVAILABLE or attempt == self.max_attempts:
                    raise CellflowError.from_rpc(error, what) from None
            time.sleep(wait)
            wait *= 2

    # -- jobs ---------------------------------------------------------------

    def submit(self, spec: SpecLike, *, name: Optional[str] = None, request_id: Optional[str] = None):
        """Validates and queues a job; returns its cellflow.v1.Job (job.id).

        spec: a dict in the protobuf JSON mapping ({"compression": {...}}), a
        JobSpec, JSON text, or a spec JSON file. request_id makes the call
        idempotent (default: a fresh UUID, so a retried call never queues twice)."""
        job_spec = spec_pb2.JobSpec()
        job_spec.CopyFrom(parse_spec(spec))
        if name is not None:
            job_spec.name = name
        # The result's author, as the C++ client names it: the spec's, else this
        # user's name (a JobSpec.author field of newer protos; absent: nothing to set).
        if "author" in job_spec.DESCRIPTOR.fields_by_name and not job_spec.author:
            user = _user_name()
            if user and len(user) <= 256:
                job_spec.author = user
        request = service_pb2.SubmitJobRequest(spec=job_spec, request_id=request_id or str(uuid.uuid4()))
        return self._call(self.stub.SubmitJob, request, "submit").job

    def submit_study(
        self,
        base: SpecLike,
        axes: Union[Mapping[str, Sequence], Sequence],
        *,
        combination: str = "grid",
        name: Optional[str] = None,
        request_id: Optional[str] = None,
    ):
        """Submits a study (sweep): the base spec expanded over its axes, one
        child job per point. axes: {path: values} with paths in the protobuf
        JSON names ("shearFlow.capillaryNumber",
        "compression.cell.material.youngsModulusPa") and Python values (each
        sent as JSON text: 0.05, True, "PER_TET"). combination: "grid" (the
        outer product, the last axis fastest) or "zip" (axes of equal length
        taken together). Returns the study's Job; its children: children(id)."""
        study = spec_pb2.StudySpec()
        study.base.CopyFrom(parse_spec(base))
        items = axes.items() if isinstance(axes, Mapping) else axes
        for path, values in items:
            if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
                raise CellflowError(f"study axis {path}: values must be a list, got {values!r}")
            study.axes.add(path=path, values=[json.dumps(v) for v in values])
        combinations = {"grid": spec_pb2.StudySpec.GRID, "zip": spec_pb2.StudySpec.ZIP}
        if combination.lower() not in combinations:
            raise CellflowError(f"study combination {combination!r}: grid or zip")
        study.combination = combinations[combination.lower()]
        spec = spec_pb2.JobSpec(name=name if name is not None else study.base.name, study=study)
        return self.submit(spec, request_id=request_id)

    def get(self, job_id: str):
        """The cellflow.v1.Job (state: state_name(job))."""
        return self._call(self.stub.GetJob, service_pb2.GetJobRequest(job_id=job_id), f"get {job_id}")

    def list_page(self, *, state: Optional[str] = None, parent_job_id: str = "", page_size: int = 0,
                  page_token: str = ""):
        """One page of jobs, oldest first: (jobs, next_page_token); the token is empty on the last page."""
        try:
            state_number = service_pb2.Job.State.Value(state.upper()) if state else 0
        except ValueError:
            raise CellflowError(f"list: state {state!r}: one of {', '.join(TERMINAL_STATES + ('QUEUED', 'RUNNING'))}") from None
        request = service_pb2.ListJobsRequest(page_size=page_size, page_token=page_token,
                                              parent_job_id=parent_job_id, state=state_number)
        response = self._call(self.stub.ListJobs, request, "list")
        return list(response.jobs), response.next_page_token

    def list(self, *, state: Optional[str] = None, parent_job_id: str = "", page_size: int = 0) -> Iterator:
        """Every job the caller may see (optionally of one state, or the
        children of one study), oldest first, fetched page by page."""
        token = ""
        while True:
            jobs, token = self.list_page(state=state, parent_job_id=parent_job_id, page_size=page_size,
                                         page_token=token)
            yield from jobs
            if not token:
                return

    def children(self, study_id: str, *, state: Optional[str] = None):
        """The child jobs of a study, in the order of their point in its grid (child_index)."""
        return sorted(self.list(parent_job_id=study_id, state=state), key=lambda job: job.child_index)

    def cancel(self, job_id: str):
        """QUEUED or RUNNING -> CANCELLED; returns the Job."""
        return self._call(self.stub.CancelJob, service_pb2.CancelJobRequest(job_id=job_id), f"cancel {job_id}")

    def delete(self, job_id: str) -> None:
        """Removes a terminal job: its rows, events and result file."""
        self._call(self.stub.DeleteJob, service_pb2.DeleteJobRequest(job_id=job_id), f"delete {job_id}")

    def upload_mesh(self, mesh: Union[bytes, str, os.PathLike], *, name: str = ""):
        """Uploads a Gmsh .msh v4 ASCII mesh (bytes or a file); returns the
        MeshRef whose sha256 goes into a spec's cell.meshSha256."""
        if not isinstance(mesh, bytes):
            name = name or os.path.basename(mesh)
            mesh = _read_bounded(mesh, 1 << 30, "mesh file")
        chunk = 1 << 20

        def chunks():
            for offset in range(0, max(len(mesh), 1), chunk):
                yield service_pb2.MeshChunk(data=mesh[offset:offset + chunk], file_name=name if offset == 0 else "")

        wait = 0.25
        for attempt in range(1, self.max_attempts + 1):
            try:
                return self.stub.UploadMesh(chunks(), timeout=max(self.timeout_s, 60.0), metadata=self._metadata)
            except grpc.RpcError as error:
                if error.code() != grpc.StatusCode.UNAVAILABLE or attempt == self.max_attempts:
                    raise CellflowError.from_rpc(error, "upload mesh") from None
            time.sleep(wait)
            wait *= 2

    # -- streams ------------------------------------------------------------

    def watch_events(self, job_id: str, after_sequence: int = 0) -> Iterator:
        """The job's cellflow.v1.JobEvent messages with sequence >
        after_sequence, in order, until its terminal state event; a broken
        stream is reopened after the last sequence seen (no event twice, none
        lost) for up to reconnect_s without an event."""
        wait = 0.1
        last_event = time.monotonic()
        while True:
            request = service_pb2.WatchJobRequest(job_id=job_id, after_sequence=after_sequence)
            call = self.stub.WatchJob(request, metadata=self._metadata)
            try:
                for event in call:
                    last_event = time.monotonic()
                    wait = 0.1
                    after_sequence = event.sequence
                    yield event
                return
            except grpc.RpcError as error:
                if error.code() != grpc.StatusCode.UNAVAILABLE or time.monotonic() - last_event > self.reconnect_s:
                    raise CellflowError.from_rpc(error, f"watch {job_id}") from None
            finally:
                call.cancel()  # the caller stopped early: end the stream on the server too
            time.sleep(wait)
            wait = min(2 * wait, 2.0)

    def watch(self, job_id: str, after_sequence: int = 0) -> Iterator[Event]:
        """The job's events as typed dataclasses (cellflow.events): StateChange,
        Progress, ForceSample (compression, indentation), DeformationSample
        (shear flow), ChildUpdate (a study's children); ends after the
        terminal StateChange. Resumes after the last sequence on reconnect."""
        for event in self.watch_events(job_id, after_sequence):
            yield event_from_proto(event)

    def wait(self, job_id: str):
        """Follows the job to its terminal state; returns the final Job."""
        for event in self.watch(job_id):
            if isinstance(event, StateChange) and event.terminal:
                break
        return self.get(job_id)

    def download(self, job_id: str, path: Union[str, os.PathLike], *, max_bytes: int = 64 << 30) -> pathlib.Path:
        """Writes the job's HDF5 result to path (through path.part, renamed
        when every byte arrived in order); retried while UNAVAILABLE."""
        path = pathlib.Path(path)
        partial = path.with_name(path.name + ".part")
        wait = 0.25
        for attempt in range(1, self.max_attempts + 1):
            received, total = 0, -1
            try:
                with open(partial, "wb") as out:
                    call = self.stub.DownloadResult(service_pb2.DownloadResultRequest(job_id=job_id),
                                                    metadata=self._metadata)
                    try:
                        for chunk in call:
                            if chunk.offset != received:
                                raise CellflowError(f"download {job_id}: chunk at {chunk.offset}, expected {received}")
                            received += len(chunk.data)
                            total = chunk.total_size_bytes
                            if received > max_bytes or (total >= 0 and received > total):
                                raise CellflowError(f"download {job_id}: more than {min(max_bytes, max(total, 0))} bytes")
                            out.write(chunk.data)
                    finally:
                        call.cancel()
                if total >= 0 and received != total:
                    raise CellflowError(f"download {job_id}: received {received} of {total} bytes",
                                        grpc.StatusCode.DATA_LOSS)
                os.replace(partial, path)
                return path
            except grpc.RpcError as error:
                partial.unlink(missing_ok=True)
                if error.code() != grpc.StatusCode.UNAVAILABLE or attempt == self.max_attempts:
                    raise CellflowError.from_rpc(error, f"download {job_id}") from None
            except BaseException:
                partial.unlink(missing_ok=True)
                raise
            time.sleep(wait)
            wait *= 2

    def result(self, job_id: str, path: Optional[Union[str, os.PathLike]] = None) -> Result:
        """The job's result read into numpy arrays (cellflow.results.Result).
        With path the HDF5 file is kept there; without, it is read from a
        temporary file that is removed (the arrays stay in memory)."""
        if path is not None:
            return read_result(self.download(job_id, path))
        folder = tempfile.TemporaryDirectory(prefix="cellflow-")
        try:
            result = read_result(self.download(job_id, pathlib.Path(folder.name) / f"{job_id}.h5"))
        except BaseException:
            folder.cleanup()
            raise
        # Removed with the Result (fields are read from the file on demand).
        weakref.finalize(result, folder.cleanup)
        return result
