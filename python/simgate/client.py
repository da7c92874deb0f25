"""The connection to a simgate, and the blocking API on it.

One `Client` is one TCP connection, served by one reader thread: every call is a `Call` (a
`concurrent.futures.Future`) registered under its id before its request is written (a
`call_many` batch, a `_Many` under each of its ids); the reader thread reads each message the
server sends and completes the call it answers, hands progress reports to their call and
samples to their subscription. Everything else (the attributes built from discovery, the
world-control helpers in `simgate._world_control`, the batches in `simgate.batch`, the asyncio
API in `simgate.aio`) submits calls and waits on these futures: there is one protocol
implementation.

What differs between JSON-RPC (``jsonrpc://``, ``ws://``) and MORSE's protocol (``socket://``)
is in the wires (`simgate._wires`); how bytes travel, in the transports (`simgate._transport`).

Callbacks (progress, `Future.add_done_callback`) run on the reader thread: they must not
block, and must not wait for another call's result.
"""

from __future__ import annotations

import concurrent.futures
import json
import logging
import math
import threading
import time
import urllib.parse
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

from . import errors
from ._services import Adapter, Namespace, ServiceInfo, ServiceMethod, did_you_mean
from ._transport import LineTransport, WebSocketTransport, wait_readable
from ._wires import JsonRpcWire, JsonText, MorseWire
from ._world_control import _WorldControl
from .batch import Batch, _Many
from .call import Call
from .errors import ConnectionClosed
from .streams import Sample, Subscription

log = logging.getLogger("simgate")

DEFAULT_TIMEOUT = 30.0
_Pending = Union[Call, _Many]  # what waits for replies, by id
_DISCOVERY_ERRORS = (errors.SimgateError, OSError, TimeoutError)


class _Blocking:
    """The blocking API's adapter: a sync service's result, an async service's `Call`."""

    def __init__(self, client: "Client") -> None:
        self._client = client

    def result(self, call: Call) -> Any:
        return call if call.is_async else self._client._wait(call)

    def callback(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        return fn


class Client(_WorldControl):
    """A connection to a simgate (made by `simgate.connect`): services as attributes,
    world control, streams. Thread-safe. A context manager: leaving it closes the connection.

    Attribute access (``sim.robot.motion.set_speed``) uses the services the server lists
    (``rpc.discover``, or ``simulation list_services`` on ``socket://``), fetched on first use;
    `refresh()` fetches them again (after a spawn). A name that is neither a service nor a
    component raises `AttributeError` with the nearest names. Methods of this class win over
    a component of the same name: reach that one with `component(name)`.
    """

    def __init__(self, url: str, token: Optional[str] = None, timeout: float = DEFAULT_TIMEOUT) -> None:
        parts = urllib.parse.urlsplit(url)
        if parts.scheme not in ("jsonrpc", "ws", "socket") or not parts.hostname or not parts.port:
            raise ValueError(f"simgate.connect: {url!r}: expected jsonrpc://HOST:PORT, "
                             "ws://HOST:PORT[/PATH] or socket://HOST:PORT")
        self.url = url
        self.scheme = parts.scheme
        self.host: str = parts.hostname
        self.port: int = parts.port
        self.timeout = timeout
        self._token = token
        self._lock = threading.Lock()
        self._read_lock = threading.RLock()  # the read role (see _read); reentrant for callbacks
        self._role_cond = threading.Condition()  # guards the counters below; signals releases
        self._role_releases = 0  # how many times the read role was given up
        self._role_waiters = 0  # callers waiting for the role or their call
        self._last_caller_read = 0.0  # time.monotonic() when a caller last held the role
        self._pending: Dict[Any, _Pending] = {}
        self._subscriptions: Dict[Any, Subscription] = {}
        self._morse_streams: List[Subscription] = []
        self._closed_reason: Optional[str] = None
        self._services: Optional[Dict[str, ServiceInfo]] = None
        self._streams: List[Dict[str, Any]] = []
        self._discover_lock = threading.Lock()
        self._root = Namespace(self, "", _Blocking(self))
        if parts.scheme == "ws":
            path = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
            self._transport: Any = WebSocketTransport(self.host, self.port, path, timeout, token)
            self._wire: Any = JsonRpcWire()
        else:
            self._transport = LineTransport(self.host, self.port, timeout)
            self._wire = JsonRpcWire() if parts.scheme == "jsonrpc" else MorseWire()
            if token is not None and parts.scheme == "socket":
                self._morse_login(token)
        self._reader = threading.Thread(target=self._read, name=f"simgate-reader {url}", daemon=True)
        self._reader.start()
        if token is not None and parts.scheme == "jsonrpc":
            try:
                self._wire.login(self, token)
            except BaseException:
                self.close()
                raise

    def _morse_login(self, token: str) -> None:
        self._transport.send(f"auth {token}".encode())
        reply = self._transport.receive()
        if reply is None or not reply.decode("utf-8", "replace").startswith("auth ") or \
                reply.split(b" ", 2)[1] not in (b"SUCCESS", b"OK"):
            self._transport.close()
            raise errors.NotAuthorized(f"{self.url}: the token was refused: {reply!r}")

    # ---- reading: the read role
    # One thread at a time reads the connection: the one holding `_read_lock`. A thread
    # blocked on a call's result (`Call.result`, `_read_for`) takes the role when it is free
    # and reads until its call is done: its reply costs no hand-off between threads. The
    # reader thread reads whenever no caller has read for `_STANDBY` seconds (so it does not
    # wake at each reply of a caller stepping in a loop): what arrives for nobody's waiting
    # call (progress, samples, a reply awaited through asyncio) is handled by the next
    # caller to read, or by the reader thread within `_STANDBY`. Whoever reads handles every
    # message it reads, and leaves the buffer with no whole message in it when it gives the
    # role up, so that what is left to read keeps the socket readable for the reader thread.
    _STANDBY = 0.005

    def _read(self) -> None:
        transport = self._transport
        reason = None
        try:
            while reason is None:
                self._stand_aside()
                wait_readable(transport._sock, None)
                self._read_lock.acquire()
                try:
                    if not transport.fill(0):
                        reason = self._end_reason()
                    self._drain()
                finally:
                    self._give_role(False)
        except Exception as e:  # noqa: BLE001 - the connection ends, saying why
            reason = f"the connection was lost: {e}"
        self._shut(reason)

    def _stand_aside(self) -> None:
        """Wait until no caller has read for `_STANDBY` seconds (or the client closes)."""
        with self._role_cond:
            while self._closed_reason is None:
                idle = time.monotonic() - self._last_caller_read
                if idle >= self._STANDBY:
                    return
                self._role_cond.wait(self._STANDBY - idle)

    def _give_role(self, by_caller: bool) -> None:
        if by_caller:
            self._last_caller_read = time.monotonic()
        self._read_lock.release()
        with self._role_cond:
            self._role_releases += 1
            if self._role_waiters:
                self._role_cond.notify_all()

    def _wake_role_waiters(self, _call: Any = None) -> None:
        with self._role_cond:
            self._role_cond.notify_all()

    def _read_for(self, call: _Pending, deadline: Optional[float]) -> None:
        """Read on this thread until `call` is done or `deadline` (time.monotonic()) passes.
        While another thread reads, wait until it completes the call or gives the role up."""
        if self._read_lock.acquire(blocking=False):
            self._read_holding(call, deadline)
            return
        call.add_done_callback(self._wake_role_waiters)
        with self._role_cond:
            self._role_waiters += 1
        try:
            while not call.done():
                with self._role_cond:
                    releases = self._role_releases
                if self._read_lock.acquire(blocking=False):
                    self._read_holding(call, deadline)
                    return
                with self._role_cond:
                    while releases == self._role_releases and not call.done() \
                            and self._closed_reason is None:
                        timeout = None if deadline is None else deadline - time.monotonic()
                        if timeout is not None and timeout <= 0:
                            return
                        self._role_cond.wait(timeout)
                    if self._closed_reason is not None:
                        return
        finally:
            with self._role_cond:
                self._role_waiters -= 1

    def _read_holding(self, call: _Pending, deadline: Optional[float]) -> None:
        """`_read_for` with the read role taken: read until `call` is done or `deadline`."""
        self._last_caller_read = time.monotonic()
        transport = self._transport
        reason = None
        try:
            message = transport.take()
            while not call.done():
                if message is not None:
                    self._handle(message)
                else:
                    timeout = None if deadline is None else deadline - time.monotonic()
                    if timeout is not None and timeout <= 0:
                        break
                    if not transport.fill(timeout):
                        reason = self._end_reason()
                        break
                message = transport.take()
            if message is not None:
                self._handle(message)
                self._drain()
        except Exception as e:  # noqa: BLE001 - the connection ends, saying why
            reason = f"the connection was lost: {e}"
        finally:
            self._give_role(True)
        if reason is not None:
            self._transport.close()
            self._shut(reason)

    def _drain(self) -> None:
        """Handle every whole message the buffer holds (the read lock held)."""
        while True:
            message = self._transport.take()
            if message is None:
                return
            self._handle(message)

    def _handle(self, message: bytes) -> None:
        if not message or message.isspace():
            return
        try:
            self._wire.handle(self, message)
        except Exception:  # a message we cannot read must not end the connection
            log.exception("simgate: could not handle a message from %s: %r", self.url, message[:200])

    def _end_reason(self) -> str:
        error = self._transport.error
        return "the server closed the connection" if error is None else f"the connection was lost: {error}"

    def _shut(self, reason: str) -> None:
        with self._lock:
            if self._closed_reason is None:
                self._closed_reason = reason
            pending, self._pending = self._pending, {}
            subscriptions, self._subscriptions = list(self._subscriptions.values()), {}
        self._wake_role_waiters()
        message = f"{self.url}: {self._closed_reason}"
        for call in pending.values():
            if not call.done():
                call.set_exception(ConnectionClosed(f"{call.method}: {message}"))
        for sub in subscriptions + self._morse_streams:
            sub._end(ConnectionClosed(message))

    def _complete(self, ident: Any, result: Any, error: Any) -> None:
        """Complete the call a reply answers (``error`` None: it succeeded)."""
        self._complete_all(((ident, result, error),))

    def _complete_all(self, replies: Sequence[Tuple[Any, Any, Any]]) -> None:
        """Complete the calls replies ``(id, result, error)`` answer, taken from the pending
        calls under one lock (a batch's replies come in one message)."""
        with self._lock:  # (the pending calls read under it: _shut swaps them)
            pending = self._pending
            calls = [pending.pop(reply[0], None) for reply in replies]
        for call, (ident, result, error) in zip(calls, replies):
            if call is None:
                log.debug("simgate: a reply to no pending call (id %r)", ident)
            elif isinstance(call, _Many):
                call._reply(ident, result, error)
            elif error is not None:
                call.set_exception(self._wire.error(call, error))
            else:
                try:
                    call.set_result(call._hook(result) if call._hook else result)
                except Exception as e:  # noqa: BLE001 - a result the hook could not read
                    call.set_exception(e)

    def _take_batch(self, ids: List[Any]) -> Optional["_Many"]:
        """The pending `call_many` batch whose ids are `ids`, in order, taken from the pending
        calls; None when they are not one batch's."""
        with self._lock:
            pending = self._pending
            many = pending.get(ids[0])
            if not isinstance(many, _Many) or many.ids != ids:
                return None
            for ident in ids:
                del pending[ident]
        return many

    def _progress(self, ident: Any, data: Any) -> None:
        with self._lock:
            call = self._pending.get(ident)
        if call is not None:
            call._report(data)

    def _sample(self, number: Any, sample: Sample) -> None:
        sub = self._subscriptions.get(number)
        if sub is not None:
            sub._push(sample)

    def _stream_ended(self, number: Any, reason: str) -> None:
        sub = self._subscriptions.pop(number, None)
        if sub is not None:
            sub._end(StopIteration(reason))

    # ---- submitting
    def _register(self, call: Call) -> Call:
        with self._lock:
            if self._closed_reason is not None:
                raise ConnectionClosed(f"{call.method}: {self.url}: {self._closed_reason}")
            call.id = self._wire.new_id()
            self._pending[call.id] = call
        return call

    def _submit(self, component: str, service: str, args: Sequence[Any] = (),
                kwargs: Optional[Dict[str, Any]] = None, *, deadline: Optional[float] = None,
                progress: Optional[Callable[[Any], None]] = None, info: Optional[ServiceInfo] = None,
                hook: Optional[Callable[[Any], Any]] = None,
                batch: Optional[List[bytes]] = None) -> Call:
        """Send one call and return its `Call`; errors before sending (a closed connection,
        arguments that cannot be sent) come back as a failed `Call`, never raised."""
        method = f"{component}.{service}"
        if info is None and self._services is not None:
            info = self._services.get(method)
        call = Call(self, method, info.is_async if info else None)
        call._hook = hook
        try:
            meta: Dict[str, Any] = {}
            if deadline is not None:
                if not deadline > 0 or math.isinf(deadline):
                    raise ValueError(f"{method}: deadline must be a positive number of seconds, found {deadline!r}")
                meta["timeout_ms"] = max(1, math.ceil(deadline * 1000))
            if progress is not None:
                meta["progress"] = True
                call.on_progress(progress)
            params = self._wire.params(args, dict(kwargs or {}), meta, info, method)
            messages = []
            if progress is not None and isinstance(self._wire, MorseWire):
                opt_in = self._wire.progress_request(self)
                if opt_in:
                    messages.append(opt_in)
            self._register(call)
            try:
                messages.append(self._wire.encode(call, component, service, params))
            except BaseException:
                with self._lock:
                    self._pending.pop(call.id, None)
                raise
            if batch is not None:
                batch.extend(messages)
            else:
                self._send(messages)
        except BaseException as e:
            if not call.done():
                call.set_exception(e)
        return call

    def _send(self, messages: List[bytes]) -> None:
        try:
            self._transport.send_many(messages)
        except OSError as e:
            self._transport.close()
            self._shut(f"the connection was lost: {e}")

    def _cancel(self, call: Call) -> bool:
        with self._lock:
            if call.id not in self._pending:
                return False
            call._cancel_sent = True
        self._send([self._wire.encode_cancel(call)])
        return True

    def _wait(self, call: Call, timeout: Optional[float] = ...) -> Any:  # type: ignore[assignment]
        """The call's result: a sync service's within `timeout` (the connection's by default),
        an async service's (or one discovery does not know) whenever it comes."""
        if timeout is ...:
            timeout = self.timeout if call.is_async is False else None
        try:
            return call.result(timeout)
        except concurrent.futures.TimeoutError:
            raise TimeoutError(f"{call.method}: no reply within {timeout} s") from None

    def _finish(self, call: Call, post: Optional[Callable[[Any], Any]] = None) -> Any:
        result = self._wait(call)
        return post(result) if post else result

    # ---- public API
    def call(self, component: str, service: str, *args: Any, **kwargs: Any) -> Any:
        """Call `component`'s `service` with positional or named arguments and wait for its
        result (MORSE's way, and the one ``socket://`` needs no discovery for):
        ``sim.call("robot.motion", "set_speed", 0.5, 0.2)``."""
        return self._wait(self._submit(component, service, args, kwargs))

    def submit(self, component: str, service: str, args: Sequence[Any] = (),
               kwargs: Optional[Mapping[str, Any]] = None, *, deadline: Optional[float] = None,
               progress: Optional[Callable[[Any], None]] = None) -> Call:
        """Send a call without waiting: its `Call`. `deadline` in seconds (not on
        ``socket://``), `progress` a callback for its reports."""
        return self._submit(component, service, args, dict(kwargs or {}),
                            deadline=deadline, progress=progress)

    def batch(self) -> "Batch":
        """Calls sent together when the ``with`` block ends: one JSON-RPC batch (run between
        the same two physics steps, in order) or one write of socket lines. See `Batch`."""
        return Batch(self)

    def call_many(self, requests: Sequence[Tuple[str, str, Any]],
                  timeout: Optional[float] = ...) -> List[Any]:  # type: ignore[assignment]
        """Call several services in one message and return their results, in order, once all
        have come: ``[(component, service, params), ...]``, `params` a dict (named), a list
        (positional), None, or JSON text already encoded (`simgate._wires.JsonText`).

        On ``jsonrpc://`` and ``ws://`` it is one JSON-RPC batch (run between the same two
        physics steps, in order) waited for as one (`_Many`), its replies read at once: the cheapest
        round trip for an action, a step and an observation (what `simgate.gym` does at each
        step). On ``socket://``, one write of lines. When a call failed, its error is raised
        (the first by position) once every reply has come. `timeout` (seconds) bounds the
        wait: the connection's when every service is known to be synchronous, else none."""
        if timeout is ...:
            known = [self.services.get(f"{c}.{s}") if self._services is not None else None
                     for c, s, _ in requests]
            timeout = self.timeout if known and all(i is not None and not i.is_async for i in known) else None
        if not isinstance(self._wire, JsonRpcWire):  # socket://: a call per line
            batch: List[bytes] = []
            requests = [(c, s, json.loads(p) if isinstance(p, JsonText) else p) for c, s, p in requests]
            calls = [self._submit(c, s, p if isinstance(p, (list, tuple)) else (),
                                  p if isinstance(p, dict) else None, batch=batch)
                     for c, s, p in requests]
            self._send(self._wire.encode_batch(batch))
            done = [self._outcome(call, timeout) for call in calls]
            for _, error in done:
                if error is not None:
                    raise error
            return [result for result, _ in done]
        many = _Many(requests)
        with self._lock:
            if self._closed_reason is not None:
                raise ConnectionClosed(f"{many.method}: {self.url}: {self._closed_reason}")
            many.ids = self._wire.new_ids(len(requests))
            self._pending.update(dict.fromkeys(many.ids, many))
        try:
            message = self._wire.encode_many(many.ids, requests)
        except BaseException:
            with self._lock:
                for ident in many.ids:
                    self._pending.pop(ident, None)
            raise
        self._send([message])
        self._read_for(many, None if timeout is None else time.monotonic() + timeout)
        if not many.done():
            if self._closed_reason is not None:  # what _shut is about to say
                raise ConnectionClosed(f"{many.method}: {self.url}: {self._closed_reason}")
            raise TimeoutError(f"{many.method}: no reply within {timeout} s")
        if many.exception is not None:
            raise many.exception
        if many.errors:
            raise many.errors[min(many.errors)]
        return many.results

    def _outcome(self, call: Call, timeout: Optional[float]) -> Tuple[Any, Optional[BaseException]]:
        try:
            return self._wait(call, timeout), None
        except errors.ServiceError as e:
            return None, e

    def subscribe(self, component: str, buffer: int = 64) -> Subscription:
        """Subscribe to `component`'s output stream (docs/streams.md): a `Subscription`
        keeping the latest `buffer` samples not read yet."""
        return self._wait(self._wire.subscribe(self, component, buffer), self.timeout)

    def publish(self, component: str, data: Mapping[str, Any]) -> Optional[bool]:
        """Write a command to `component`'s input stream: ``rpc.publish`` (returns whether it
        was applied at once; a refused one raises `InvalidArguments`), or on ``socket://`` a
        line on its stream port (returns None: MORSE's ports answer nothing)."""
        return self._wait(self._wire.publish(self, component, data), self.timeout)

    def _forget_subscription(self, number: Any) -> None:
        if self._closed_reason is None:
            self._wire.unsubscribe(self, number)

    @property
    def services(self) -> Dict[str, ServiceInfo]:
        """Every service this connection may call, by ``component.service`` (discovered once)."""
        if self._services is None:
            with self._discover_lock:
                if self._services is None:
                    services, self._streams = self._wire.discover(self)
                    self._services = {s.method: s for s in services}
        return self._services

    @property
    def streams(self) -> List[Dict[str, Any]]:
        """The data streams this transport carries (``x-simgate-streams`` / ``list_streams``)."""
        self.services
        return self._streams

    def refresh(self) -> None:
        """Fetch the service list again (after a spawn or a delete of a robot)."""
        with self._discover_lock:
            self._services = None
        self._root = Namespace(self, "", _Blocking(self))
        self.services

    def component(self, name: str) -> Namespace:
        """The component `name` (``"robot.motion"``) as a namespace of its services."""
        return self._namespace_for(name, self._root._adapter)

    def _namespace_for(self, name: str, adapter: Adapter) -> Namespace:
        prefix, _, last = name.rpartition(".")
        found = self._resolve(prefix, last, adapter)
        if not isinstance(found, Namespace):
            raise AttributeError(f"{name!r} is a service, not a component")
        return found

    def _children(self, prefix: str) -> List[str]:
        start = prefix + "." if prefix else ""
        names = set()
        for method in self.services:
            if method.startswith(start):
                names.add(method[len(start):].split(".", 1)[0])
        return sorted(names)

    def _resolve(self, prefix: str, name: str, adapter: Adapter) -> Any:
        full = f"{prefix}.{name}" if prefix else name
        info = self.services.get(full)
        if info is not None:
            return ServiceMethod(self, info, adapter)
        if any(m.startswith(full + ".") for m in self.services):
            return Namespace(self, full, adapter)
        where = f"component {prefix!r}" if prefix else self.url
        raise AttributeError(f"simgate: {where} has no service or component {name!r}"
                             + did_you_mean(name, self._children(prefix)))

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._root, name)

    def __dir__(self) -> List[str]:
        own = list(super().__dir__())
        try:
            return sorted(set(own) | set(self._children("")))
        except _DISCOVERY_ERRORS:
            return own

    @property
    def closed(self) -> bool:
        return self._closed_reason is not None

    def close(self) -> None:
        """Close the connection: calls still pending fail with `ConnectionClosed`,
        subscriptions end. Idempotent."""
        with self._lock:
            if self._closed_reason is None:
                self._closed_reason = "closed by the client"
        self._transport.close()
        self._wake_role_waiters()  # the reader thread standing aside sees the end
        if isinstance(self._wire, MorseWire):
            self._wire.close()
        for sub in list(self._morse_streams):
            sub.close()
        if threading.current_thread() is not self._reader:
            self._reader.join(self.timeout)
        self._shut("closed by the client")

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<simgate.Client {self.url}{' closed' if self.closed else ''}>"

