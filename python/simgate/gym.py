"""A Gymnasium environment over a simgate: any MJCF model as an RL environment (docs/python.md).

    import gymnasium, simgate.gym
    env = gymnasium.make("simgate/Model-v0", model="cartpole.xml", max_episode_steps=500)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    env.close()

Importing this module registers ``simgate/Model-v0`` (``gymnasium.make("simgate.gym:simgate/Model-v0",
...)`` imports it for you). The environment (`SimgateEnv`) either starts its own ``simgate run``
(``model=FILE.xml`` or ``config=FILE.json``; the executable from ``binary=``, else
``SIMGATE_BIN``, else ``simgate`` on PATH) on ports the kernel picks, or attaches to a running
one (``address="jsonrpc://HOST:PORT"``). Either way the simulation is paused and the
environment joins its lockstep (docs/world/stepping.md): nothing steps the world but
`step()`. A simgate it started is stopped (SIGTERM, then SIGKILL) and reaped by `close()`, or
at interpreter exit. Many worlds of one simgate stepped by one call: `simgate.vector`
(``make_vec(n, vectorization_mode="worlds", ...)``).

Life cycle: the constructor connects, reads what the robots have (``simulation details``:
their ``actuators``, ``armature_pose``, ``sensors`` and ``pose`` components), builds the spaces
and saves the simulation state (``simulation save_state``); `reset()` restores that state
(exact: ``restore_state`` puts back every part of MuJoCo's data the next step reads);
`step(action)` sends the controls, the steps and the observation's reads in one JSON-RPC batch,
which the server runs between the same two physics steps: one round trip.

Spaces (the order of everything is fixed when the environment is made):

- action: a ``Box`` of every actuator of every robot (robots in ``simulation details`` order,
  actuators in MuJoCo's order), bounded by its ``ctrlrange`` (an actuator without one: ±1e6,
  the bound simgate accepts). `action_names` names each element.
- observation (``flat=False``): a ``Dict`` of ``Box``es, float64, keys present when not empty:
  ``joint_pos`` and ``joint_vel`` (every hinge and slide joint of each robot, robots in order,
  joints in MuJoCo's order: rad, m, rad/s, m/s), ``base`` (13 numbers per robot with a floating
  base, i.e. a ``pose`` component: position x y z, orientation quaternion qx qy qz qw,
  linear velocity, angular velocity, all in the world frame), ``sensors`` (each robot's MJCF
  sensors by name, each as many numbers as its dimension). ``flat=True``: one ``Box``, those
  four concatenated in that order. `observation_names` names each element of the flat vector.
"""

from __future__ import annotations

import math
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple

import gymnasium
import numpy as np

from ._environment import (UNLIMITED_CONTROL, RewardFn, SimgateStartError,  # noqa: F401 (re-exported)
                           TerminatedFn, _Attached, _attach, _check_arguments, _encoded, _Layout,
                           _Server, find_binary)
from ._wires import JsonText
from .client import Client
from .errors import ServiceError

__all__ = ["SimgateEnv", "SimgateStartError", "make_vec", "ENV_ID", "UNLIMITED_CONTROL"]

ENV_ID = "simgate/Model-v0"


# ---- the environment
class SimgateEnv(_Attached, gymnasium.Env):
    """A simgate simulation as a Gymnasium environment (module docstring: the spaces, the
    life cycle). One instance owns one connection, and the simgate it started if any.

    Parameters (exactly one of `model`, `config`, `address`):

    - `model`: an MJCF (or URDF) file, served with the generic components
      (``simgate run --model``); `config`: a deployment file (its robots and scene; its
      transports are replaced by the environment's); `address`: ``jsonrpc://HOST:PORT`` (or
      ``HOST:PORT``) of a running simgate, which is paused and stepped by the environment.
    - `binary`, `plugin_path` (directories for ``--plugin-path``), `log_level`: for the
      simgate the environment starts.
    - `frame_skip`: physics steps per `step()` (1 to 1 000 000).
    - `flat`: the observation as one ``Box`` (order: joint_pos, joint_vel, base, sensors).
    - `out_of_range`: ``"clip"`` (default) clips each control into its actuator's range;
      ``"refuse"`` raises ``ValueError`` naming the actuator, value and range, and sends
      nothing. A NaN or infinite control, or an action of the wrong shape, is always refused.
    - `reward_fn(obs, action, next_obs) -> float` (default: 0.0), `terminated_fn(obs, action,
      next_obs) -> bool` (default: never), `max_episode_steps` (truncation; also given by
      ``gymnasium.make(..., max_episode_steps=N)``, which wraps the env in a ``TimeLimit``).
    - `render_mode`: ``"rgb_array"`` or None; `render_camera` (an MJCF camera, or ``""``
      for the free view of the whole scene), `render_width`, `render_height`: `render()`
      returns ``simulation get_snapshot``'s picture, an ``HxWx3 uint8`` array.
    - `lockstep`: join the simulation's lockstep barrier (default True), so that no other
      client steps the world unasked; False: plain ``simulation step``.
    - `token`, `timeout`: the connection's (``simgate.connect``).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, model: Optional[str] = None, config: Optional[str] = None,
                 address: Optional[str] = None, *, binary: Optional[str] = None,
                 frame_skip: int = 1, flat: bool = False, out_of_range: str = "clip",
                 reward_fn: Optional[RewardFn] = None, terminated_fn: Optional[TerminatedFn] = None,
                 max_episode_steps: Optional[int] = None, render_mode: Optional[str] = None,
                 render_camera: str = "", render_width: int = 480, render_height: int = 480,
                 lockstep: bool = True, plugin_path: Sequence[str] = (), log_level: str = "warning",
                 token: Optional[str] = None, timeout: float = 30.0) -> None:
        super().__init__()
        self._join: Any = None
        self._initial: Optional[int] = None
        _check_arguments(model, config, address, frame_skip, out_of_range, max_episode_steps)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"simgate.gym: render_mode = {render_mode!r}: expected 'rgb_array' or None")
        self._keep_episode_options(frame_skip, flat, out_of_range, reward_fn, terminated_fn, max_episode_steps)
        self.render_mode = render_mode
        self.render_camera = render_camera
        self.render_width = render_width
        self.render_height = render_height
        self._participant = f"gym-{os.getpid()}-{id(self):x}"
        self._lockstep = lockstep
        self._elapsed = 0
        self._obs: Any = None
        try:
            if address is None:
                self._server = _Server(find_binary(binary), model, config, plugin_path, log_level)
                address = self._server.url("jsonrpc")
            self._sim = _attach(address, token, timeout)
            self.url = self._sim.url
            self._sim.pause()
            self._layout = _Layout(self._sim)
            self._join_lockstep()
            self._initial = self._sim.save_state()
        except BaseException:
            self.close()
            raise
        layout = self._layout
        self.action_space, self.observation_space, self.observation_names = layout.spaces(flat)
        self.action_names: List[str] = list(layout.action_names)
        self._controls = layout.controls  # bench/gym_bench.py sends step()'s batch from it
        self._reads = layout.reads()
        step = (("simulation", "lockstep_step", {"participant": self._participant, "n": frame_skip})
                if lockstep else ("simulation", "step", {"n": frame_skip}))
        self._step_and_reads = [step] + self._reads
        # what step() sends, encoded once but for the controls' values: each actuators
        # component's set_controls params as a %-format of its values, and the step's and
        # the reads' params
        self._control_formats = layout.control_formats()
        self._step_and_reads_text = _encoded(self._step_and_reads)

    def _join_lockstep(self) -> None:
        if self._lockstep and (self._join is None or self._join.done()):
            self._join = self.client.submit("simulation", "lockstep_join", (), {"participant": self._participant})

    # ---- Gymnasium's API
    def reset(self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None) -> Tuple[Any, Dict[str, Any]]:
        """Back to the state saved when the environment was made (``restore_state``: exact, so
        the same seed and actions give the same episode, bit for bit). `seed` seeds
        `np_random` (the action space's sampling and any use the caller makes of it): the
        initial state itself has no noise. `options` is not used."""
        super().reset(seed=seed)
        sim = self.client
        if self._join is not None and self._join.done():
            self._join_lockstep()  # a divergence ended the join: join again
        restored, *values = sim.call_many([("simulation", "restore_state", {"handle": self._initial})]
                                          + self._reads, timeout=sim.timeout)
        self._obs = self._layout.observe(values, self.flat)
        self._elapsed = 0
        return self._obs, {"sim_time": restored["sim_time"]}

    def step(self, action: Any) -> Tuple[Any, float, bool, bool, Dict[str, Any]]:
        """Apply `action` (one control per actuator, `action_names`' order), take `frame_skip`
        physics steps, observe: one round trip (a JSON-RPC batch)."""
        if self._obs is None:
            raise RuntimeError("simgate.gym: call reset() before step()")
        values = self._check(action)
        requests = _set_controls(self._control_formats, values)
        n = len(requests)
        requests += self._step_and_reads_text
        try:
            replies = self.client.call_many(requests, timeout=None)
        except ServiceError as e:
            raise type(e)(f"simgate.gym: step failed: {e.message} (reset() puts the world "
                          "back)", status=e.status, code=e.code, data=e.data, method=e.method) from e
        result = replies[n]
        obs = self._layout.observe(replies[n + 1:], self.flat)
        previous, self._obs = self._obs, obs
        self._elapsed += 1
        act = np.array(values, dtype=np.float64) if self.reward_fn or self.terminated_fn else None
        reward = float(self.reward_fn(previous, act, obs)) if self.reward_fn else 0.0
        terminated = bool(self.terminated_fn(previous, act, obs)) if self.terminated_fn else False
        truncated = self.max_episode_steps is not None and self._elapsed >= self.max_episode_steps
        return obs, reward, terminated, truncated, {"sim_time": result["sim_time"]}

    def render(self) -> Optional[np.ndarray]:
        """With ``render_mode="rgb_array"``: a picture of the current state (``simulation
        get_snapshot`` from `render_camera`), ``HxWx3 uint8``; otherwise None."""
        if self.render_mode != "rgb_array":
            return None
        return self.client.snapshot(self.render_camera, self.render_width, self.render_height,
                                    numpy_arrays=True)

    def close(self) -> None:
        """Leave the lockstep, drop the saved state, close the connection, stop and reap the
        simgate this environment started. Idempotent."""
        self._detach(self._leave)
        super().close()

    def _leave(self, sim: Client) -> None:
        if self._join is not None and not self._join.done():
            self._join.cancel()
        if self._initial is not None:
            sim.drop_state(self._initial)

    # ---- helpers
    def _check(self, action: Any) -> List[float]:
        """The controls of `action`: checked (its shape; each finite; in range when refusing,
        else `_Layout.refuse` raises) and clipped into their ranges, as floats."""
        act = np.asarray(action, dtype=np.float64)
        if act.shape != self.action_space.shape:
            raise ValueError(f"simgate.gym: the action has shape {act.shape}, expected "
                             f"{self.action_space.shape} ({', '.join(self.action_names)})")
        values = act.tolist()
        # the sum is finite when every control is (or overflowed: then they are checked)
        if not math.isfinite(sum(values)) and not np.all(np.isfinite(act)) or \
                self.out_of_range == "refuse" and ((act < self._layout.low) | (act > self._layout.high)).any():
            self._layout.refuse(act, "action", self.out_of_range)
        return self._layout.clip(values)



def _set_controls(formats: Sequence[Tuple[str, str, int, int]],
                  values: Sequence[float]) -> List[Tuple[str, str, Any]]:
    """The ``set_controls`` requests of one action's `values` (`_Layout.control_formats`)."""
    return [(component, "set_controls", JsonText(form % tuple(values[start:stop])))
            for component, form, start, stop in formats]


def make_vec(num_envs: int, vectorization_mode: str = "async", **kwargs: Any) -> gymnasium.vector.VectorEnv:
    """`num_envs` environments stepped together: ``gymnasium.make_vec("simgate/Model-v0",
    num_envs, vectorization_mode, **kwargs)``. ``"worlds"`` (Gymnasium's
    ``"vector_entry_point"``): one simgate running `num_envs` worlds, stepped by one call
    (`simgate.vector.SimgateVectorEnv`, which `kwargs` go to); ``"async"``, ``"sync"``: a
    simgate process per environment (each environment in a worker process of its own, or
    all in this one)."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"simgate.gym.make_vec: num_envs = {num_envs!r}: expected a positive integer")
    mode = "vector_entry_point" if vectorization_mode == "worlds" else vectorization_mode
    return gymnasium.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode=mode, **kwargs)


def _register() -> None:
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point="simgate.gym:SimgateEnv",
                           vector_entry_point="simgate.vector:SimgateVectorEnv")


_register()
