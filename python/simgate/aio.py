"""The asyncio API: the same connection, its calls awaited.

    async with await simgate.aio.connect("ws://127.0.0.1:8090/") as sim:
        await sim.pause()
        print(await sim.robot.motion.set_speed(v=0.5, w=0.2))
        goto = sim.robot.waypoint.goto.options(progress=print)(x=2, y=0, z=0)
        print(await goto)        # task.cancel() / goto.cancel() sends rpc.cancel
        async for sample in await sim.subscribe("robot.pose"):
            ...

`AsyncClient` wraps a `simgate.Client`: the reader thread and the futures are the blocking
API's; every call is that `Call` wrapped by `asyncio.wrap_future` (cancelling the asyncio
future cancels the call on the server). Progress callbacks given to ``.options(progress=)``
run in the event loop. Connecting and discovery run in the default executor.
"""

from __future__ import annotations

import asyncio
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence

from ._services import Namespace, ServiceInfo
from ._world_control import _WorldControl
from .call import Call
from .client import DEFAULT_TIMEOUT, Client
from .streams import Subscription


class _Awaitable:
    """The asyncio adapter: calls as asyncio futures, callbacks into the loop."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop

    def result(self, call: Call) -> "asyncio.Future[Any]":
        return asyncio.wrap_future(call, loop=self._loop)

    def callback(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        return lambda data: self._loop.call_soon_threadsafe(fn, data)


async def connect(url: str, token: Optional[str] = None,
                  timeout: float = DEFAULT_TIMEOUT) -> "AsyncClient":
    """`simgate.connect` for asyncio: connects (and logs in) without blocking the loop."""
    loop = asyncio.get_running_loop()
    client = await loop.run_in_executor(None, lambda: Client(url, token=token, timeout=timeout))
    return AsyncClient(client, loop)


class AsyncClient(_WorldControl):
    """A `simgate.Client` seen from asyncio: services, world control and images are
    awaitables; `subscribe` gives a `Subscription` to read with ``async for``.
    An async context manager (``async with``) that closes the connection."""

    def __init__(self, client: Client, loop: asyncio.AbstractEventLoop) -> None:
        self.client = client  # the blocking client underneath (same connection)
        self._loop = loop
        self._adapter = _Awaitable(loop)
        self._root = Namespace(client, "", self._adapter)

    def _submit(self, component: str, service: str, args: Sequence[Any] = (),
                kwargs: Optional[Dict[str, Any]] = None, **options: Any) -> Call:
        return self.client._submit(component, service, args, kwargs, **options)

    async def _finish(self, call: Call, post: Optional[Callable[[Any], Any]] = None) -> Any:
        result = await asyncio.wrap_future(call, loop=self._loop)
        return post(result) if post else result

    async def call(self, component: str, service: str, *args: Any, **kwargs: Any) -> Any:
        """`Client.call`, awaited."""
        return await self._finish(self._submit(component, service, args, kwargs))

    def submit(self, component: str, service: str, args: Sequence[Any] = (),
               kwargs: Optional[Mapping[str, Any]] = None, *, deadline: Optional[float] = None,
               progress: Optional[Callable[[Any], None]] = None) -> "asyncio.Future[Any]":
        """`Client.submit` as an asyncio future (`progress` called in the loop)."""
        return self._adapter.result(self.client._submit(
            component, service, args, dict(kwargs or {}), deadline=deadline,
            progress=self._adapter.callback(progress) if progress else None))

    async def subscribe(self, component: str, buffer: int = 64) -> Subscription:
        """`Client.subscribe`, awaited: read the subscription with ``async for``."""
        return await self._finish(self.client._wire.subscribe(self.client, component, buffer))

    async def publish(self, component: str, data: Mapping[str, Any]) -> Optional[bool]:
        """`Client.publish`, awaited."""
        return await self._finish(self.client._wire.publish(self.client, component, data))

    async def services(self) -> Dict[str, ServiceInfo]:
        """`Client.services`, fetched in the executor the first time."""
        return await self._loop.run_in_executor(None, lambda: self.client.services)

    def component(self, name: str) -> Namespace:
        return self.client._namespace_for(name, self._adapter)

    def __getattr__(self, name: str) -> Any:
        # discovery happens on first use; it blocks for one round trip (await services()
        # first to keep even that off the loop)
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._root, name)

    @property
    def streams(self) -> List[Dict[str, Any]]:
        return self.client.streams

    async def close(self) -> None:
        await self._loop.run_in_executor(None, self.client.close)

    async def __aenter__(self) -> "AsyncClient":
        return self

    async def __aexit__(self, *exc: Any) -> None:
        await self.close()
