"""The one exception the client raises for a refused or failed call."""

import grpc


class CellflowError(Exception):
    """A call the service refused or that could not reach it.

    code: the grpc.StatusCode (INVALID_ARGUMENT names the field of the spec and
    its allowed range, NOT_FOUND, UNAUTHENTICATED, UNAVAILABLE, ...), or None
    for an error of the client itself (a bad spec file, a token file readable
    by others)."""

    def __init__(self, message, code=None):
        super().__init__(message)
        self.code = code

    @classmethod
    def from_rpc(cls, error, what):
        code = error.code() if isinstance(error, grpc.Call) else None
        details = error.details() if isinstance(error, grpc.Call) else str(error)
        name = code.name if code is not None else "ERROR"
        return cls(f"{what}: {name}: {details}", code)
