"""The one exception the client raises for a refused or failed call."""


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
        # A grpc.RpcError of a call is also a grpc.Call (code, details).
        code = error.code() if callable(getattr(error, "code", None)) else None
        details = error.details() if callable(getattr(error, "details", None)) else str(error)
        name = code.name if code is not None else "ERROR"
        return cls(f"{what}: {name}: {details}", code)
