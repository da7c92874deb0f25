"""A Gymnasium vector environment over the worlds of one simgate (docs/python.md, docs/worlds.md).

    import simgate.gym
    envs = simgate.gym.make_vec(16, vectorization_mode="worlds", model="cartpole.xml")
    obs, infos = envs.reset(seed=0)
    obs, rewards, terminations, truncations, infos = envs.step(envs.action_space.sample())
    envs.close()

`SimgateVectorEnv` starts one ``simgate run`` of ``"worlds": num_envs`` (or attaches to a
running simgate of that many worlds or more): sub-environment k is world k, exactly a
`simgate.gym.SimgateEnv` of that world (the same spaces, the same observations bit for bit).
Each `step()` is one request, one round trip whatever the number of worlds: world 0's
``simulation step_many`` (the worlds step in parallel on the server's threads) of
`frame_skip` steps, each world's action in the order of MuJoCo's ``ctrl`` (each actuator
where its ``list_actuators`` ``index`` says; null, kept, for the actuators the environment
does not drive), and as its ``reads`` the services a `SimgateEnv` reads
(``<robot>.armature_pose get_state``, ...), which each world runs after its steps. The
observations come from those reads' results, not from step_many's own arrays (``qpos``,
``sensordata``, ...): nothing the server offers says where a robot's joints and sensors are
in those arrays, and the floating bases' pose and velocity are not among them.

Episodes end as a `SimgateEnv`'s do (`terminated_fn`, `max_episode_steps`) and are reset
world by world (``w<k>/simulation restore_state`` of the state saved when the environment
was made, then its reads), in a batch ending with the next step's step_many
(`autoreset_mode` ``NEXT_STEP``, Gymnasium's default), in a second batch of the same step
(``SAME_STEP``), or when `reset()` is given a ``reset_mask`` (``DISABLED``). A world that
diverges (docs/world/divergence.md) ends its episode truncated, with reward 0 and its
divergence in ``infos["diverged"]``, and is reset like any other.
"""

from __future__ import annotations

from itertools import chain
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ._wires import JsonText, _json
from .client import Client
from .errors import ServiceError, ServiceFailed
from ._environment import (RewardFn, TerminatedFn, _Attached, _attach, _check_arguments, _encoded,
                           _in_world, _Layout, _Server, find_binary)

__all__ = ["SimgateVectorEnv", "MAX_BATCH"]

MAX_BATCH = 1024  # the entries of one JSON-RPC batch simgate takes (docs/transports/jsonrpc.md)


class SimgateVectorEnv(_Attached, VectorEnv):
    """`num_envs` worlds of one simgate as a Gymnasium vector environment (module docstring:
    how it steps and resets). One instance owns one connection, and the simgate it started
    if any.

    Parameters: `num_envs`, the worlds stepped (worlds 0 to num_envs - 1); `autoreset_mode`
    (an ``AutoresetMode`` or its value, default ``NEXT_STEP``); the others are
    `simgate.gym.SimgateEnv`'s: exactly one of `model`, `config` (the simgate started runs
    ``"worlds": num_envs``) or `address` (a running simgate of worlds
    0 to num_envs - 1 at least, each paused by the environment and left paused by `close()`);
    `binary`, `plugin_path`, `log_level`, `frame_skip`, `flat`, `out_of_range`, `reward_fn`,
    `terminated_fn` (called for each world with that world's observations and action),
    `max_episode_steps`, `token`, `timeout`. Not there: rendering, and the lockstep (nothing
    keeps another client from stepping a world).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int, model: Optional[str] = None, config: Optional[str] = None,
                 address: Optional[str] = None, *, binary: Optional[str] = None,
                 frame_skip: int = 1, flat: bool = False, out_of_range: str = "clip",
                 reward_fn: Optional[RewardFn] = None, terminated_fn: Optional[TerminatedFn] = None,
                 max_episode_steps: Optional[int] = None,
                 autoreset_mode: Any = AutoresetMode.NEXT_STEP, plugin_path: Sequence[str] = (),
                 log_level: str = "warning", token: Optional[str] = None, timeout: float = 30.0) -> None:
        self._initial: List[int] = []
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"simgate.gym: num_envs = {num_envs!r}: expected a positive integer")
        _check_arguments(model, config, address, frame_skip, out_of_range, max_episode_steps)
        modes = [m.value for m in AutoresetMode]
        if autoreset_mode not in list(AutoresetMode) + modes:
            raise ValueError(f"simgate.gym: autoreset_mode = {autoreset_mode!r}: expected an "
                             f"AutoresetMode or one of {', '.join(modes)}")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        self.num_envs = num_envs
        self._keep_episode_options(frame_skip, flat, out_of_range, reward_fn, terminated_fn, max_episode_steps)
        self._worlds = list(range(num_envs))
        self._obs: Any = None
        self._elapsed = np.zeros(num_envs, dtype=np.int64)
        self._autoreset = np.zeros(num_envs, dtype=np.bool_)  # NEXT_STEP: reset at the next step
        try:
            if address is None:
                self._server = _Server(find_binary(binary), model, config, plugin_path, log_level,
                                       worlds=num_envs)
                address = self._server.url("jsonrpc")
            self._sim = sim = _attach(address, token, timeout)
            self.url = sim.url
            there = _worlds_of(sim)
            if not set(range(num_envs)) <= set(there):
                raise ValueError(f"simgate.gym: {self.url} runs worlds {', '.join(map(str, sorted(there)))}: "
                                 f"num_envs = {num_envs} needs worlds 0 to {num_envs - 1} "
                                 "(\"worlds\": N in its config, or simulation create_world; "
                                 "docs/worlds.md)")
            sim.call_many([(_in_world("simulation", k), "pause", None) for k in self._worlds])
            self._layout = _Layout(sim)
            if None in self._layout.indices:
                raise ValueError(f"simgate.gym: {self.url}: list_actuators gives no actuator's index "
                                 "in MuJoCo's ctrl: a simgate older than this client")
            self._initial = sim.call_many([(_in_world("simulation", k), "save_state", None)
                                           for k in self._worlds])
        except BaseException:
            self.close()
            raise
        layout = self._layout
        self.single_action_space, self.single_observation_space, self.observation_names = layout.spaces(flat)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_names: List[str] = list(layout.action_names)
        # step_many's params but its worlds and actions: the reads of a SimgateEnv, in every world
        self._step_params = {"n": frame_skip, "observe": [],
                             "reads": [{"component": c, "service": s, "params": p} for c, s, p in layout.reads()]}
        # each world's MuJoCo ctrl: its actuators, those the environment does not drive kept
        self._ctrl_sizes = [there[k] for k in self._worlds]
        # the resets' batches, encoded once: each world's restore_state and reads
        self._reads = [_encoded(layout.reads(k)) for k in self._worlds]
        self._restores = [(_in_world("simulation", k), "restore_state",
                           JsonText(_json({"handle": handle}, allow_nan=False)))
                          for k, handle in zip(self._worlds, self._initial)]

    # ---- Gymnasium's API
    def reset(self, *, seed: Optional[int] = None,
              options: Optional[Dict[str, Any]] = None) -> Tuple[Any, Dict[str, Any]]:
        """Every world (or those of ``options["reset_mask"]``, a bool array of `num_envs`)
        back to the state saved when the environment was made, in one round trip. `seed`
        seeds `np_random`; the initial states have no noise."""
        super().reset(seed=seed)
        mask = (options or {}).get("reset_mask")
        if mask is None:
            worlds = self._worlds
        else:
            if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (self.num_envs,) \
                    or not mask.any():
                raise ValueError(f"simgate.gym: options['reset_mask'] = {mask!r}: expected a numpy bool "
                                 f"array of shape ({self.num_envs},) with at least one True")
            if self._obs is None:
                raise RuntimeError("simgate.gym: call reset() without reset_mask first")
            worlds = np.flatnonzero(mask).tolist()
        restored, _, obs = self._exchange(worlds, [], [])
        self._obs = obs if mask is None else _with_rows(self._obs, worlds, obs)
        self._elapsed[worlds] = 0
        self._autoreset[worlds] = False
        sim_time = np.zeros(self.num_envs)
        sim_time[worlds] = [r["sim_time"] for r in restored]
        return self._obs, {"sim_time": sim_time, "_sim_time": _mask(self.num_envs, worlds)}

    def step(self, actions: Any) -> Tuple[Any, np.ndarray, np.ndarray, np.ndarray, Dict[str, Any]]:
        """Apply each world's action (a row of `actions`), take `frame_skip` physics steps in
        every world (but those reset instead, `autoreset_mode` ``NEXT_STEP``), observe: one
        round trip. ``infos["sim_time"]``: each world's simulated time after it."""
        if self._obs is None:
            raise RuntimeError("simgate.gym: call reset() before step()")
        values = self._check(actions)
        n = self.num_envs
        resetting = np.flatnonzero(self._autoreset).tolist()
        stepping = [k for k in self._worlds if not self._autoreset[k]] if resetting else self._worlds
        restored, slots, obs = self._exchange(resetting, stepping, values)
        previous, self._obs = self._obs, obs
        rewards = np.zeros(n)
        terminated = np.zeros(n, dtype=np.bool_)
        truncated = np.zeros(n, dtype=np.bool_)
        sim_time = np.zeros(n)
        diverged: Dict[int, Any] = {}  # world: its divergence (get_simulation_state's last_divergence)
        for k, reply in zip(resetting, restored):
            sim_time[k] = reply["sim_time"]
        self._elapsed[resetting] = 0
        self._elapsed[stepping] += 1
        for slot in slots:
            k = slot["world"]
            sim_time[k] = slot["sim_time"]
            if "diverged" in slot:
                truncated[k] = True
                diverged[k] = slot["diverged"]
                continue
            if self.reward_fn or self.terminated_fn:
                before, after = _row(previous, k), _row(obs, k)
                act = np.array(values[k], dtype=np.float64)
                if self.reward_fn:
                    rewards[k] = float(self.reward_fn(before, act, after))
                if self.terminated_fn:
                    terminated[k] = bool(self.terminated_fn(before, act, after))
        if self.max_episode_steps is not None:
            truncated |= self._elapsed >= self.max_episode_steps
        infos: Dict[str, Any] = {"sim_time": sim_time, "_sim_time": np.ones(n, dtype=np.bool_)}
        for k, divergence in diverged.items():
            infos = self._add_info(infos, {"diverged": divergence}, k)
        ended = terminated | truncated
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._autoreset = ended
        elif self.autoreset_mode == AutoresetMode.SAME_STEP and ended.any():
            infos = self._reset_ended(np.flatnonzero(ended).tolist(), diverged, infos)
        return self._obs, rewards, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        """Drop the saved states, close the connection, stop and reap the simgate this
        environment started."""
        self._detach(self._drop_states)

    # ---- helpers
    def _exchange(self, restore: Sequence[int], step: Sequence[int],
                  values: Sequence[List[float]]) -> Tuple[List[Any], List[Dict[str, Any]], Any]:
        """One round trip: the worlds `step` given their controls (`values`, by world) and
        stepped by one ``simulation step_many``, which reads them; the worlds `restore` put
        back and read in a batch before it (several batches in turn past `MAX_BATCH`
        entries). Returns the replies of the restores, step_many's slots, and the
        observations of both (rows in world order). A failed step raises, saying so."""
        requests: List[Tuple[str, str, Any]] = [self._restores[k] for k in restore]
        for k in restore:
            requests += self._reads[k]
        sim = self.client
        replies: List[Any] = []
        slots: List[Dict[str, Any]] = []
        try:
            if step:
                params = {**self._step_params, "worlds": list(step),
                          "actions": [self._ctrl(k, values[k]) for k in step]}
                requests.append(("simulation", "step_many", params))
            if not restore:  # a step alone: one request, not a batch
                slots = sim.submit("simulation", "step_many", (), params).result()["worlds"]
            else:
                for start in range(0, len(requests), MAX_BATCH):
                    replies += sim.call_many(requests[start:start + MAX_BATCH],
                                             timeout=None if step else sim.timeout)
                if step:
                    slots = replies.pop()["worlds"]
        except ServiceError as e:
            if not step:
                raise
            raise type(e)(f"simgate.gym: step failed: {e.message} (reset() puts the worlds back)",
                          status=e.status, code=e.code, data=e.data, method=e.method) from e
        results: Dict[int, Sequence[Any]] = {}  # each world's reads' results
        count = len(self._step_params["reads"])
        for i, k in enumerate(restore):
            results[k] = replies[len(restore) + i * count:len(restore) + (i + 1) * count]
        for slot in slots:
            if "error" in slot:
                raise ServiceFailed(f"simgate.gym: step failed in world {slot['world']}: {slot['error']} "
                                    "(reset() puts the worlds back)", method="simulation.step_many")
            results[slot["world"]] = slot.get("reads", ())  # none when there is nothing to read
        observed = sorted(results)
        obs = self._layout.observe_many(chain.from_iterable(results[k] for k in observed), len(observed), self.flat)
        return replies[:len(restore)], slots, obs

    def _ctrl(self, world: int, values: List[float]) -> List[Optional[float]]:
        """One action's `values` where `world`'s MuJoCo ctrl has them (list_actuators'
        indices), null (kept) for the actuators the environment does not drive."""
        ctrl: List[Optional[float]] = [None] * self._ctrl_sizes[world]
        for i, value in zip(self._layout.indices, values):
            ctrl[i] = value
        return ctrl

    def _reset_ended(self, ended: List[int], diverged: Dict[int, Any], infos: Dict[str, Any]) -> Dict[str, Any]:
        """``SAME_STEP``: the worlds that `ended` reset in a second round trip; their last
        observation and info (`diverged`: their divergences) in ``infos["final_obs"]`` and
        ``infos["final_info"]``, ``infos["sim_time"]`` the time they were put back to."""
        for k in ended:
            info = {"sim_time": float(infos["sim_time"][k])}
            if k in diverged:
                info["diverged"] = diverged[k]
            infos = self._add_info(infos, {"final_obs": _row(self._obs, k), "final_info": info}, k)
        restored, _, obs = self._exchange(ended, [], [])
        self._obs = _with_rows(self._obs, ended, obs)
        self._elapsed[ended] = 0
        infos["sim_time"][ended] = [r["sim_time"] for r in restored]
        return infos

    def _check(self, actions: Any) -> List[List[float]]:
        """Each world's controls: `actions` checked (its shape; each control finite; in range
        when refusing, else `_Layout.refuse` raises, naming the world) and clipped into their
        ranges, as `SimgateEnv` does for one."""
        shape = self.action_space.shape
        try:
            act = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"simgate.gym: the actions are not an array of shape {shape}: {e}") from e
        if act.shape != shape:
            raise ValueError(f"simgate.gym: the actions have shape {act.shape}, expected {shape}: "
                             f"one action per world of {shape[1]} controls ({', '.join(self.action_names)})")
        layout = self._layout
        if not np.isfinite(act).all() or \
                self.out_of_range == "refuse" and ((act < layout.low) | (act > layout.high)).any():
            for k, action in enumerate(act):
                layout.refuse(action, f"actions[{k}]", self.out_of_range)
        return [layout.clip(action) for action in act.tolist()]

    def _drop_states(self, sim: Client) -> None:
        if self._initial:
            sim.call_many([(_in_world("simulation", k), "drop_state", {"handle": handle})
                           for k, handle in zip(self._worlds, self._initial)])


def _worlds_of(sim: Client) -> Dict[int, int]:
    """The worlds the simgate of `sim` runs (``simulation list_worlds``), each with its number
    of MuJoCo actuators (the length of its controls in ``step_many``)."""
    return {w["world"]: w["actuators"] for w in sim.call("simulation", "list_worlds")["worlds"]}


def _row(obs: Any, k: int) -> Any:
    """World `k`'s observation in the batched `obs` (views of its rows)."""
    return {key: value[k] for key, value in obs.items()} if isinstance(obs, dict) else obs[k]


def _with_rows(obs: Any, worlds: List[int], rows: Any) -> Any:
    """A copy of the batched `obs` with the rows of `worlds` replaced by `rows`."""
    if isinstance(obs, dict):
        return {key: _with_rows(value, worlds, rows[key]) for key, value in obs.items()}
    out = obs.copy()
    out[worlds] = rows
    return out


def _mask(n: int, worlds: Sequence[int]) -> np.ndarray:
    mask = np.zeros(n, dtype=np.bool_)
    mask[list(worlds)] = True
    return mask
