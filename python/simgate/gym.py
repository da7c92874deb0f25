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

import json
import math
import operator
import os
import shutil
import signal
import subprocess
import tempfile
import time
import weakref
from typing import Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple

import gymnasium
import numpy as np
from gymnasium import spaces

from ._wires import JsonText, _json, json_string
from .client import Client
from .errors import ConnectionClosed, MethodNotFound, ServiceError, SimgateError

__all__ = ["SimgateEnv", "SimgateStartError", "make_vec", "ENV_ID", "UNLIMITED_CONTROL"]

ENV_ID = "simgate/Model-v0"
UNLIMITED_CONTROL = 1e6  # the bound simgate accepts for a control without ctrlrange
START_TIMEOUT = 60.0  # seconds for `simgate run` to listen
STOP_TIMEOUT = 10.0  # seconds for it to stop after SIGTERM, before SIGKILL
BASE_SIZE = 13  # position 3, quaternion 4, linear velocity 3, angular velocity 3

RewardFn = Callable[[Any, np.ndarray, Any], float]
TerminatedFn = Callable[[Any, np.ndarray, Any], bool]


class SimgateStartError(SimgateError, RuntimeError):
    """`simgate run` could not be started, or stopped before it listened: the message holds
    its command line, exit status and output."""


# ---- the simgate process an environment starts
def find_binary(binary: Optional[str] = None) -> str:
    """The simgate executable: `binary`, else ``SIMGATE_BIN``, else ``simgate`` on PATH."""
    for source, candidate in (("binary=", binary), ("SIMGATE_BIN", os.environ.get("SIMGATE_BIN"))):
        if candidate:
            path = shutil.which(candidate) or (candidate if os.path.isfile(candidate) else None)
            if path is None or not os.access(path, os.X_OK):
                raise FileNotFoundError(f"simgate.gym: {source} {candidate!r}: no such executable")
            return path
    path = shutil.which("simgate")
    if path is None:
        raise FileNotFoundError("simgate.gym: no simgate executable: pass binary=PATH, set "
                                "SIMGATE_BIN, or put simgate on PATH")
    return path


def _transports() -> Dict[str, Any]:
    loopback = {"host": "127.0.0.1", "port": 0}
    return {"jsonrpc": {"plugin": "jsonrpc", "options": dict(loopback)},
            "socket": {"plugin": "socket", "options": {**loopback, "stream_port": 0}}}


def _config_for(config: str) -> Dict[str, Any]:
    """The deployment file `config`, made the environment's: started paused, its transports
    replaced by JSON-RPC and MORSE's socket protocol on 127.0.0.1 (ports the kernel picks),
    serving every component; its relative paths made absolute."""
    try:
        with open(config) as f:
            data = json.load(f)
    except (OSError, ValueError) as e:
        raise SimgateStartError(f"simgate.gym: config={config!r}: cannot read it: {e}") from e
    if not isinstance(data, dict) or not isinstance(data.get("scene"), dict):
        raise SimgateStartError(f"simgate.gym: config={config!r}: expected a deployment file "
                                "(a JSON object with a 'scene'; docs/configuration.md)")
    here = os.path.dirname(os.path.abspath(config))
    scene = data["scene"]
    if isinstance(scene.get("mjcf"), str):
        scene["mjcf"] = os.path.join(here, scene["mjcf"])
    if isinstance(scene.get("allowed_dirs"), list):
        scene["allowed_dirs"] = [os.path.join(here, d) if isinstance(d, str) else d
                                 for d in scene["allowed_dirs"]]
    scene["start_paused"] = True
    data["transports"] = _transports()
    data.pop("services", None)  # it named the file's transports: every transport serves all
    data.pop("streams", None)
    return data


class _Server:
    """One ``simgate run`` of an environment: started on ports the kernel picks, reported by
    ``--endpoints-file``, running `worlds` copies of the scene when given (docs/worlds.md);
    `stop()` ends and reaps it (also at interpreter exit)."""

    def __init__(self, binary: str, model: Optional[str], config: Optional[str],
                 plugin_path: Sequence[str], log_level: str, worlds: Optional[int] = None) -> None:
        self.dir = tempfile.mkdtemp(prefix="simgate-gym-")
        try:
            cfg = _config_for(config) if config else {"scene": {"start_paused": True},
                                                       "transports": _transports()}
            cfg["log_level"] = log_level
            if worlds is not None:
                cfg["worlds"] = worlds
            cfg_path = os.path.join(self.dir, "config.json")
            with open(cfg_path, "w") as f:
                json.dump(cfg, f)
            endpoints = os.path.join(self.dir, "endpoints.json")
            self.command = [binary, "run"]
            if model:
                self.command += ["--model", os.path.abspath(model)]
            self.command += [cfg_path, "--endpoints-file", endpoints, "--realtime-factor", "max"]
            for d in plugin_path:
                self.command += ["--plugin-path", d]
            self.log_path = os.path.join(self.dir, "simgate.log")
            with open(self.log_path, "wb") as log:
                self.process: Optional[subprocess.Popen] = subprocess.Popen(
                    self.command, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT)
        except BaseException:
            shutil.rmtree(self.dir, ignore_errors=True)
            raise
        self._finalizer = weakref.finalize(self, _stop, self.process, self.dir)
        try:
            self.endpoints = self._wait_for(endpoints)
        except BaseException:
            self.stop()
            raise

    def _wait_for(self, endpoints: str) -> Dict[str, List[str]]:
        deadline = time.monotonic() + START_TIMEOUT
        assert self.process is not None
        while True:
            if os.path.exists(endpoints):  # written whole, then renamed
                with open(endpoints) as f:
                    return json.load(f)
            status = self.process.poll()
            if status is not None:
                raise SimgateStartError(f"simgate.gym: {' '.join(self.command)} exited with status "
                                        f"{status} before listening:\n{self.output().strip()}")
            if time.monotonic() > deadline:
                raise SimgateStartError(f"simgate.gym: {' '.join(self.command)} did not listen "
                                        f"within {START_TIMEOUT:.0f} s:\n{self.output().strip()}")
            time.sleep(0.01)  # polling for the file the child writes, bounded by the deadline

    def url(self, transport: str) -> str:
        scheme = "jsonrpc" if transport == "jsonrpc" else "socket"
        return f"{scheme}://" + self.endpoints[transport][0].split("://", 1)[1]

    def output(self) -> str:
        try:
            with open(self.log_path, errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    def stop(self) -> None:
        self._finalizer()
        self.process = None


def _stop(process: subprocess.Popen, directory: str) -> None:
    """SIGTERM (simgate stops cleanly), SIGKILL after `STOP_TIMEOUT`, and reap."""
    try:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(STOP_TIMEOUT)
    finally:
        shutil.rmtree(directory, ignore_errors=True)


# ---- what the robots have
class _Layout:
    """The components the environment reads and drives, found through ``simulation details``,
    and where each number goes in the action and observation vectors."""

    def __init__(self, sim: Client) -> None:
        details = sim.call("simulation", "details")
        self.actuators: List[Tuple[str, List[str]]] = []  # (component, actuator names)
        self.joints: List[Tuple[str, List[str]]] = []  # (armature_pose component, joints)
        self.sensors: List[Tuple[str, List[Tuple[str, int]]]] = []  # (component, (name, dim))
        self.bases: List[str] = []  # bodies of the floating bases
        self.action_names: List[str] = []
        self.indices: List[Optional[int]] = []  # each action element's place in MuJoCo's ctrl
        low: List[float] = []
        high: List[float] = []
        for robot in details.get("robots", []):
            components = robot.get("components", {})
            by_type: Dict[str, List[str]] = {}
            for name, component in components.items():
                by_type.setdefault(component.get("type", ""), []).append(name)
            for component in by_type.get("actuators", []):
                names = sim.call(component, "get_properties")["properties"]["actuators"]
                ranges = sim.call(component, "list_actuators")
                self.actuators.append((component, list(names)))
                for name in names:
                    r = ranges[name]["ctrlrange"]
                    low.append(r[0] if r else -UNLIMITED_CONTROL)
                    high.append(r[1] if r else UNLIMITED_CONTROL)
                    self.indices.append(ranges[name].get("index"))  # None: a simgate that does not say
                    self.action_names.append(f"{component}/{name}")
            for component in by_type.get("armature_pose", []):
                self.joints.append((component, list(sim.call(component, "get_joints"))))
            for component in by_type.get("sensors", []):
                props = sim.call(component, "get_properties")["properties"]["sensors"]
                self.sensors.append((component, [(n, int(props[n]["dim"])) for n in sorted(props)]))
            if by_type.get("pose"):
                # the robot's body: its robot-level get_configurations, or, when the robot's
                # own services are not served to this transport, its name (simgate names a
                # robot's body after it unless its config says otherwise)
                try:
                    configuration = sim.call(robot["name"], "get_configurations")
                    self.bases.append(configuration["configurations"]["body"])
                except MethodNotFound:
                    self.bases.append(robot["name"])
        if not self.actuators:
            robots = ", ".join(r.get("name", "?") for r in details.get("robots", [])) or "none"
            raise ValueError("simgate.gym: the simulation has no actuators component (robots: "
                             f"{robots}): nothing to act with. A robot of type 'mjcf' (--model) "
                             "gets one for its MJCF actuators; docs/components/actuators-and-sensors.md")
        self.low = np.array(low, dtype=np.float64)
        self.high = np.array(high, dtype=np.float64)
        self._low, self._high = low, high  # for clip
        # each actuators component, its actuators and its slice of the action
        self.controls = [(c, names, slice(start, start + len(names)))
                         for c, names, start in _offsets(self.actuators)]
        self.names: Dict[str, List[str]] = {  # the elements' names: "<key>:<component>/<name>"
            "joint_pos": [f"joint_pos:{c}/{j}" for c, js in self.joints for j in js],
            "joint_vel": [f"joint_vel:{c}/{j}" for c, js in self.joints for j in js],
            "base": [f"base:{b}/{part}" for b in self.bases for part in
                     ("x", "y", "z", "qx", "qy", "qz", "qw", "vx", "vy", "vz", "wx", "wy", "wz")],
            "sensors": [f"sensors:{c}/{n}" + (f"[{i}]" if d > 1 else "")
                        for c, s in self.sensors for n, d in s for i in range(d)],
        }
        # the observation's keys that have elements, and their place in `observe`'s parts
        self.keys = [(k, i) for i, k in enumerate(self.names) if self.names[k]]
        # each armature_pose's get_state -> its joints' states, in order
        self._joint_states = [_items(joints) for _, joints in self.joints]

    def reads(self, world: int = 0) -> List[Tuple[str, str, Any]]:
        """The observation's reads of `world`, as `Client.call_many` requests, in `parts`'
        order."""
        return ([(_in_world(c, world), "get_state", None) for c, _ in self.joints]
                + [(_in_world("simulation", world), "get_entity_state", {"name": b}) for b in self.bases]
                + [(_in_world(c, world), "get_local_data", None) for c, _ in self.sensors])

    def control_formats(self) -> List[Tuple[str, str, int, int]]:
        """Each actuators component with its ``set_controls`` params as a %-format of its
        values (`_controls_format`) and its slice of the action."""
        return [(c, _controls_format(names), where.start, where.stop) for c, names, where in self.controls]

    def spaces(self, flat: bool) -> Tuple[spaces.Box, spaces.Space, List[str]]:
        """The action space, the observation space (`flat`: one ``Box``) and the names of
        the flat observation's elements."""
        action = spaces.Box(self.low, self.high, dtype=np.float64)
        boxes = {k: spaces.Box(-np.inf, np.inf, (len(v),), np.float64) for k, v in self.names.items() if v}
        names = [n for k in boxes for n in self.names[k]]
        if flat:
            return action, spaces.Box(-np.inf, np.inf, (len(names),), np.float64), names
        return action, spaces.Dict(boxes), names

    def parts(self, results: Iterator[Any]) -> Tuple[List[float], List[float], List[float], List[float]]:
        """joint_pos, joint_vel, base and sensors from the results of one world's `reads`,
        taken from `results`."""
        pos: List[float] = []
        vel: List[float] = []
        for joint_states in self._joint_states:
            states = joint_states(next(results))
            pos += map(_POSITION, states)
            vel += map(_VELOCITY, states)
        base: List[float] = []
        for _ in self.bases:
            e = next(results)
            p, t = e["pose"], e["twist"]
            base += p["position"] + p["orientation"] + t["linear"] + t["angular"]
        values: List[float] = []
        for _, sensors in self.sensors:
            data = next(results)
            for n, d in sensors:
                v = data[n]
                if d == 1:
                    values.append(v[0] if isinstance(v, list) else v)
                else:
                    values += v
        return pos, vel, base, values

    def observe(self, results: Sequence[Any], flat: bool) -> Any:
        """The observation from the results of the `reads`: a ``Dict`` of the keys that have
        elements, or (`flat`) their concatenation, one array."""
        pos, vel, base, values = self.parts(iter(results))
        if flat:
            return np.array(pos + vel + base + values, dtype=np.float64)
        parts = (pos, vel, base, values)
        return {k: np.array(parts[i], dtype=np.float64) for k, i in self.keys}

    def observe_many(self, results: Iterator[Any], count: int, flat: bool) -> Any:
        """The observations of `count` worlds, one row each (the values `observe` gives each),
        from their `reads`' results in turn."""
        rows = [self.parts(results) for _ in range(count)]
        if flat:
            return np.array([pos + vel + base + values for pos, vel, base, values in rows], dtype=np.float64)
        return {k: np.array([row[i] for row in rows], dtype=np.float64) for k, i in self.keys}

    def refuse(self, act: np.ndarray, label: str, out_of_range: str) -> None:
        """Raise the error of the first control of `act` (one action, named `label`) that is
        not finite or (`out_of_range` ``"refuse"``) out of range; return when none is."""
        for i, value in enumerate(act.tolist()):
            if not math.isfinite(value):
                raise ValueError(f"simgate.gym: {label}[{i}] ({self.action_names[i]}) = {value}: "
                                 "expected a finite number")
        if out_of_range != "refuse":
            return
        for i, (value, lo, hi) in enumerate(zip(act.tolist(), self.low.tolist(), self.high.tolist())):
            if not lo <= value <= hi:
                raise ValueError(f"simgate.gym: {label}[{i}] ({self.action_names[i]}) = {value!r} is "
                                 f"out of range: expected a number from {lo!r} to {hi!r} "
                                 "(out_of_range='refuse')")

    def clip(self, values: Sequence[float]) -> List[float]:
        """`values` (one action) clipped into the actuators' ranges: the values of
        ``np.minimum(np.maximum(act, low), high)`` (low <= high, Box says so)."""
        return [lo if v < lo else hi if v > hi else v for v, lo, hi in zip(values, self._low, self._high)]


def _in_world(component: str, world: int) -> str:
    """The name of `component` in world `world`: world 0's keeps its name, world k's is
    ``w<k>/<component>`` (docs/worlds.md)."""
    return f"w{world}/{component}" if world else component


def _check_arguments(model: Optional[str], config: Optional[str], address: Optional[str],
                     frame_skip: int, out_of_range: str, max_episode_steps: Optional[int]) -> None:
    """Raise ValueError (FileNotFoundError for a missing file) for arguments an environment
    cannot start from."""
    if sum(x is not None for x in (model, config, address)) != 1:
        raise ValueError("simgate.gym: give exactly one of model=FILE.xml, config=FILE.json "
                         "or address=jsonrpc://HOST:PORT")
    if isinstance(frame_skip, bool) or not isinstance(frame_skip, int) or not 1 <= frame_skip <= 1_000_000:
        raise ValueError(f"simgate.gym: frame_skip = {frame_skip!r}: expected an integer from 1 to 1000000")
    if out_of_range not in ("clip", "refuse"):
        raise ValueError(f"simgate.gym: out_of_range = {out_of_range!r}: expected 'clip' or 'refuse'")
    if max_episode_steps is not None and (not isinstance(max_episode_steps, int) or max_episode_steps < 1):
        raise ValueError(f"simgate.gym: max_episode_steps = {max_episode_steps!r}: expected a positive integer")
    for name, path in (("model", model), ("config", config)):
        if path is not None and not os.path.isfile(path):
            raise FileNotFoundError(f"simgate.gym: {name}={path!r}: no such file")


def _attach(address: str, token: Optional[str], timeout: float) -> Client:
    """A connection to the simgate at `address` (a URL, or ``HOST:PORT`` for JSON-RPC);
    `ConnectionClosed` naming it when none answers."""
    url = address if "://" in address else f"jsonrpc://{address}"
    try:
        return Client(url, token=token, timeout=timeout)
    except ConnectionClosed as e:
        raise ConnectionClosed(f"simgate.gym: cannot attach to {url}: {e}") from e


# ---- what every environment has: its connection, and the simgate it started if any
class _Attached:
    """The connection of an environment (`client`) and the simgate it started, if any
    (`server_output`, `url_of`); `_detach` ends both."""

    _server: Optional[_Server] = None
    _sim: Optional[Client] = None

    @property
    def client(self) -> Client:
        """The connection to the simulation (`simgate.Client`), for anything else."""
        if self._sim is None:
            raise RuntimeError("simgate.gym: the environment is closed")
        return self._sim

    @property
    def server_output(self) -> str:
        """What the simgate this environment started printed so far ("" when attached)."""
        return self._server.output() if self._server else ""

    def url_of(self, transport: str) -> str:
        """The URL of the started simgate's ``jsonrpc`` or ``socket`` transport (for pymorse
        or another client beside the environment)."""
        if self._server is None:
            raise RuntimeError("simgate.gym: attached to a running simgate: its transports are its own")
        return self._server.url(transport)

    def _detach(self, tidy: Callable[[Client], None]) -> None:
        """`tidy(client)` while the connection is open (a simulation gone away is ignored),
        then close the connection, stop and reap the simgate this environment started."""
        sim, self._sim = self._sim, None
        if sim is not None:
            try:
                if not sim.closed:
                    tidy(sim)
            except (SimgateError, OSError, TimeoutError):
                pass  # the simulation went away: nothing to tidy there
            sim.close()
        server, self._server = self._server, None
        if server is not None:
            server.stop()


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
        self.frame_skip = frame_skip
        self.flat = flat
        self.out_of_range = out_of_range
        self.reward_fn = reward_fn
        self.terminated_fn = terminated_fn
        self.max_episode_steps = max_episode_steps
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


_POSITION, _VELOCITY = operator.itemgetter("position"), operator.itemgetter("velocity")


def _items(keys: Sequence[str]) -> Callable[[Mapping[str, Any]], Sequence[Any]]:
    """``lambda d: tuple(d[k] for k in keys)``, in C when there are several keys."""
    if len(keys) > 1:
        return operator.itemgetter(*keys)
    return lambda d: tuple(d[k] for k in keys)


def _controls_format(names: Sequence[str]) -> str:
    """``set_controls``' params ``{"controls": {name: value, ...}}`` as a ``%`` format of the
    values (a tuple of finite floats): ``%r`` writes a float as json does, so ``format %
    values`` is the JSON text `_json` gives the params, the values exact."""
    keys = (json_string(n).replace("%", "%%") for n in names)
    return '{"controls":{' + ",".join(k + ":%r" for k in keys) + "}}"


def _set_controls(formats: Sequence[Tuple[str, str, int, int]],
                  values: Sequence[float]) -> List[Tuple[str, str, Any]]:
    """The ``set_controls`` requests of one action's `values` (`_Layout.control_formats`)."""
    return [(component, "set_controls", JsonText(form % tuple(values[start:stop])))
            for component, form, start, stop in formats]


def _encoded(requests: Sequence[Tuple[str, str, Any]]) -> List[Tuple[str, str, Any]]:
    """`requests` with their params encoded once (`JsonText`), for requests sent again and again."""
    return [(c, s, None if p is None else JsonText(_json(p, allow_nan=False))) for c, s, p in requests]


def _offsets(groups: Sequence[Tuple[str, List[str]]]) -> List[Tuple[str, List[str], int]]:
    out, i = [], 0
    for component, names in groups:
        out.append((component, names, i))
        i += len(names)
    return out


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
