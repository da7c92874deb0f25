"""The two protocols a `Client` speaks, each as a "wire": how a call, a cancel and a batch
are written, how each message the server sends is dispatched, and how discovery, login and
streams work on it.

- `JsonRpcWire`: JSON-RPC 2.0 (``jsonrpc://`` lines, ``ws://`` WebSocket text messages;
  docs/transports/jsonrpc.md): results, ``rpc.progress`` and ``rpc.sample`` by id.
- `MorseWire`: MORSE's text protocol (``socket://``, docs/transports/socket.md):
  ``<id> <component> <service> [params]`` lines, answered ``<id> SUCCESS|FAILED|PREEMPTED
  [json]``, progress lines after ``simgate progress``, streams on TCP ports of their own.
"""

from __future__ import annotations

import functools
import itertools
import json
import logging
import threading
from json.encoder import encode_basestring_ascii  # type: ignore[attr-defined]
from typing import TYPE_CHECKING, Any, Dict, List, Mapping, Optional, Sequence, Tuple

from . import errors
from ._services import ServiceInfo
from ._transport import LineTransport
from .call import Call
from .errors import ConnectionClosed, ServiceError
from .streams import Sample, Subscription

if TYPE_CHECKING:
    from .client import Client

log = logging.getLogger("simgate")


def _default(o: Any) -> Any:
    if hasattr(o, "tolist"):  # numpy arrays and scalars
        return o.tolist()
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


# what json.dumps(value, separators=(",", ":"), allow_nan=..., default=_default) makes, by
# encoders made once (json.dumps makes one at each call when given options)
_ENCODERS = {allow_nan: json.JSONEncoder(separators=(",", ":"), allow_nan=allow_nan, default=_default).encode
             for allow_nan in (False, True)}


def _json(value: Any, allow_nan: bool) -> str:
    return _ENCODERS[allow_nan](value)


json_string = encode_basestring_ascii  # a str as JSON text, as _json encodes it


@functools.lru_cache(maxsize=1024)
def _method_json(component: str, service: str) -> str:
    """``"component.service"`` as JSON text (kept: a client calls the same few, over and over)."""
    return json_string(f"{component}.{service}")

_DECODER = json.JSONDecoder()


def _loads(message: bytes) -> Any:
    """``json.loads(message)``: the same value or the same error, without its encoding
    detection and whitespace scans when the message is what servers send, one UTF-8 JSON
    object or array with nothing around it."""
    if message[:1] in (b"{", b"[") and message[1:2] != b"\0":  # UTF-8, as json.detect_encoding says
        try:
            text = message.decode("utf-8", "surrogatepass")
            value, end = _DECODER.raw_decode(text)
            if end == len(text):
                return value
        except ValueError:
            pass
    return json.loads(message)


class JsonText(str):
    """Parameters already encoded as JSON text (compact, ASCII, finite numbers: what `_json`
    makes). `Client.call_many` puts them in its JSON-RPC batch as they are (on ``socket://``
    they are decoded back): `simgate.gym` encodes the parts of its step's batch that never
    change once, and the controls with ``repr`` (the text json gives a float)."""

    __slots__ = ()


class JsonRpcWire:
    """JSON-RPC 2.0: one JSON object per message; results, progress and samples by id."""

    scheme_has_deadlines = True

    def __init__(self) -> None:
        self._ids = itertools.count(1)

    def new_id(self) -> int:
        return next(self._ids)

    def new_ids(self, n: int) -> List[int]:
        """`n` new ids, consecutive (the client's lock held)."""
        return list(itertools.islice(self._ids, n))

    def encode(self, call: Call, component: str, service: str, params: Any) -> bytes:
        request: Dict[str, Any] = {"jsonrpc": "2.0", "id": call.id, "method": f"{component}.{service}"}
        if params is not None:
            request["params"] = params
        return _json(request, allow_nan=False).encode()

    def params(self, args: Sequence[Any], kwargs: Dict[str, Any], meta: Dict[str, Any],
               info: Optional[ServiceInfo], method: str) -> Any:
        if meta:
            if args:  # _meta needs named params: name the positional ones from discovery
                if info is None or len(args) > len(info.params):
                    raise TypeError(f"{method}: a deadline or progress needs named arguments "
                                    "(or a service known from discovery)")
                for p, value in zip(info.params, args):
                    if p.name in kwargs:
                        raise TypeError(f"{method}: got multiple values for argument {p.name!r}")
                    kwargs[p.name] = value
            return {**kwargs, "_meta": meta}
        if args and kwargs:
            if info is None:
                raise TypeError(f"{method}: positional and named arguments together need "
                                "the service's parameter names (discovery)")
            named = dict(zip((p.name for p in info.params), args))
            return {**named, **kwargs}
        return kwargs if kwargs else (list(args) if args else None)

    def encode_batch(self, messages: List[bytes]) -> List[bytes]:
        return [b"[" + b",".join(messages) + b"]"]

    def encode_many(self, ids: Sequence[int], requests: Sequence[Tuple[str, str, Any]]) -> bytes:
        """One batch of requests ``(component, service, params)`` under `ids`: the text
        ``_json`` gives the list of their request objects, assembled a request at a time, with
        `JsonText` params as they are."""
        parts = []
        for ident, (component, service, params) in zip(ids, requests):
            method = _method_json(component, service)
            if params is None:
                parts.append('{"jsonrpc":"2.0","id":%d,"method":%s}' % (ident, method))
            else:
                text = params if isinstance(params, JsonText) else _json(params, allow_nan=False)
                parts.append('{"jsonrpc":"2.0","id":%d,"method":%s,"params":%s}' % (ident, method, text))
        return ("[" + ",".join(parts) + "]").encode()

    def encode_cancel(self, call: Call) -> bytes:
        return _json({"jsonrpc": "2.0", "method": "rpc.cancel", "params": {"id": call.id}}, False).encode()

    def handle(self, client: "Client", message: bytes) -> None:
        decoded = _loads(message)
        if isinstance(decoded, list) and decoded:
            try:
                ids = [m.get("id") for m in decoded]
                many = client._take_batch(ids)
            except AttributeError:  # not a list of objects: see below
                many = None
            if many is not None:  # the answer to a call_many batch, in its order
                many._answered(decoded, [m.get("result") for m in decoded])
                return
        replies: List[Tuple[Any, Any, Any]] = []  # completed together (a batch's, one lock)
        for m in decoded if isinstance(decoded, list) else (decoded,):
            if "result" in m or "error" in m:
                ident = m.get("id")
                if ident is None:
                    log.warning("simgate: the server answered a request it could not read: %s",
                                m.get("error"))
                else:
                    replies.append((ident, m.get("result"), m.get("error")))
                continue
            if replies:  # what came before this notification is handled before it
                client._complete_all(replies)
                replies = []
            method, params = m.get("method"), m.get("params") or {}
            if method == "rpc.progress":
                client._progress(params.get("id"), params.get("data"))
            elif method == "rpc.sample":
                client._sample(params.get("subscription"),
                               Sample(params.get("component", ""), params.get("seq", 0),
                                      params.get("time"), params.get("data")))
            elif method == "rpc.unsubscribed":
                client._stream_ended(params.get("subscription"), params.get("reason", ""))
        if replies:
            client._complete_all(replies)

    def error(self, call: Call, error: Any) -> ServiceError:
        return errors.from_jsonrpc(error if isinstance(error, dict) else {"message": str(error)},
                                   call.method)

    def discover(self, client: "Client") -> Tuple[List[ServiceInfo], List[Dict[str, Any]]]:
        doc = client._submit("rpc", "discover", (), {}).result(client.timeout)
        return ([ServiceInfo.from_openrpc(m) for m in doc.get("methods", [])],
                list(doc.get("x-simgate-streams", [])))

    def login(self, client: "Client", token: str) -> None:
        client._submit("rpc", "login", (), {"token": token}).result(client.timeout)

    def subscribe(self, client: "Client", component: str, buffer: int) -> Call:
        def register(result: Any) -> Subscription:
            number = result["subscription"]
            existing = client._subscriptions.get(number)
            if existing is not None and not existing.closed:
                return existing  # the server: the same stream twice is one subscription
            sub = Subscription(component, result.get("stream", {}), buffer,
                               lambda: client._forget_subscription(number))
            client._subscriptions[number] = sub
            return sub
        return client._submit("rpc", "subscribe", (), {"component": component}, hook=register)

    def unsubscribe(self, client: "Client", number: Any) -> None:
        client._subscriptions.pop(number, None)
        client._submit("rpc", "unsubscribe", (), {"subscription": number})

    def publish(self, client: "Client", component: str, data: Mapping[str, Any]) -> Call:
        return client._submit("rpc", "publish", (), {"component": component, "data": dict(data)},
                              hook=lambda r: bool(r.get("applied")) if isinstance(r, dict) else r)


class MorseWire:
    """MORSE's socket protocol: ``<id> <component> <service> [params]`` lines, answered
    ``<id> SUCCESS|FAILED|PREEMPTED [json]``; progress lines after ``simgate progress``;
    streams on TCP ports of their own."""

    scheme_has_deadlines = False

    def __init__(self) -> None:
        self._ids = itertools.count(1)
        self._progress_on = False
        self._ports: Dict[str, int] = {}
        self._inputs: Dict[str, LineTransport] = {}
        self._lock = threading.Lock()

    def new_id(self) -> str:
        return str(next(self._ids))

    def params(self, args: Sequence[Any], kwargs: Dict[str, Any], meta: Dict[str, Any],
               info: Optional[ServiceInfo], method: str) -> Any:
        if "timeout_ms" in meta:
            raise ValueError(f"{method}: socket:// cannot give a call a deadline (MORSE's lines "
                             "have no place for one: the transport's 'timeouts' option sets them); "
                             "use jsonrpc:// or ws://")
        if args and kwargs:
            raise TypeError(f"{method}: socket:// takes positional or named arguments, not both")
        return kwargs if kwargs else (list(args) if args else None)

    def encode(self, call: Call, component: str, service: str, params: Any) -> bytes:
        line = f"{call.id} {component} {service}"
        if params is not None:
            line += " " + _json(params, allow_nan=True)
        return line.encode()

    def encode_batch(self, messages: List[bytes]) -> List[bytes]:
        return messages

    def encode_cancel(self, call: Call) -> bytes:
        return f"{call.id} cancel".encode()

    def progress_request(self, client: "Client") -> Optional[bytes]:
        """The opt-in line before the first call that wants progress (None afterwards)."""
        with self._lock:
            if self._progress_on:
                return None
            self._progress_on = True
        call = client._register(Call(client, "simgate.progress", False))
        return f"{call.id} simgate progress [true]".encode()

    def handle(self, client: "Client", message: bytes) -> None:
        ident, _, rest = message.decode("utf-8", "replace").partition(" ")
        status, _, value = rest.partition(" ")
        if status == "PROGRESS":
            client._progress(ident, json.loads(value) if value else None)
        elif status in ("SUCCESS", "OK"):
            client._complete(ident, json.loads(value) if value else None, None)
        elif status in ("FAILED", "PREEMPTED"):
            client._complete(ident, None, (status, json.loads(value) if value else None))
        else:
            log.warning("simgate: socket:// line not understood: %r", message[:200])

    def error(self, call: Call, error: Any) -> ServiceError:
        status, value = error
        message = value if isinstance(value, str) else ("" if value is None else json.dumps(value))
        exc = errors.from_socket(status, message, call.method)
        if value is not None and not isinstance(value, str):
            exc.data = {"value": value}
        if status == "PREEMPTED" and call._cancel_sent:
            exc = errors.Cancelled(message or "cancelled by its client", status=status,
                                   data=exc.data, method=call.method)
        return exc

    def discover(self, client: "Client") -> Tuple[List[ServiceInfo], List[Dict[str, Any]]]:
        listed = client._submit("simulation", "list_services", (), {}).result(client.timeout)
        services = [ServiceInfo.from_list_services(s) for s in listed]
        streams: List[Dict[str, Any]] = []
        if any(s.method == "simulation.list_streams" for s in services):
            names = client._submit("simulation", "list_streams", (), {}).result(client.timeout)
            streams = [{"component": n} for n in names]
        return services, streams

    def login(self, client: "Client", token: str) -> None:
        pass  # done on the transport before the reader starts (connect)

    def _open_stream(self, client: "Client", component: str) -> LineTransport:
        """A connection to `component`'s stream port, logged in when the client has a token
        (the port answers nothing: a wrong token only closes it)."""
        transport = LineTransport(client.host, self._port(client, component), client.timeout)
        if client._token is not None:
            transport.send(f"auth {client._token}".encode())
        return transport

    def _port(self, client: "Client", component: str) -> int:
        port = self._ports.get(component)
        if port is None:
            port = client._submit("simulation", "get_stream_port", (component,), {}).result(client.timeout)
            self._ports[component] = port
        return port

    def subscribe(self, client: "Client", component: str, buffer: int) -> Call:
        call = Call(client, "simulation.get_stream_port", False)
        try:
            transport = self._open_stream(client, component)
        except BaseException as e:
            call.set_exception(e)
            return call
        sub = Subscription(component, {"component": component, "direction": "OUT"}, buffer,
                           transport.close)
        client._morse_streams.append(sub)

        def read() -> None:
            seq = 0
            try:
                while True:
                    line = transport.receive()
                    if line is None:
                        break
                    data = json.loads(line)
                    seq += 1
                    sub._push(Sample(component, seq, data.get("timestamp") if isinstance(data, dict) else None, data))
            except Exception as e:  # noqa: BLE001 - the stream ends, saying why
                sub._end(ConnectionClosed(f"{component} stream: {e}"))
            sub._end(StopIteration() if sub.closed or client.closed else
                     ConnectionClosed(f"{component} stream: the server closed its port"))

        threading.Thread(target=read, name=f"simgate-{component}", daemon=True).start()
        call.set_result(sub)
        return call

    def unsubscribe(self, client: "Client", number: Any) -> None:
        pass

    def publish(self, client: "Client", component: str, data: Mapping[str, Any]) -> Call:
        call = Call(client, f"{component} (stream port)", False)
        try:
            with self._lock:
                transport = self._inputs.get(component)
            if transport is None:
                transport = self._open_stream(client, component)
                with self._lock:
                    self._inputs[component] = transport
            transport.send(_json(dict(data), allow_nan=True).encode())
            call.set_result(None)  # MORSE's input ports answer nothing
        except BaseException as e:
            call.set_exception(e)
        return call

    def close(self) -> None:
        with self._lock:
            for t in self._inputs.values():
                t.close()
            self._inputs.clear()
