"""Services as Python attributes: what discovery says of each, and the proxies built on it.

`ServiceInfo` is one service as the server describes it (JSON-RPC's ``rpc.discover``, the
socket transport's ``simulation list_services``: the same facts). `Namespace` turns dotted
names into attributes (``sim.robot.motion`` → component ``robot.motion``) and `ServiceMethod`
is one service, callable, with a real `inspect.signature` and a docstring. How a call's
outcome is handed back (waited for, as a `Call`, as an asyncio future) is the `Adapter`'s
business, so the blocking, the asyncio and the batch APIs share these classes.
"""

from __future__ import annotations

import difflib
import inspect
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Protocol, Tuple

if TYPE_CHECKING:
    from .client import Call, Client

_MISSING = inspect.Parameter.empty
_TYPES: Dict[str, Any] = {"number": float, "integer": int, "string": str, "boolean": bool,
                          "array": list, "object": dict}


@dataclass(frozen=True)
class ParamInfo:
    """One parameter: its name, whether it is required, its default, its JSON schema."""

    name: str
    required: bool
    default: Any = None
    schema: Mapping[str, Any] = field(default_factory=dict)

    @property
    def annotation(self) -> Any:
        return _TYPES.get(self.schema.get("type", ""), Any)


@dataclass(frozen=True)
class ServiceInfo:
    """One service: ``component.name``, its documentation, parameters and kind."""

    component: str
    name: str
    doc: str
    params: Tuple[ParamInfo, ...]
    is_async: bool
    extra: Mapping[str, Any] = field(default_factory=dict)

    @property
    def method(self) -> str:
        return f"{self.component}.{self.name}"

    @classmethod
    def from_openrpc(cls, m: Mapping[str, Any]) -> "ServiceInfo":
        """From a method of ``rpc.discover``'s OpenRPC document."""
        doc = m.get("description") or m.get("summary") or ""
        return cls(m["x-component"], m["x-service"], doc, _params(m.get("params", [])),
                   bool(m.get("x-async")), {k: v for k, v in m.items() if k.startswith("x-")})

    @classmethod
    def from_list_services(cls, s: Mapping[str, Any]) -> "ServiceInfo":
        """From an entry of the socket transport's ``simulation list_services``."""
        return cls(s["component"], s["name"], s.get("doc", ""), _params(s.get("params", [])),
                   bool(s.get("async")))

    def signature(self) -> inspect.Signature:
        params = [inspect.Parameter(p.name, inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                    default=_MISSING if p.required else p.default,
                                    annotation=p.annotation) for p in self.params]
        return inspect.Signature(params)

    def docstring(self) -> str:
        lines = [self.doc or f"simgate service {self.method}.", ""]
        for p in self.params:
            kind = p.schema.get("type", "any JSON value")
            lines.append(f"    {p.name} ({kind}" + (")" if p.required else f", default {p.default!r})"))
        if self.is_async:
            lines += ["", "Asynchronous service: returns a `simgate.Call` (a future: `.result()`, "
                      "`.cancel()`, progress reports); `.options(deadline=, progress=)` sets them."]
        return "\n".join(lines).rstrip() + f"\n\nsimgate method: {self.method}"


def _params(raw: List[Mapping[str, Any]]) -> Tuple[ParamInfo, ...]:
    out = []
    for p in raw:
        schema = p.get("schema") or {}
        # rpc.discover puts the default in the schema, list_services beside it
        default = p["default"] if "default" in p else schema.get("default")
        out.append(ParamInfo(p["name"], bool(p.get("required")), default, schema))
    return tuple(out)


class Adapter(Protocol):
    """How a proxy hands back a call it submitted (blocking, asyncio, batch)."""

    def result(self, call: "Call") -> Any: ...

    def callback(self, fn: Callable[[Any], None]) -> Callable[[Any], None]: ...


class ServiceMethod:
    """One service, callable as a Python function of its parameters.

    Calling it submits the call and hands the outcome back through the adapter: with the
    blocking API a synchronous service's result (or its `ServiceError`), an asynchronous
    service's `Call`. `submit()` always returns the `Call`; `options()` gives a copy whose
    calls carry a deadline or ask for progress reports.
    """

    def __init__(self, client: "Client", info: ServiceInfo, adapter: Adapter,
                 deadline: Optional[float] = None,
                 progress: Optional[Callable[[Any], None]] = None) -> None:
        self._client = client
        self._adapter = adapter
        self._deadline = deadline
        self._progress = progress
        self.info = info
        self.__name__ = info.name
        self.__qualname__ = info.method
        self.__doc__ = info.docstring()
        self.__signature__ = info.signature()

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self._adapter.result(self.submit(*args, **kwargs))

    def submit(self, *args: Any, **kwargs: Any) -> "Call":
        """Send the call; return its `Call` (a `concurrent.futures.Future`) at once."""
        return self._client._submit(self.info.component, self.info.name, args, kwargs,
                                    deadline=self._deadline, progress=self._progress, info=self.info)

    def options(self, *, deadline: Optional[float] = None,
                progress: Optional[Callable[[Any], None]] = None) -> "ServiceMethod":
        """A copy whose calls have a `deadline` (seconds, sent as ``_meta.timeout_ms``: past it
        the server answers `DeadlineExceeded` and interrupts an async service) and/or report
        `progress` (called with each report's data, on the connection's reader thread, or in
        the event loop with the asyncio API)."""
        return ServiceMethod(self._client, self.info, self._adapter, deadline,
                             self._adapter.callback(progress) if progress else None)

    def __repr__(self) -> str:
        return f"<simgate service {self.info.method}{self.__signature__}>"


class Namespace:
    """A component (or a prefix of components) whose attributes are its services and
    sub-components: ``sim.robot`` → ``sim.robot.motion`` → ``sim.robot.motion.set_speed``."""

    def __init__(self, client: "Client", prefix: str, adapter: Adapter) -> None:
        self._client = client
        self._prefix = prefix
        self._adapter = adapter
        self._cache: Dict[str, Any] = {}

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        found = self._cache.get(name)
        if found is None:
            found = self._cache[name] = self._client._resolve(self._prefix, name, self._adapter)
        return found

    def __dir__(self) -> List[str]:
        return sorted(self._client._children(self._prefix))

    def __repr__(self) -> str:
        return f"<simgate component {self._prefix}: {', '.join(dir(self))}>"


def did_you_mean(name: str, candidates: List[str]) -> str:
    close = difflib.get_close_matches(name, candidates, n=3, cutoff=0.6)
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""
