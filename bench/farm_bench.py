#!/usr/bin/python3
"""The `farm` section's client (bench/harness.py, issue #43): many worlds of one model stepped
remotely, by `simulation step_many` over one JSON-RPC connection, against the same steps taken
by one lockstep round trip per world and step.

Starts `simgate run` (--simgate) on a config made here: the MJCF (--model) as the scene,
"worlds": --worlds, paused, the JSON-RPC transport on a kernel-picked loopback port, no robots.
Then, for --seconds each, in alternating rounds (--rounds):
- step_many: `simulation.step_many` {n, actions: one control vector per world (the middle of
  each actuator's range, or 0), observe: qpos, qvel, sensordata}, one call after the other,
  the reply read and decoded with json.loads; for each n of --n;
- step_many pipelined: the worlds in two halves, a call for each in flight at once (the
  server steps one half while the client decodes the other's reply: how a learner overlaps
  its own work with the stepping), `"encoding": "base64"` (each array's float64 bytes,
  decoded with array.array: no number formatted or parsed), 10 steps a call;
- round trips: for each step, `w<k>/simulation.step` {n: 1} for every world k, one after the
  other (what a client without step_many pays: a round trip per world per step).
With --pipelined-only, only the pipelined calls (the section's run on fewer threads).
Prints one JSON object: per n the aggregate steps/s (world steps per second) of each round,
those of the pipelined calls and of the round trips. Every loop is bounded by --seconds; the
simgate is stopped.
"""
import array
import base64
import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time


class Rpc:
    """One JSON-RPC connection, requests one at a time."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=60)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.reader = self.sock.makefile("rb")
        self.id = 0

    def send(self, method, params):
        """Sends a request; returns its id."""
        self.id += 1
        self.sock.sendall(json.dumps({"jsonrpc": "2.0", "id": self.id, "method": method,
                                      "params": params}, separators=(",", ":")).encode() + b"\n")
        return self.id

    def receive(self):
        """The next reply: (its id, its result)."""
        reply = json.loads(self.reader.readline())
        if "error" in reply:
            raise RuntimeError(reply["error"]["message"])
        return reply["id"], reply["result"]

    def call(self, method, params):
        self.send(method, params)
        return self.receive()[1]


OBSERVE = ["qpos", "qvel", "sensordata"]


def pipelined(rpc, worlds, nu, n, seconds):
    """World steps per second of step_many over two halves of the worlds, a call of each in
    flight, base64 arrays decoded as the reply comes."""
    halves = [list(range(0, worlds // 2)), list(range(worlds // 2, worlds))]
    params = [{"worlds": h, "n": n, "actions": [[0.0] * nu for _ in h], "observe": OBSERVE,
               "encoding": "base64"} for h in halves]
    half_of = {rpc.send("simulation.step_many", params[i]): i for i in range(2)}
    steps = 0
    start_t = time.perf_counter()
    end_t = start_t + seconds
    while True:
        rid, result = rpc.receive()
        i = half_of.pop(rid)
        now = time.perf_counter()
        if now < end_t:  # the next call of this half, before decoding this one's reply
            half_of[rpc.send("simulation.step_many", params[i])] = i
        for w in result["worlds"]:
            assert w["steps_done"] == n, w
            for what in OBSERVE:
                w[what] = array.array("d", base64.b64decode(w[what]))
        steps += n * len(halves[i])
        if not half_of:
            return steps / (time.perf_counter() - start_t)


def start(simgate, model, worlds, workdir, on_divergence="pause", threads=0):
    config = {"scene": {"mjcf": os.path.abspath(model), "start_paused": True, "on_divergence": on_divergence},
              "worlds": {"count": worlds, "threads": threads},
              "transports": {"jsonrpc": {"plugin": "jsonrpc", "options": {"host": "127.0.0.1", "port": 0}}},
              "services": {"default": ["jsonrpc"]},
              "log_level": "warning"}
    path = os.path.join(workdir, "farm.json")
    with open(path, "w") as f:
        json.dump(config, f)
    endpoints = os.path.join(workdir, "endpoints.json")
    log = open(os.path.join(workdir, "run.log"), "w+")
    process = subprocess.Popen([simgate, "run", path, "--endpoints-file", endpoints], stdout=log,
                               stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 120
    while not os.path.exists(endpoints):
        if process.poll() is not None or time.monotonic() > deadline:
            log.seek(0)
            raise RuntimeError("simgate run did not start:\n" + log.read())
        time.sleep(0.02)  # polling for the file the child writes; bounded by the deadline
    with open(endpoints) as f:
        port = int(json.load(f)["jsonrpc"][0].rsplit(":", 1)[1])
    return process, port


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--simgate", required=True)
    parser.add_argument("--model", required=True)
    parser.add_argument("--worlds", type=int, default=64)
    parser.add_argument("--n", type=int, action="append", help="steps per step_many call (repeatable; default 1 and 10)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=0,
                        help="step_many's threads (the config's worlds.threads; 0: one per core)")
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--pipelined-only", action="store_true",
                        help="only the pipelined calls (no one-by-one calls, no round trips)")
    parser.add_argument("--on-divergence", default="reset",
                        help="the scene's policy (default reset, what a learner's episodes want: "
                             "pause keeps the state before every step to undo a diverging one)")
    args = parser.parse_args()
    ns = [] if args.pipelined_only else args.n or [1, 10]
    with tempfile.TemporaryDirectory() as workdir:
        process, port = start(args.simgate, args.model, args.worlds, workdir, args.on_divergence,
                              args.threads)
        try:
            rpc = Rpc(port)
            # the controls: the middle of each actuator's range (0 without one), from the
            # sizes world 0 reports
            probe = rpc.call("simulation.step_many", {"worlds": [0], "n": 1, "observe": ["ctrl"]})
            nu = len(probe["worlds"][0]["ctrl"])
            actions = [[0.0] * nu for _ in range(args.worlds)]
            out = {"worlds": args.worlds, "actuators": nu, "model": os.path.basename(args.model),
                   "on_divergence": args.on_divergence,
                   "step_many": {str(n): [] for n in ns}, "pipelined": [], "round_trips": []}
            for _ in range(args.rounds):
                for n in ns:
                    params = {"n": n, "actions": actions, "observe": OBSERVE}
                    calls = 0
                    start_t = time.perf_counter()
                    end_t = start_t + args.seconds
                    while True:
                        result = rpc.call("simulation.step_many", params)
                        calls += 1
                        now = time.perf_counter()
                        if now >= end_t:
                            break
                    assert all(w["steps_done"] == n for w in result["worlds"]), result
                    out["step_many"][str(n)].append(calls * n * args.worlds / (now - start_t))
                out["pipelined"].append(pipelined(rpc, args.worlds, nu, 10, args.seconds))
                if args.pipelined_only:
                    continue
                steps = 0
                start_t = time.perf_counter()
                end_t = start_t + args.seconds
                while True:
                    for k in range(args.worlds):
                        rpc.call(("w%d/" % k if k else "") + "simulation.step", {"n": 1})
                    steps += args.worlds
                    now = time.perf_counter()
                    if now >= end_t:
                        break
                out["round_trips"].append(steps / (now - start_t))
            print(json.dumps(out))
        finally:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout=60)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


if __name__ == "__main__":
    sys.exit(main())
