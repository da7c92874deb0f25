"""What `simgate.gym.SimgateEnv` and `simgate.vector.SimgateVectorEnv` share: the simgate
process an environment starts (`_Server`), the connection (`_attach`, `_Attached`), and the
layout of the spaces (`_Layout`: the components an environment reads and drives, and where
each number goes in the action and observation vectors). Private to the package; the public
names are re-exported by `simgate.gym`."""

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

import numpy as np
from gymnasium import spaces

from ._wires import JsonText, _json, json_string
from .client import Client
from .errors import ConnectionClosed, MethodNotFound, SimgateError

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

    def _keep_episode_options(self, frame_skip: int, flat: bool, out_of_range: str,
                              reward_fn: Optional[RewardFn], terminated_fn: Optional[TerminatedFn],
                              max_episode_steps: Optional[int]) -> None:
        """How an environment steps, observes and ends its episodes (`_check_arguments` checked
        them)."""
        self.frame_skip = frame_skip
        self.flat = flat
        self.out_of_range = out_of_range
        self.reward_fn = reward_fn
        self.terminated_fn = terminated_fn
        self.max_episode_steps = max_episode_steps

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

def _encoded(requests: Sequence[Tuple[str, str, Any]]) -> List[Tuple[str, str, Any]]:
    """`requests` with their params encoded once (`JsonText`), for requests sent again and again."""
    return [(c, s, None if p is None else JsonText(_json(p, allow_nan=False))) for c, s, p in requests]


def _offsets(groups: Sequence[Tuple[str, List[str]]]) -> List[Tuple[str, List[str], int]]:
    out, i = [], 0
    for component, names in groups:
        out.append((component, names, i))
        i += len(names)
    return out
