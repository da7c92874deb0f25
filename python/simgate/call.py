"""`Call`: one call in flight, a `concurrent.futures.Future` of its result."""

from __future__ import annotations

import concurrent.futures
import logging
import time
from typing import TYPE_CHECKING, Any, Callable, List, Optional

if TYPE_CHECKING:
    from .client import Client

log = logging.getLogger("simgate")


class Call(concurrent.futures.Future):
    """One call in flight: a `concurrent.futures.Future` of its result.

    `result(timeout)` gives the service's result or raises its `ServiceError`; `cancel()`
    asks the server to cancel it (the call then ends with `Cancelled`, or with its result if
    it finished first); `progress` is its latest progress report and `on_progress(fn)` calls
    `fn(data)` for each report (when the call asked for them: `.options(progress=...)`).
    """

    def __init__(self, client: "Client", method: str, is_async: Optional[bool]) -> None:
        super().__init__()
        self.method = method
        self.is_async = is_async  # None: not known (no discovery)
        self.id: Any = None
        self.progress: Any = None
        self._client = client
        self._progress_callbacks: List[Callable[[Any], None]] = []
        self._cancel_sent = False
        self._hook: Optional[Callable[[Any], Any]] = None  # maps the result, on the reader thread

    def result(self, timeout: Optional[float] = None) -> Any:
        """The service's result, waiting up to `timeout` seconds (None: as long as it takes);
        raises its `ServiceError`, or `concurrent.futures.TimeoutError`.

        While no other thread reads the connection, the calling thread reads it itself until
        the reply comes (handling whatever else arrives meanwhile: other calls' replies,
        progress, samples), which spares a hand-off from the reader thread."""
        if not self.done() and self.id is not None:
            deadline = None if timeout is None else time.monotonic() + timeout
            self._client._read_for(self, deadline)
            if deadline is not None:
                timeout = max(0.0, deadline - time.monotonic())
        return super().result(timeout)

    def on_progress(self, fn: Callable[[Any], None]) -> None:
        """Call `fn(data)` for every progress report from now on (on the reader thread)."""
        with self._condition:
            self._progress_callbacks.append(fn)

    def _report(self, data: Any) -> None:
        with self._condition:
            self.progress = data
            callbacks = list(self._progress_callbacks)
        for fn in callbacks:
            try:
                fn(data)
            except Exception:
                log.exception("simgate: progress callback of %s raised", self.method)

    def cancel(self) -> bool:
        """Ask the server to cancel this call (``rpc.cancel`` / ``<id> cancel``).

        Returns False when the call has ended already, True when the cancel was sent; the
        call then ends as the server says: `Cancelled`, or its result if it had finished.
        (The future itself never enters the cancelled state: its outcome is the server's.)"""
        if self.done() or self.id is None:
            return False
        return self._client._cancel(self)

    def __repr__(self) -> str:
        state = "done" if self.done() else "pending"
        return f"<simgate.Call {self.method} id={self.id!r} {state}>"
