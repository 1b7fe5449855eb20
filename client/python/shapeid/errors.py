"""The exceptions of a failed call: one class per gRPC status code the server documents
(proto/shapeid/v1/shapeid.proto), all subclasses of ShapeidError.

    try:
        client.classify("parts", cloud)
    except shapeid.NotFoundError:          # no gallery "parts"
        ...
    except shapeid.ShapeidError as e:      # any other refusal
        print(e.code, e.message)

A bad argument caught before anything is sent (a cloud of the wrong shape or type, a bad
option) is a plain TypeError or ValueError instead.
"""

import re

import grpc

__all__ = [
    "ShapeidError", "InvalidArgumentError", "NotFoundError", "AlreadyExistsError",
    "FailedPreconditionError", "ResourceExhaustedError", "PermissionDeniedError",
    "UnauthenticatedError", "UnavailableError", "DeadlineExceededError", "CancelledError",
    "AbortedError", "DataLossError", "UnimplementedError", "from_rpc_error",
]


class ShapeidError(Exception):
    """A call the server (or the transport) refused. `code` is the grpc.StatusCode, `message`
    the server's own text (what to fix, the numbers of a limit); `str()` gives both."""

    def __init__(self, code, message):
        super().__init__("%s: %s" % (code.name, message))
        self.code = code
        self.message = message


class InvalidArgumentError(ShapeidError, ValueError):
    """A malformed call: a bad gallery name or spec, a cloud of fewer than 3 points..."""


class NotFoundError(ShapeidError, LookupError):
    """An unknown gallery or sample id."""


class AlreadyExistsError(ShapeidError):
    """A gallery name or sample id that is taken."""


class FailedPreconditionError(ShapeidError):
    """Classify on an empty gallery, or a gallery made by another descriptor version."""


class ResourceExhaustedError(ShapeidError):
    """Over a size limit (never succeeds as it is) or the server is busy (retry later, with
    backoff): the message says which. Not retried by the client. `client_limit` is True when
    the limit is this client's own (an answer larger than its max_receive_bytes: the server
    answered, the client would not read it), False for every refusal the server sent."""

    def __init__(self, code, message, client_limit=False):
        super().__init__(code, message)
        self.client_limit = client_limit


class PermissionDeniedError(ShapeidError):
    """The API key's scope does not cover the call."""


class UnauthenticatedError(ShapeidError):
    """The server wants an API key and got none, or an unknown one."""


class UnavailableError(ShapeidError, ConnectionError):
    """The server cannot be reached, is loading or shutting down (retried where safe)."""


class DeadlineExceededError(ShapeidError, TimeoutError):
    """The call's deadline passed; the server stops its work."""


class CancelledError(ShapeidError):
    """The call was cancelled (by a server that shut down before serving it)."""


class AbortedError(ShapeidError):
    """A write kept colliding with writes through other replicas: retry the call."""


class DataLossError(ShapeidError):
    """An import whose export is damaged or truncated."""


class UnimplementedError(ShapeidError):
    """The server does not know the call (an older release)."""


_BY_CODE = {
    grpc.StatusCode.INVALID_ARGUMENT: InvalidArgumentError,
    grpc.StatusCode.NOT_FOUND: NotFoundError,
    grpc.StatusCode.ALREADY_EXISTS: AlreadyExistsError,
    grpc.StatusCode.FAILED_PRECONDITION: FailedPreconditionError,
    grpc.StatusCode.RESOURCE_EXHAUSTED: ResourceExhaustedError,
    grpc.StatusCode.PERMISSION_DENIED: PermissionDeniedError,
    grpc.StatusCode.UNAUTHENTICATED: UnauthenticatedError,
    grpc.StatusCode.UNAVAILABLE: UnavailableError,
    grpc.StatusCode.DEADLINE_EXCEEDED: DeadlineExceededError,
    grpc.StatusCode.CANCELLED: CancelledError,
    grpc.StatusCode.ABORTED: AbortedError,
    grpc.StatusCode.DATA_LOSS: DataLossError,
    grpc.StatusCode.UNIMPLEMENTED: UnimplementedError,
}


def error_for(code, message):
    """The ShapeidError subclass instance for `code` (ShapeidError itself for other codes)."""
    return _BY_CODE.get(code, ShapeidError)(code, message)


# gRPC's words for a message over a receive limit, the client's or the server's.
_TOO_LARGE = re.compile(r"Received message larger than max \((\d+) vs\. (\d+)\)")


def from_rpc_error(error, receive_limit=None):
    """A grpc.RpcError (what grpcio raises) as the matching ShapeidError. gRPC words this
    client's refusal of an answer over its `receive_limit` as a server words its refusal of
    a request too large for it; the limit in the message tells them apart, and this client's
    own refusal says so (ResourceExhaustedError.client_limit)."""
    code = error.code() if hasattr(error, "code") else grpc.StatusCode.UNKNOWN
    message = error.details() if hasattr(error, "details") else str(error)
    if code == grpc.StatusCode.RESOURCE_EXHAUSTED and receive_limit is not None:
        match = _TOO_LARGE.fullmatch(message or "")
        if match and int(match.group(2)) == receive_limit:
            return ResourceExhaustedError(
                code, "the server's answer is %s bytes, more than this client's receive limit "
                      "of %s bytes: this client refused it, not the server; ask for less (a "
                      "smaller page, fewer neighbors)" % match.groups(), client_limit=True)
    return error_for(code or grpc.StatusCode.UNKNOWN, message or "")
