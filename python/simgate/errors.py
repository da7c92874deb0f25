"""The exceptions of the simgate client.

Every failure a call can end with is a `ServiceError` carrying simgate's own words: `status`
(MORSE's ``FAILED`` / ``PREEMPTED``), `message` (the service's reason), `code` (the JSON-RPC
error code, ``None`` on ``socket://``) and `data` (the error's ``data`` object: ``method``,
``parameter``, ``failure``, ...). Its subclasses say what kind of failure it was, so a caller
can catch just the one it handles. A connection that ends fails every call still pending with
`ConnectionClosed`.
"""

from __future__ import annotations

from typing import Any, Mapping, Optional


class SimgateError(Exception):
    """Base class of every exception this package raises on purpose."""


class ConnectionClosed(SimgateError):
    """The connection to simgate ended (closed by the client or the server, or lost).

    Every call pending on it fails with this exception, naming why the connection ended.
    """


class ServiceError(SimgateError):
    """A call answered with an error.

    Attributes: `status` (``"FAILED"`` or ``"PREEMPTED"``), `message` (the server's reason),
    `code` (JSON-RPC error code; ``None`` on the socket transport), `data` (the error's
    ``data`` object, ``{}`` when there is none), `method` (``"component.service"``).
    """

    def __init__(self, message: str, *, status: str = "FAILED", code: Optional[int] = None,
                 data: Optional[Mapping[str, Any]] = None, method: str = "") -> None:
        super().__init__(f"{method}: {message}" if method and not message.startswith(method) else message)
        self.message = message
        self.status = status
        self.code = code
        self.data: Mapping[str, Any] = dict(data or {})
        self.method = method


class ServiceFailed(ServiceError):
    """The service ran and failed (JSON-RPC -32000, -32603; socket ``FAILED``)."""


class InvalidArguments(ServiceError):
    """The server refused the arguments (JSON-RPC -32602): `data["parameter"]` names the one."""


class MethodNotFound(ServiceError):
    """No such service on this transport (JSON-RPC -32601)."""


class Preempted(ServiceError):
    """The call was interrupted before its end (status ``PREEMPTED``): by a newer call on its
    component (JSON-RPC -32001), by `Cancelled`, or by a pause, play, reset or restore."""


class Cancelled(Preempted):
    """The call was cancelled by its client (`Call.cancel()`; JSON-RPC -32002)."""


class DeadlineExceeded(ServiceError):
    """The call's deadline (or the server's ``max_wait_ms``) passed (JSON-RPC -32003)."""


class Busy(ServiceError):
    """A non-interruptible service already runs on the component (JSON-RPC -32004)."""


class NotAuthorized(ServiceError):
    """The transport wants a token, and none or a wrong one was given (JSON-RPC -32005)."""


class Overloaded(ServiceError):
    """The server refused the call for its limits (JSON-RPC -32006, -32007)."""


class ProtocolError(ServiceError):
    """The server could not read the request (JSON-RPC -32700, -32600): a client bug."""


_BY_CODE = {
    -32700: ProtocolError, -32600: ProtocolError, -32601: MethodNotFound,
    -32602: InvalidArguments, -32603: ServiceFailed, -32000: ServiceFailed,
    -32001: Preempted, -32002: Cancelled, -32003: DeadlineExceeded, -32004: Busy,
    -32005: NotAuthorized, -32006: Overloaded, -32007: Overloaded,
}


def from_jsonrpc(error: Mapping[str, Any], method: str) -> ServiceError:
    """The exception for a JSON-RPC ``error`` object of a call to `method`."""
    code = error.get("code")
    data = error.get("data") if isinstance(error.get("data"), dict) else {}
    cls = _BY_CODE.get(code, ServiceFailed) if isinstance(code, int) else ServiceFailed
    status = data.get("status") or ("PREEMPTED" if issubclass(cls, Preempted) else "FAILED")
    return cls(str(error.get("message", "")), status=status, code=code, data=data, method=method)


# The socket transport has only a status and a sentence: the phrases MORSE clients rely on
# (docs/transports/socket.md, "Error phrases") tell the kinds apart.
_SOCKET_PHRASES = (
    ("wrong # of parameters", InvalidArguments), ("wrong parameter type", InvalidArguments),
    ("parameters expected for service", InvalidArguments),
    ("Invalid request syntax", InvalidArguments),
    ("has not been registered", MethodNotFound), ("is already running", Busy),
    ("no reply within", DeadlineExceeded), ("Authentication required", NotAuthorized),
    ("wrong token", NotAuthorized), ("too many connections", Overloaded),
)


def from_socket(status: str, message: str, method: str) -> ServiceError:
    """The exception for a socket reply ``<id> FAILED "message"`` or ``<id> PREEMPTED``."""
    if status == "PREEMPTED":
        return Preempted(message or "preempted", status=status, method=method)
    cls = next((c for phrase, c in _SOCKET_PHRASES if phrase in message), ServiceFailed)
    return cls(message, status=status, method=method)
