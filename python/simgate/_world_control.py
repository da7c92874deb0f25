"""World control shared by every API: `_WorldControl`'s helpers (pause, step, reset, save and
restore, spawn and delete, images), each one call of the ``simulation`` component (or the
camera's). How a call is handed back is the subclass's business: `Client` waits for it,
`simgate.aio.AsyncClient` awaits it, `Batch` returns its `Call` (`simgate.batch`).
"""

from __future__ import annotations

from typing import Any, Callable, Dict, Mapping, Optional, Sequence

from .call import Call
from .images import decode_image


class _WorldControl:
    """World-control and camera helpers (docs/world/): each submits one call of the
    ``simulation`` component (or the camera's) and hands it to `_finish`, which waits for it
    (`Client`), awaits it (`AsyncClient`) or returns the `Call` (`Batch`)."""

    def _submit(self, component: str, service: str, args: Sequence[Any] = (),
                kwargs: Optional[Dict[str, Any]] = None, **options: Any) -> Call:
        raise NotImplementedError

    def _finish(self, call: Call, post: Optional[Callable[[Any], Any]] = None) -> Any:
        raise NotImplementedError

    def _sim(self, service: str, post: Optional[Callable[[Any], Any]] = None, **kwargs: Any) -> Any:
        return self._finish(self._submit("simulation", service, (), kwargs), post)

    def pause(self) -> Any:
        """Stop time and physics (``simulation.pause``); requests are still served."""
        return self._sim("pause")

    def play(self) -> Any:
        """Resume time and physics at the real-time factor (``simulation.play``)."""
        return self._sim("play")

    def step(self, n: int = 1) -> Any:
        """Take `n` physics steps of a paused simulation (``simulation.step``); returns
        ``{"sim_time", "steps_done"}`` once they are taken."""
        return self._sim("step", n=n)

    def reset(self, scope: str = "all", robot: str = "") -> Any:
        """``simulation.reset``: scope ``"all"`` (objects and time), ``"state"`` (objects),
        ``"robot"`` (the robot named `robot`)."""
        return self._sim("reset", scope=scope, robot=robot)

    def save_state(self) -> Any:
        """Keep the whole simulation state in memory (``simulation.save_state``); returns its
        handle for `restore_state`."""
        return self._sim("save_state")

    def restore_state(self, handle: int) -> Any:
        """Go back to a saved state (``simulation.restore_state``); returns ``{"sim_time",
        "exact", "missing", "kept"}``."""
        return self._sim("restore_state", handle=handle)

    def drop_state(self, handle: int) -> Any:
        """Forget a saved state (``simulation.drop_state``)."""
        return self._sim("drop_state", handle=handle)

    def state(self) -> Any:
        """``simulation.get_simulation_state``: state, sim_time, steps, timestep, ..."""
        return self._sim("get_simulation_state")

    def spawn(self, name: str, mjcf: str, pose: Sequence[float],
              robot: Optional[Mapping[str, Any]] = None) -> Any:
        """Add an MJCF (or URDF) body to the world as `name` at `pose` ([x, y, z] or with
        [qx, qy, qz, qw]); `robot` makes it a robot with components
        (``simulation.spawn_entity``, docs/world/spawn.md)."""
        kwargs: Dict[str, Any] = {"name": name, "mjcf": mjcf, "pose": list(pose)}
        if robot is not None:
            kwargs["robot"] = dict(robot)
        return self._sim("spawn_entity", **kwargs)

    def delete(self, name: str) -> Any:
        """Remove an entity, a body of the scene or a robot (``simulation.delete_entity``)."""
        return self._sim("delete_entity", name=name)

    def get_image(self, camera: str, numpy_arrays: Optional[bool] = None) -> Any:
        """An image of the current state from camera component `camera` (``get_image``),
        decoded: RGB ``uint8 HxWx3`` or depth ``float32 HxW`` metres (`simgate.images`)."""
        return self._finish(self._submit(camera, "get_image"),
                            lambda record: decode_image(record, numpy_arrays))

    def capture(self, camera: str, n: int = 1, numpy_arrays: Optional[bool] = None) -> Any:
        """The next `n` images of camera `camera` (``capture``), decoded, in a list."""
        return self._finish(self._submit(camera, "capture", (), {"n": n}),
                            lambda records: [decode_image(r, numpy_arrays) for r in records])

    def snapshot(self, camera: str = "", width: int = 640, height: int = 480,
                 numpy_arrays: Optional[bool] = None) -> Any:
        """A picture of the scene (``simulation.get_snapshot``), decoded as an RGB image."""
        return self._finish(self._submit("simulation", "get_snapshot", (),
                                         {"camera": camera, "width": width, "height": height}),
                            lambda record: decode_image(record, numpy_arrays))
