"""Data streams: a subscription to a sensor's samples (docs/streams.md).

A `Subscription` keeps the latest `buffer` samples it has not handed out yet (the oldest is
dropped, and counted in `dropped`, when a new one finds the buffer full: a slow reader loses
samples, never slows the connection). Read it by iterating (``for sample in sub``, or
``async for``), with `get(timeout)`, or only look at the newest with `latest()`. It ends
when closed (`close()`, the connection's end) or when the server ends it (its component was
deleted); iteration then stops.
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import threading
import time
from typing import Any, Callable, Deque, Iterator, List, Mapping, NamedTuple, Optional

from .errors import ConnectionClosed


class Sample(NamedTuple):
    """One sample: the stream's `component`, its number `seq` (from 1), the simulated `time`
    and the component's `data` (its ``get_local_data``)."""

    component: str
    seq: int
    time: Optional[float]
    data: Any


class Subscription:
    """The samples of one output stream. Thread-safe; samples arrive on the reader thread."""

    def __init__(self, component: str, stream: Mapping[str, Any], buffer: int,
                 unsubscribe: Callable[[], None]) -> None:
        if buffer < 1:
            raise ValueError(f"subscribe({component!r}): buffer must be at least 1, found {buffer}")
        self.component = component
        self.stream = dict(stream)  # {component, direction, kind, type, frequency}
        self.dropped = 0  # samples dropped because the buffer was full
        self._unsubscribe = unsubscribe
        self._lock = threading.Lock()
        self._samples: Deque[Sample] = collections.deque(maxlen=buffer)
        self._latest: Optional[Sample] = None
        self._ended: Optional[BaseException] = None  # why no sample will come anymore
        self._waiters: List[concurrent.futures.Future] = []

    # --- fed by the connection (reader thread)
    def _push(self, sample: Sample) -> None:
        with self._lock:
            if self._ended is not None:
                return
            if len(self._samples) == self._samples.maxlen:
                self.dropped += 1
            self._samples.append(sample)
            self._latest = sample
            self._wake()

    def _end(self, reason: BaseException) -> None:
        with self._lock:
            if self._ended is None:
                self._ended = reason
            self._wake()

    def _wake(self) -> None:
        waiters, self._waiters = self._waiters, []
        for w in waiters:
            if not w.done():  # an asyncio reader that gave up cancelled its waiter
                w.set_result(None)

    def _waiter(self) -> concurrent.futures.Future:
        """A future done once a sample is buffered or the subscription ended (it consumes
        nothing, so a reader that gives up waiting loses no sample)."""
        w: concurrent.futures.Future = concurrent.futures.Future()
        if self._samples or self._ended is not None:
            w.set_result(None)
        else:
            self._waiters.append(w)
        return w

    def _take(self) -> Optional[Sample]:
        """The oldest buffered sample; None when there is none yet; raises at the end."""
        with self._lock:
            if self._samples:
                return self._samples.popleft()
            if self._ended is not None:
                raise self._ended
            return None

    # --- public
    @property
    def closed(self) -> bool:
        return self._ended is not None

    def get(self, timeout: Optional[float] = None) -> Sample:
        """The next sample (oldest first), waiting at most `timeout` seconds for one.

        Raises `TimeoutError` when none came in time, `StopIteration` once the subscription
        was closed or ended by the server, `ConnectionClosed` when the connection ended."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            sample = self._take()
            if sample is not None:
                return sample
            with self._lock:
                waiter = self._waiter()
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                waiter.result(left)
            except concurrent.futures.TimeoutError:
                raise TimeoutError(f"{self.component}: no sample within {timeout} s") from None

    def latest(self, timeout: Optional[float] = None) -> Optional[Sample]:
        """The newest sample received (consumed or not); if none came yet, waits up to
        `timeout` seconds for the first (None: does not wait). None when there is none."""
        if self._latest is None and timeout:
            deadline = time.monotonic() + timeout
            while self._latest is None and self._ended is None and time.monotonic() < deadline:
                with self._lock:
                    waiter = self._waiter()
                try:
                    waiter.result(max(0.0, deadline - time.monotonic()))
                except concurrent.futures.TimeoutError:
                    break
        return self._latest

    def __iter__(self) -> Iterator[Sample]:
        return self

    def __next__(self) -> Sample:
        return self.get()

    def __aiter__(self) -> "Subscription":
        return self

    async def __anext__(self) -> Sample:
        while True:
            try:
                sample = self._take()
            except StopIteration:
                raise StopAsyncIteration from None
            if sample is not None:
                return sample
            with self._lock:
                waiter = self._waiter()
            await asyncio.wrap_future(waiter)

    def close(self) -> None:
        """Unsubscribe; iteration stops once the samples already buffered are read."""
        if self._ended is None:
            self._end(StopIteration())
            try:
                self._unsubscribe()
            except ConnectionClosed:
                pass

    def __enter__(self) -> "Subscription":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self.closed else "open"
        return f"<simgate subscription {self.component} ({state}, {len(self._samples)} buffered)>"
