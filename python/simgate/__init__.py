"""simgate: a Python client for the simgate robotics simulator (docs/python.md).

    import simgate
    with simgate.connect("jsonrpc://127.0.0.1:4001") as sim:
        sim.pause()
        sim.robot.motion.set_speed(v=0.5, w=0.2)
        print(sim.step(100), sim.robot.pose.get_local_data())

`connect` speaks JSON-RPC over TCP (``jsonrpc://``), JSON-RPC over WebSocket (``ws://``) and
MORSE's socket protocol (``socket://``); `simgate.aio.connect` is the asyncio API over the
same connection code.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

from .call import Call
from .batch import Batch
from .client import DEFAULT_TIMEOUT, Client
from .errors import (Busy, Cancelled, ConnectionClosed, DeadlineExceeded, InvalidArguments,
                     MethodNotFound, NotAuthorized, Overloaded, Preempted, ProtocolError,
                     ServiceError, ServiceFailed, SimgateError)
from .images import RawImage, decode_image
from .streams import Sample, Subscription

if TYPE_CHECKING:
    from .aio import AsyncClient

__version__ = "0.1.0"

__all__ = ["connect", "connect_async", "Client", "Call", "Batch", "Subscription", "Sample",
           "RawImage", "decode_image", "SimgateError", "ConnectionClosed", "ServiceError",
           "ServiceFailed", "InvalidArguments", "MethodNotFound", "Preempted", "Cancelled",
           "DeadlineExceeded", "Busy", "NotAuthorized", "Overloaded", "ProtocolError"]


def connect(url: str, token: Optional[str] = None, timeout: float = DEFAULT_TIMEOUT) -> Client:
    """Connect to a simgate at `url`: ``jsonrpc://HOST:PORT``, ``ws://HOST:PORT[/PATH]`` or
    ``socket://HOST:PORT``. `token`: the transport's ``auth`` token (sent as ``rpc.login``,
    in the WebSocket upgrade, or as the socket's ``auth`` line). `timeout` (seconds) bounds
    connecting, discovery and the wait for each synchronous service's reply.
    Raises `ConnectionClosed` when the server cannot be reached."""
    return Client(url, token=token, timeout=timeout)


async def connect_async(url: str, token: Optional[str] = None,
                        timeout: float = DEFAULT_TIMEOUT) -> "AsyncClient":
    """`simgate.aio.connect`: the asyncio API."""
    from . import aio
    return await aio.connect(url, token=token, timeout=timeout)
