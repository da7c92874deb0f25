"""Batched calls: `Batch` (``with sim.batch() as b:``, calls gathered and sent in one message)
and `_Many` (a `Client.call_many` JSON-RPC batch in flight, waited for as one).

On ``jsonrpc://`` and ``ws://`` both are one JSON-RPC batch, which the server runs between the
same two physics steps, in order; on ``socket://`` the lines go out in one write.
"""

from __future__ import annotations

import concurrent.futures
import logging
import threading
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

from . import errors
from ._services import Namespace
from ._world_control import _WorldControl
from .call import Call

if TYPE_CHECKING:
    from .client import Client

log = logging.getLogger("simgate")


class _Many:
    """A `Client.call_many` JSON-RPC batch in flight: registered under each of its requests'
    ids, done when every reply has come (`results` in the requests' order, None for a call
    that failed, `errors` the failed calls' errors by position) or when the connection ended
    (`exception`).

    Not a `Call`: it is never handed out, and only `call_many` waits for it, reading the
    connection itself (`Client._read_for`), so it has just what that wait and the thread
    that reads need (`done`, `add_done_callback`, `set_exception`): a Future's condition,
    states and notifications were an eighth of the instructions of `simgate.gym`'s step."""

    __slots__ = ("_requests", "ids", "results", "errors", "exception", "_left", "_done", "_callbacks", "_lock")
    is_async = False

    def __init__(self, requests: Sequence[Tuple[str, str, Any]]) -> None:
        self._requests = requests
        self.ids: List[Any] = []
        self.results: List[Any] = [None] * len(requests)
        self.errors: Dict[int, errors.ServiceError] = {}
        self.exception: Optional[BaseException] = None
        self._left = len(requests)
        self._done = False
        self._callbacks: List[Callable[[Any], None]] = []
        self._lock = threading.Lock()  # `_done` and `_callbacks`

    @property
    def methods(self) -> List[str]:
        """The requests' ``component.service``, in order."""
        return [f"{c}.{s}" for c, s, _ in self._requests]

    @property
    def method(self) -> str:
        """What error messages call the batch."""
        return "batch of " + ", ".join(self.methods)

    def done(self) -> bool:
        return self._done

    def add_done_callback(self, fn: Callable[[Any], None]) -> None:
        """Call `fn(self)` once the batch is done (now if it is; else on the thread that
        completes it)."""
        with self._lock:
            if not self._done:
                self._callbacks.append(fn)
                return
        fn(self)

    def set_exception(self, exception: BaseException) -> None:
        """The connection ended before every reply came."""
        self._finish(exception)

    def _finish(self, exception: Optional[BaseException] = None) -> None:
        with self._lock:
            if self._done:
                return
            self.exception = exception
            self._done = True
            callbacks, self._callbacks = self._callbacks, []
        for fn in callbacks:
            try:
                fn(self)
            except Exception:
                log.exception("simgate: a done callback of %s raised", self.method)

    def _report(self, data: Any) -> None:
        """A progress report of one of the batch's calls: nobody listens to them."""

    def _reply(self, ident: Any, result: Any, error: Any) -> None:
        """One reply (on the thread that reads; the replies of one batch come in one message,
        read by one thread)."""
        i = self.ids.index(ident)
        self.results[i] = result
        if error is not None:
            self._failed(i, error)
        self._left -= 1
        if self._left == 0:
            self._finish()

    def _answered(self, replies: List[Dict[str, Any]], results: List[Any]) -> None:
        """Every reply at once: the JSON-RPC response objects, in the requests' order (what
        `Client._take_batch` checked), and their results."""
        self.results = results
        if None in results:  # a failed call has no result
            for i, m in enumerate(replies):
                if m.get("error") is not None:
                    self._failed(i, m["error"])
        self._left = 0
        self._finish()

    def _failed(self, i: int, error: Any) -> None:
        self.errors[i] = errors.from_jsonrpc(error if isinstance(error, dict) else {"message": str(error)},
                                             self.methods[i])

    def __repr__(self) -> str:
        return f"<simgate batch of {len(self._requests)} ids={self.ids!r} {'done' if self._done else 'pending'}>"


class _Deferred:
    """The batch's adapter: every call hands back its `Call`."""

    def result(self, call: Call) -> Any:
        return call

    def callback(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        return fn


class Batch(_WorldControl):
    """Calls gathered and sent in one message when the ``with`` block ends (or at `send()`).

    Inside, every call returns its `Call` at once: ``b.robot.motion.set_speed(v=1, w=0)``,
    ``b.step(1)``, ``b.submit(...)``. On ``jsonrpc://`` and ``ws://`` it is one JSON-RPC batch:
    the server runs its calls between the same two physics steps, in order, and answers when
    the last is done: one round trip for an action, a step and an observation. On
    ``socket://`` the lines go out in one write.
    """

    def __init__(self, client: Client) -> None:
        self._client = client
        self._messages: List[bytes] = []
        self._calls: List[Call] = []
        self._root = Namespace(client, "", _Deferred())
        self._sent = False

    def _submit(self, component: str, service: str, args: Sequence[Any] = (),
                kwargs: Optional[Dict[str, Any]] = None, **options: Any) -> Call:
        if self._sent:
            raise RuntimeError("simgate batch: already sent")
        call = self._client._submit(component, service, args, kwargs, batch=self._messages, **options)
        self._calls.append(call)
        return call

    def _finish(self, call: Call, post: Optional[Callable[[Any], Any]] = None) -> Any:
        if post is None:
            return call
        mapped: concurrent.futures.Future = concurrent.futures.Future()

        def done(f: concurrent.futures.Future) -> None:
            try:
                mapped.set_result(post(f.result()))
            except BaseException as e:  # noqa: BLE001 - handed to the waiter
                mapped.set_exception(e)
        call.add_done_callback(done)
        return mapped

    def submit(self, component: str, service: str, args: Sequence[Any] = (),
               kwargs: Optional[Mapping[str, Any]] = None, **options: Any) -> Call:
        return self._submit(component, service, args, dict(kwargs or {}), **options)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._root, name)

    def send(self) -> None:
        """Send the gathered calls (once); the `Call`s complete as the answers come."""
        if self._sent:
            return
        self._sent = True
        if self._messages:
            self._client._send(self._client._wire.encode_batch(self._messages))

    def __enter__(self) -> "Batch":
        return self

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        if exc_type is None:
            self.send()
            return
        self._sent = True  # nothing was sent: the gathered calls fail
        for call in self._calls:
            with self._client._lock:
                self._client._pending.pop(call.id, None)
            if not call.done():
                call.set_exception(RuntimeError(f"{call.method}: not sent (the batch's with block raised)"))
