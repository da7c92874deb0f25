#!/usr/bin/python3
"""The `gym` section's client (bench/harness.py): simgate.gym's env.step() against the raw
JSON-RPC round trip of the same batch, on one simgate, in alternating rounds.

One `SimgateEnv` (model=MODEL) starts `simgate run` (SIMGATE_BIN or --simgate); then, in each
of --rounds rounds and in alternating order:
- env: --steps calls of env.step(action) (the action a fixed vector inside the action space);
- raw: a second TCP connection to the same JSON-RPC transport, a bare loop sending the very
  batch env.step() sends (set_controls of every actuators component, lockstep_step as the
  environment's participant, the observation's reads), encoded with json.dumps at each step,
  one line read back and decoded with json.loads: what any client pays at least.
Prints one JSON object: per round the steps/s of each and env/raw's time per step ratio.
Needs gymnasium and numpy on PYTHONPATH (tests/python/pypi-requirements.txt) and the package
in python/. Every loop is bounded by --steps; the simgate is stopped at the end.
"""
import argparse
import json
import os
import socket
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "python"))

import numpy as np  # noqa: E402

import simgate.gym  # noqa: E402


def raw_loop(env, steps):
    """The batch of env.step() over a bare socket: seconds for `steps` round trips."""
    host, port = env.url.split("://", 1)[1].rsplit(":", 1)
    action = fixed_action(env)
    controls = [(c, "set_controls", {"controls": dict(zip(names, action[where].tolist()))})
                for c, names, where in env._controls]
    requests = controls + env._step_and_reads
    with socket.create_connection((host, int(port)), timeout=30) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        reader = sock.makefile("rb")
        ident = 0
        start = time.perf_counter()
        for _ in range(steps):
            batch = []
            for component, service, params in requests:
                ident += 1
                r = {"jsonrpc": "2.0", "id": ident, "method": f"{component}.{service}"}
                if params is not None:
                    r["params"] = params
                batch.append(r)
            sock.sendall(json.dumps(batch, separators=(",", ":")).encode() + b"\n")
            replies = json.loads(reader.readline())
            if any("error" in r for r in replies):
                raise RuntimeError(f"raw loop: {replies}")
        return time.perf_counter() - start


def env_loop(env, steps):
    action = fixed_action(env)
    start = time.perf_counter()
    for _ in range(steps):
        env.step(action)
    return time.perf_counter() - start


def fixed_action(env):
    return (env.action_space.low + env.action_space.high) / 2 + 0.1 * (env.action_space.high - env.action_space.low) / 2


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--model", required=True)
    parser.add_argument("--simgate", default=None)
    parser.add_argument("--plugin-path", action="append", default=[])
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--frame-skip", type=int, default=1)
    args = parser.parse_args()
    env = simgate.gym.SimgateEnv(model=args.model, binary=args.simgate, plugin_path=args.plugin_path,
                                 frame_skip=args.frame_skip)
    try:
        env.reset(seed=0)
        env_loop(env, min(200, args.steps))  # warm up both paths
        raw_loop(env, min(200, args.steps))
        rounds = []
        for k in range(args.rounds):
            env.reset(seed=k)
            if k % 2 == 0:
                e = env_loop(env, args.steps)
                r = raw_loop(env, args.steps)
            else:
                r = raw_loop(env, args.steps)
                e = env_loop(env, args.steps)
            rounds.append({"env_steps_per_s": args.steps / e, "raw_steps_per_s": args.steps / r,
                           "env_us": e / args.steps * 1e6, "raw_us": r / args.steps * 1e6, "ratio": e / r})
        print(json.dumps({"model": args.model, "steps": args.steps, "frame_skip": args.frame_skip,
                          "actuators": env.action_space.shape[0],
                          "observation_size": len(env.observation_names),
                          "requests_per_step": len(env._controls) + len(env._step_and_reads),
                          "rounds": rounds}))
    finally:
        env.close()


if __name__ == "__main__":
    main()
