#!/usr/bin/python3
"""simgate benchmark harness: runs every comparison of issue 7 and writes the results.

Each figure is measured beside its baseline in the same run, repeated, and reported as a
ratio with its median and spread (min..max over the repeats); a ratio is always computed
between two measurements of the same repeat. Everything talks to 127.0.0.1 only; every
loop is bounded in count and time; every process it starts is stopped before it returns.

Sections (each ends "ok", "error" with the reason, or "skipped" when a part was not built):
  socket   the socket transport vs the Asio line-echo limit: round-trip latency (1
           outstanding) and pipelined throughput (windows 1/64/256 x 1/4 connections).
           Two echoes: the limit polls before sleeping with the transports' idle-spin rule
           (--spin-us 50, as their default io_spin_us); the "plain Asio server" sleeps in
           epoll_wait. Targets are taken against the limit; ratios to both are reported
  jsonrpc  the JSON-RPC transport vs the same two echoes (JSON-RPC-sized lines)
  websocket  issue #23: the websocket transport's sync round trip (JSON-RPC over WebSocket,
           a Beast client) vs the JSON-RPC transport's (TCP lines), the same request, both
           servers up at once, alternating runs in each repeat; issue #38: the same call as
           a Foxglove service call (the foxglove transport) vs JSON-RPC over WebSocket
  dds      simgate's DDS round trip vs a raw Cyclone ping-pong (same types, QoS, payload)
  peers    MORSE's Python SocketRequestManager vs the socket transport; jayson@5's TCP
           server vs the JSON-RPC transport; all with the same client
  sim      gateway steps/s (as fast as possible) vs a bare mj_step loop on the same MJCF;
           real-time factor and step jitter at real-time pacing, idle and under
           10 000 requests/s
  foxglove issue #38: the real-time factor with /tf at 60 Hz (50 bodies) and a 640x480 camera
           at 10 Hz to 4 Foxglove clients vs no client
  memory   resident memory of an idle gateway (demo config) and with 1 000 idle connections
  byor     issue #18, bring your own robot: the gateway stepping Debian's humanoid with its
           generic components vs bare mj_step (same model, same steps); the sync round trip
           of a 40-value `sensors` component's get_local_data vs `time now` (same gateway,
           real time); a 360-ray laser_scanner update vs the same bare mj_ray loop
  world    issue #19: `simulation step [1]` calls/s back to back on a gateway started
           paused (socket) vs 1 / (`time now` round trip p50 + one bare mj_step), the same
           gateway and connection kind; save_state / restore_state vs mj_copyData
  progress issue #20: the real-time factor while 100 concurrent JSON-RPC calls get progress
           reports at 1 kHz each vs the same calls without progress, alternating rounds in
           one gateway (simgate_bench_sim --mode progress)
  streams  issue #21: 50 pose sensors streaming at 100 Hz on every transport (real-time
           factor, CPU, latency); a DDS pose stream vs a raw Cyclone writer
  cameras  issue #22: camera frames/s (320x240, 640x480; RGB and depth) through simgate's
           Renderer (scene copy, render thread, pixels back; with and without the PNG record)
           vs a bare mjv_updateScene + mjr_render + mjr_readPixels loop on the same kind of
           EGL context; the real-time factor of config/rover.json with a JSON-RPC client
           subscribed to its 10 Hz camera stream vs none. "skipped" when no EGL context can
           be made (no GPU is needed: Mesa's llvmpipe renders surfaceless)
  web      issue #23: the real-time factor of config/demo.json (the web app's deployment)
           while 20 WebSocket clients (browser pages) receive the body poses at 60 Hz vs none
           (simgate_bench_sim --mode web_poses)
  recording  issue #39: config/demo.json as fast as possible recorded to MCAP (simgate_bench_sim
           --mode gateway --record) vs not, alternating: steps/s with no client, `time now`
           round trip (socket) meanwhile; the replay of that recording (simgate replay --verify
           --json) vs a bare mj_step loop on the same MJCF
  gym      issue #40: simgate.gym's env.step() steps/s over loopback (bench/gym_bench.py: the
           cartpole of tests/python and Debian's humanoid) vs the raw JSON-RPC round trip of
           the same batch from a bare socket loop, alternating rounds on one simgate, and vs a
           bare mj_step loop on the same MJCF. "skipped" without gymnasium and numpy (scripts/
           lib.sh ensure_python_test_clients) or simgate_bench_sim

Usage: bench/harness.py --build-dir DIR [--out DIR] [--smoke] [--repeats N]
Normally run through bench/run, which builds first. Writes DIR/results.json and
DIR/results.md; exits 1 if a section failed.
"""
import argparse
import datetime
import json
import os
import platform
import select
import shutil
import signal
import statistics
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The echo limit waits as simgate's TCP transports do: polls this long after each event
# before sleeping (their default io_spin_us, simgate/core/idle_spin.h). The plain Asio
# server peer is the same echo with 0 (it sleeps in epoll_wait).
ECHO_SPIN_US = 50
PINNING = "none: every server, client and peer runs unpinned (no taskset), on both sides of every comparison"


class BenchError(Exception):
    """A measurement could not be made (a process failed, a reply was wrong, a timeout)."""


# ---------------------------------------------------------------------------------------
# processes


class Process:
    """A server or peer started for a section; reads its JSON announcement from stdout."""

    def __init__(self, name, argv, logs, env=None, stdin=subprocess.DEVNULL):
        self.name = name
        self.log_path = os.path.join(logs, name + ".log")
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=self.log, stdin=stdin,
                                     env=env, cwd=ROOT)
        self.buffer = b""

    def read_json(self, key, timeout):
        """The first JSON object on stdout that has `key` (other lines are ignored)."""
        deadline = time.monotonic() + timeout
        fd = self.proc.stdout.fileno()
        while True:
            while b"\n" in self.buffer:
                line, self.buffer = self.buffer.split(b"\n", 1)
                line = line.strip()
                if line.startswith(b"{"):
                    try:
                        obj = json.loads(line)
                    except ValueError:
                        continue
                    if key in obj:
                        return obj
            left = deadline - time.monotonic()
            if left <= 0:
                raise BenchError(f"{self.name}: no '{key}' on stdout within {timeout:.0f} s (log: {self.log_path})")
            ready, _, _ = select.select([fd], [], [], min(left, 0.5))
            if ready:
                chunk = os.read(fd, 65536)
                if not chunk:
                    code = self.proc.wait(timeout=5)
                    raise BenchError(f"{self.name}: exited with code {code} before printing '{key}' "
                                     f"({tail(self.log_path)})")
                self.buffer += chunk

    def rss_kib(self):
        with open(f"/proc/{self.proc.pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
        raise BenchError(f"{self.name}: no VmRSS in /proc/{self.proc.pid}/status")

    def pause(self):
        """SIGSTOP: a peer that busy-polls (MORSE's loop) must not take a CPU while the
        servers it is compared with are measured."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGSTOP)

    def resume(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGCONT)

    def stop(self, timeout=20):
        """SIGTERM, then the exit code (SIGKILL after `timeout`); non-zero codes are errors."""
        self.resume()  # a paused process would hold SIGTERM until continued
        if self.proc.stdin:
            # programs told to stop by closing stdin finish on their own first
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                pass
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            code = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            code = "killed"
        self.proc.stdout.close()
        self.log.close()
        return code

    def check_stopped(self):
        """Stops; a non-zero exit code is an error, unless another error is already on its
        way (called from `finally`: the first error is the one worth reporting)."""
        pending = sys.exc_info()[1]
        code = self.stop()
        if code != 0 and pending is None:
            raise BenchError(f"{self.name}: exit code {code} at shutdown ({tail(self.log_path)})")


def tail(path, lines=5):
    try:
        with open(path, errors="replace") as f:
            text = f.read().strip().splitlines()[-lines:]
        return "log tail: " + " | ".join(text) if text else "empty log"
    except OSError:
        return "no log"


def run_json(argv, timeout, env=None):
    """Runs a client to completion and returns the last JSON object it printed."""
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT)
    except subprocess.TimeoutExpired:
        raise BenchError(f"{os.path.basename(argv[0])}: still running after {timeout:.0f} s")
    if done.returncode != 0:
        raise BenchError(f"{os.path.basename(argv[0])} {' '.join(argv[1:])}: exit code {done.returncode}: "
                         f"{done.stderr.strip()[-400:]}")
    for line in reversed(done.stdout.strip().splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    raise BenchError(f"{os.path.basename(argv[0])}: no JSON result on stdout")


def socket_call(port, request):
    """One request on a new connection to the socket transport at 127.0.0.1:`port`: its
    SUCCESS value (JSON). Anything else is an error."""
    import socket
    with socket.create_connection(("127.0.0.1", port), timeout=10) as c:
        c.sendall(b"1 " + request.encode() + b"\n")
        reply = b""
        while not reply.endswith(b"\n"):
            chunk = c.recv(65536)
            if not chunk:
                break
            reply += chunk
    head, _, body = reply.decode().strip().partition(" SUCCESS ")
    if head != "1" or not body:
        raise BenchError(f"{request}: unexpected reply {reply[:200]!r}")
    return json.loads(body)


def port_of(endpoints):
    """The port of the first tcp:// (or ws://host:port/, http://host:port/path) endpoint."""
    for e in endpoints:
        m = re.match(r"(?:tcp|ws|http)://[^/]*:(\d+)(?:/.*)?$", e)
        if m:
            return int(m.group(1))
    raise BenchError(f"no tcp://, ws:// or http:// endpoint in {endpoints}")


# ---------------------------------------------------------------------------------------
# statistics


def spread(values):
    values = [v for v in values if v is not None]
    if not values:
        return None
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "n": len(values)}


def in_order(repeat, first, second):
    """Runs both measurements of a pair, swapping their order on odd repeats so that neither
    side always runs first (a warm cache or a quieter moment); returns (first, second)."""
    if repeat % 2 == 0:
        a = first()
        return a, second()
    b = second()
    return first(), b


def in_rotation(repeat, *measurements):
    """Runs every measurement of a group, starting with a different one on each repeat (the
    order rotates), so that none always runs first; returns the results in argument order."""
    n = len(measurements)
    results = [None] * n
    for k in range(n):
        i = (repeat + k) % n
        results[i] = measurements[i]()
    return tuple(results)


def ratio(a, b):
    return a / b if a is not None and b not in (None, 0) else None


# ---------------------------------------------------------------------------------------
# the harness


class Harness:
    def __init__(self, args):
        self.args = args
        self.smoke = args.smoke
        self.build = os.path.abspath(args.build_dir)
        self.bin = os.path.join(self.build, "bin")
        self.out = os.path.abspath(args.out)
        self.logs = os.path.join(self.out, "logs")
        os.makedirs(self.logs, exist_ok=True)
        self.repeats = args.repeats or (1 if self.smoke else 3)
        # sizes: seconds of each throughput run, round trips of each latency run
        self.duration = 0.15 if self.smoke else 1.0
        self.warmup_s = 0.05 if self.smoke else 0.3
        self.count = 50 if self.smoke else 2000
        self.windows = [1, 64] if self.smoke else [1, 64, 256]
        self.connections = [1] if self.smoke else [1, 4]
        self.env = dict(os.environ)
        self.env["SIMGATE_PLUGIN_PATH"] = os.path.join(self.build, "plugins")
        self.env["CYCLONEDDS_URI"] = "file://" + os.path.join(ROOT, "config", "dds", "loopback.xml")
        self.env.setdefault("ASAN_OPTIONS", "detect_leaks=1")
        self.results = {"sections": {}, "targets": []}
        self.timeout = 120 if self.smoke else 300  # per client run (sanitizer builds are slow)

    def exe(self, name):
        path = os.path.join(self.bin, name)
        if not os.access(path, os.X_OK):
            raise FileNotFoundError(path)
        return path

    def plugin_built(self, name):
        return os.path.exists(os.path.join(self.build, "plugins", f"libsimgate_transport_{name}.so"))

    # ---- common measurements

    def loadgen(self, port, proto_args, mode_args):
        return run_json([self.exe("simgate_bench_loadgen"), "--port", str(port)] + proto_args + mode_args,
                        self.timeout, self.env)

    def latency(self, port, proto_args, count=None):
        r = self.loadgen(port, proto_args, ["--mode", "latency", "--count", str(count or self.count)])
        if r["errors"]:
            raise BenchError(f"{r['errors']} wrong replies (first: {r.get('first_reply')!r})")
        return r

    def throughput(self, port, proto_args, window, connections):
        r = self.loadgen(port, proto_args, ["--mode", "throughput", "--window", str(window),
                                            "--connections", str(connections), "--duration", str(self.duration),
                                            "--warmup-seconds", str(self.warmup_s)])
        if r["errors"]:
            raise BenchError(f"{r['errors']} wrong replies (first: {r.get('first_reply')!r})")
        if not r["replies"]:
            raise BenchError(f"no replies counted at window {window}, {connections} connection(s)")
        return r

    def host(self, transport, options):
        p = Process(f"host-{transport}", [self.exe("simgate_bench_host"), "--transport", transport,
                                          "--options", json.dumps(options)], self.logs, self.env)
        p.announcement = p.read_json("endpoints", 60)
        return p

    def echo(self, spin_us=ECHO_SPIN_US):
        """The echo limit (polling as the transports do), or with spin_us=0 the plain Asio
        server (sleeps in epoll_wait)."""
        p = Process("echo" if spin_us else "echo-plain",
                    [self.exe("simgate_bench_echo"), "--spin-us", str(spin_us)], self.logs, self.env)
        p.port = p.read_json("port", 30)["port"]
        return p

    def compare_tcp(self, name, server_port, echo_port, plain_port, proto_args, windows, connections):
        """Latency and throughput of a server, of the echo limit (polling) and of the plain
        Asio server (the sleeping echo), the three in rotating order within each repeat."""
        rows = {"latency": [], "throughput": {}}
        for rep in range(self.repeats):
            echo, plain, server = in_rotation(rep, lambda: self.latency(echo_port, proto_args + ["--echo"]),
                                              lambda: self.latency(plain_port, proto_args + ["--echo"]),
                                              lambda: self.latency(server_port, proto_args))
            rows["latency"].append({"echo": echo, "plain": plain, name: server,
                                    "ratio_p50": ratio(server["p50_us"], echo["p50_us"]),
                                    "ratio_p99": ratio(server["p99_us"], echo["p99_us"]),
                                    "plain_ratio_p50": ratio(server["p50_us"], plain["p50_us"]),
                                    "plain_ratio_p99": ratio(server["p99_us"], plain["p99_us"])})
            for c in connections:
                for w in windows:
                    key = f"w{w}_c{c}"
                    echo_t, plain_t, server_t = in_rotation(
                        rep, lambda: self.throughput(echo_port, proto_args + ["--echo"], w, c),
                        lambda: self.throughput(plain_port, proto_args + ["--echo"], w, c),
                        lambda: self.throughput(server_port, proto_args, w, c))
                    rows["throughput"].setdefault(key, []).append(
                        {"echo": echo_t, "plain": plain_t, name: server_t,
                         "ratio": ratio(server_t["rps"], echo_t["rps"]),
                         "plain_ratio": ratio(server_t["rps"], plain_t["rps"])})
        return rows

    @staticmethod
    def summarize_tcp(rows, name):
        """echo_* and ratio* are against the echo limit (polling); plain_* against the plain
        Asio server (the sleeping echo)."""
        out = {"latency": {
            "server_p50_us": spread([r[name]["p50_us"] for r in rows["latency"]]),
            "server_p99_us": spread([r[name]["p99_us"] for r in rows["latency"]]),
            "echo_p50_us": spread([r["echo"]["p50_us"] for r in rows["latency"]]),
            "echo_p99_us": spread([r["echo"]["p99_us"] for r in rows["latency"]]),
            "ratio_p50": spread([r["ratio_p50"] for r in rows["latency"]]),
            "ratio_p99": spread([r["ratio_p99"] for r in rows["latency"]]),
            "plain_p50_us": spread([r["plain"]["p50_us"] for r in rows["latency"]]),
            "plain_p99_us": spread([r["plain"]["p99_us"] for r in rows["latency"]]),
            "plain_ratio_p50": spread([r["plain_ratio_p50"] for r in rows["latency"]]),
            "plain_ratio_p99": spread([r["plain_ratio_p99"] for r in rows["latency"]]),
        }, "throughput": {}, "echo_spin_us": ECHO_SPIN_US}
        for key, runs in rows["throughput"].items():
            out["throughput"][key] = {
                "server_rps": spread([r[name]["rps"] for r in runs]),
                "echo_rps": spread([r["echo"]["rps"] for r in runs]),
                "ratio": spread([r["ratio"] for r in runs]),
                "plain_rps": spread([r["plain"]["rps"] for r in runs]),
                "plain_ratio": spread([r["plain_ratio"] for r in runs]),
            }
        return out

    @staticmethod
    def report_both(label, s):
        """One stderr line: the sync p50 and window-64 throughput ratios to both echoes."""
        def m(v):
            return "–" if not v else f"{v['median']:.2f}"
        lat, w64 = s["latency"], s["throughput"].get("w64_c1", {})
        print(f"[bench] {label}: sync round trip p50 / echo limit (polling) {m(lat['ratio_p50'])}, "
              f"/ plain Asio server (sleeping) {m(lat['plain_ratio_p50'])}; throughput (window 64, 1 conn.) "
              f"/ echo limit {m(w64.get('ratio'))}, / plain Asio server {m(w64.get('plain_ratio'))}",
              file=sys.stderr, flush=True)

    def target(self, what, value, op, threshold, unit=""):
        """Records a target of the issue and whether this run met it (never asserted)."""
        v = value["median"] if isinstance(value, dict) and value else value
        met = None if v is None else (v <= threshold if op == "<=" else v >= threshold)
        self.results["targets"].append({"target": what, "value": value, "op": op, "threshold": threshold,
                                        "unit": unit, "met": met})

    # ---- sections

    def section_socket(self):
        if not self.plugin_built("socket"):
            return {"status": "skipped", "reason": "libsimgate_transport_socket.so is not built"}
        echo = self.echo()
        plain = host = None
        try:
            plain = self.echo(spin_us=0)
            host = self.host("socket", {"host": "127.0.0.1", "port": 0})
            port = port_of(host.announcement["endpoints"])
            rows = self.compare_tcp("socket", port, echo.port, plain.port, ["--proto", "socket"], self.windows,
                                    self.connections)
        finally:
            echo.check_stopped()
            if plain:
                plain.check_stopped()
            if host:
                host.check_stopped()
        s = self.summarize_tcp(rows, "socket")
        self.report_both("socket", s)
        self.target("socket sync round trip p50 / echo p50", s["latency"]["ratio_p50"], "<=", 1.3, "x")
        self.target("socket pipelined throughput (window 64, 1 connection) / echo", s["throughput"]["w64_c1"]["ratio"],
                    ">=", 0.5, "x")
        if "w64_c4" in s["throughput"]:  # issue #37's gap: four clients pipelining at once
            self.target("socket pipelined throughput (window 64, 4 connections) / echo",
                        s["throughput"]["w64_c4"]["ratio"], ">=", 0.5, "x")
        return {"status": "ok", "summary": s, "runs": rows}

    def section_jsonrpc(self):
        if not self.plugin_built("jsonrpc"):
            return {"status": "skipped", "reason": "libsimgate_transport_jsonrpc.so is not built"}
        echo = self.echo()
        plain = host = None
        try:
            plain = self.echo(spin_us=0)
            host = self.host("jsonrpc", {"host": "127.0.0.1", "port": 0})
            port = port_of(host.announcement["endpoints"])
            rows = self.compare_tcp("jsonrpc", port, echo.port, plain.port, ["--proto", "jsonrpc"], self.windows,
                                    self.connections)
        finally:
            echo.check_stopped()
            if plain:
                plain.check_stopped()
            if host:
                host.check_stopped()
        s = self.summarize_tcp(rows, "jsonrpc")
        self.report_both("jsonrpc", s)
        self.target("JSON-RPC sync round trip p50 / echo p50", s["latency"]["ratio_p50"], "<=", 1.3, "x")
        self.target("JSON-RPC pipelined throughput (window 64, 1 connection) / echo",
                    s["throughput"]["w64_c1"]["ratio"], ">=", 0.35, "x")
        if "w64_c4" in s["throughput"]:  # issue #37's gap: four clients pipelining at once
            self.target("JSON-RPC pipelined throughput (window 64, 4 connections) / echo",
                        s["throughput"]["w64_c4"]["ratio"], ">=", 0.5, "x")
        return {"status": "ok", "summary": s, "runs": rows}

    def section_websocket(self):
        if not self.plugin_built("websocket") or not self.plugin_built("jsonrpc"):
            return {"status": "skipped", "reason": "libsimgate_transport_websocket.so or _jsonrpc.so is not built"}
        tcp = ws = fox = None
        rows = []
        try:
            tcp = self.host("jsonrpc", {"host": "127.0.0.1", "port": 0})
            ws = self.host("websocket", {"host": "127.0.0.1", "port": 0})
            tcp_port, ws_port = port_of(tcp.announcement["endpoints"]), port_of(ws.announcement["endpoints"])
            # issue #38: a Foxglove service call against the same call over JSON-RPC on WebSocket
            if self.plugin_built("foxglove"):
                fox = self.host("foxglove", {"host": "127.0.0.1", "port": 0})
                fox_port = port_of(fox.announcement["endpoints"])
            for rep in range(self.repeats):
                measured = [lambda: self.latency(tcp_port, ["--proto", "jsonrpc"]),
                            lambda: self.latency(ws_port, ["--proto", "ws-jsonrpc"])]
                if fox:
                    measured.append(lambda: self.latency(fox_port, ["--proto", "foxglove"]))
                t, w, *f = in_rotation(rep, *measured)
                row = {"jsonrpc": t, "websocket": w, "ratio_p50": ratio(w["p50_us"], t["p50_us"]),
                       "ratio_p99": ratio(w["p99_us"], t["p99_us"])}
                if f:
                    row.update(foxglove=f[0], foxglove_ratio_p50=ratio(f[0]["p50_us"], w["p50_us"]))
                rows.append(row)
        finally:
            for h in (tcp, ws, fox):
                if h:
                    h.check_stopped()
        s = {"websocket_p50_us": spread([r["websocket"]["p50_us"] for r in rows]),
             "jsonrpc_p50_us": spread([r["jsonrpc"]["p50_us"] for r in rows]),
             "websocket_p99_us": spread([r["websocket"]["p99_us"] for r in rows]),
             "jsonrpc_p99_us": spread([r["jsonrpc"]["p99_us"] for r in rows]),
             "ratio_p50": spread([r["ratio_p50"] for r in rows]),
             "ratio_p99": spread([r["ratio_p99"] for r in rows])}
        print(f"[bench] websocket: sync round trip p50 {s['websocket_p50_us']['median']:.1f} us, "
              f"JSON-RPC over TCP {s['jsonrpc_p50_us']['median']:.1f} us, ratio {s['ratio_p50']['median']:.2f}",
              file=sys.stderr, flush=True)
        self.target("WebSocket sync round trip p50 / JSON-RPC (TCP) p50", s["ratio_p50"], "<=", 1.3, "x")
        if fox:
            s["foxglove_p50_us"] = spread([r["foxglove"]["p50_us"] for r in rows])
            s["foxglove_ratio_p50"] = spread([r["foxglove_ratio_p50"] for r in rows])
            print(f"[bench] foxglove: service round trip p50 {s['foxglove_p50_us']['median']:.1f} us, "
                  f"ratio to JSON-RPC over WebSocket {s['foxglove_ratio_p50']['median']:.2f}",
                  file=sys.stderr, flush=True)
            self.target("Foxglove service round trip p50 / WebSocket JSON-RPC p50", s["foxglove_ratio_p50"],
                        "<=", 1.3, "x")
        return {"status": "ok", "summary": s, "runs": rows}

    def section_mcp(self):
        """Issue #42: an MCP tool call (streamable HTTP, one kept-alive connection) against the
        same service called over JSON-RPC on TCP, in the same run, in rotating order."""
        if not self.plugin_built("mcp") or not self.plugin_built("jsonrpc"):
            return {"status": "skipped", "reason": "libsimgate_transport_mcp.so or _jsonrpc.so is not built"}
        tcp = mcp = None
        rows = []
        named = ["--method", "test_component.add", "--params", '{"a":1,"b":2}']
        try:
            tcp = self.host("jsonrpc", {"host": "127.0.0.1", "port": 0})
            mcp = self.host("mcp", {"host": "127.0.0.1", "port": 0, "max_calls_per_s": 1e6})
            tcp_port, mcp_port = port_of(tcp.announcement["endpoints"]), port_of(mcp.announcement["endpoints"])
            for rep in range(self.repeats):
                t, m = in_rotation(rep, lambda: self.latency(tcp_port, ["--proto", "jsonrpc"] + named),
                                   lambda: self.latency(mcp_port, ["--proto", "mcp"] + named))
                rows.append({"jsonrpc": t, "mcp": m, "ratio_p50": ratio(m["p50_us"], t["p50_us"]),
                             "ratio_p99": ratio(m["p99_us"], t["p99_us"])})
        finally:
            for h in (tcp, mcp):
                if h:
                    h.check_stopped()
        s = {"mcp_p50_us": spread([r["mcp"]["p50_us"] for r in rows]),
             "jsonrpc_p50_us": spread([r["jsonrpc"]["p50_us"] for r in rows]),
             "mcp_p99_us": spread([r["mcp"]["p99_us"] for r in rows]),
             "jsonrpc_p99_us": spread([r["jsonrpc"]["p99_us"] for r in rows]),
             "ratio_p50": spread([r["ratio_p50"] for r in rows]),
             "ratio_p99": spread([r["ratio_p99"] for r in rows])}
        print(f"[bench] mcp: tool call round trip p50 {s['mcp_p50_us']['median']:.1f} us, "
              f"JSON-RPC over TCP {s['jsonrpc_p50_us']['median']:.1f} us, ratio {s['ratio_p50']['median']:.2f}",
              file=sys.stderr, flush=True)
        self.target("MCP tool call round trip p50 / JSON-RPC (TCP) p50", s["ratio_p50"], "<=", 1.5, "x")
        return {"status": "ok", "summary": s, "runs": rows}

    def section_dds(self):
        if not self.plugin_built("dds") or not os.access(os.path.join(self.bin, "simgate_bench_dds"), os.X_OK):
            return {"status": "skipped", "reason": "the DDS transport or simgate_bench_dds is not built"}
        domain = 17  # away from the default domain 0 that tests and demos use
        tag = f"simgate-bench-{os.getpid()}"
        pong = Process("dds-pong", [self.exe("simgate_bench_dds"), "--mode", "pong", "--domain", str(domain),
                                    "--partition", tag + "-raw", "--timeout", "900"], self.logs, self.env)
        host = None
        runs = []
        try:
            pong.read_json("ready", 60)
            host = self.host("dds", {"domain": domain, "partition": tag + "-simgate"})
            common = ["--domain", str(domain), "--count", str(self.count), "--timeout", "120"]
            for rep in range(self.repeats):
                raw, sg = in_order(
                    rep,
                    lambda: run_json([self.exe("simgate_bench_dds"), "--mode", "ping", "--partition", tag + "-raw"]
                                     + common, self.timeout, self.env),
                    lambda: run_json([self.exe("simgate_bench_dds"), "--mode", "client", "--partition",
                                      tag + "-simgate"] + common, self.timeout, self.env))
                if raw["errors"] or sg["errors"]:
                    raise BenchError(f"DDS replies wrong: raw {raw['errors']}, simgate {sg['errors']}")
                runs.append({"raw": raw, "simgate": sg, "ratio_p50": ratio(sg["p50_us"], raw["p50_us"]),
                             "ratio_p99": ratio(sg["p99_us"], raw["p99_us"])})
        finally:
            pong.check_stopped()
            if host:
                host.check_stopped()
        s = {"simgate_p50_us": spread([r["simgate"]["p50_us"] for r in runs]),
             "simgate_p99_us": spread([r["simgate"]["p99_us"] for r in runs]),
             "raw_p50_us": spread([r["raw"]["p50_us"] for r in runs]),
             "raw_p99_us": spread([r["raw"]["p99_us"] for r in runs]),
             "ratio_p50": spread([r["ratio_p50"] for r in runs]),
             "ratio_p99": spread([r["ratio_p99"] for r in runs])}
        self.target("DDS round trip p50 / raw Cyclone ping-pong p50", s["ratio_p50"], "<=", 1.3, "x")
        return {"status": "ok", "summary": s, "runs": runs}

    def peer_compare(self, peer_name, peer_argv, transport, proto_args, windows, env):
        """A peer server against a simgate transport, same client, interleaved per repeat.

        The echo limit is measured in the same repeat with the same lines: echo / peer is
        the highest ratio any server could show against this peer on this machine."""
        peer = Process(peer_name, peer_argv, self.logs, env)
        host = None
        echo = None
        runs = []
        def measure_peer(fn):
            # the peer runs only for its own measurements: MORSE's standalone loop spins a
            # CPU even when idle, which would leave simgate and the echo one CPU of two
            peer.resume()
            try:
                return fn()
            finally:
                peer.pause()

        try:
            peer_port = peer.read_json("port", 60)["port"]
            peer.pause()
            host = self.host(transport, {"host": "127.0.0.1", "port": 0})
            echo = self.echo()
            port = port_of(host.announcement["endpoints"])
            for rep in range(self.repeats):
                lp, ls = in_order(rep, lambda: measure_peer(lambda: self.latency(peer_port, proto_args)),
                                  lambda: self.latency(port, proto_args))
                le = self.latency(echo.port, proto_args + ["--echo"])
                run = {"latency": {"peer": lp, "simgate": ls, "echo": le, "ratio_p50": ratio(ls["p50_us"], lp["p50_us"]),
                                   "echo_ratio_p50": ratio(le["p50_us"], lp["p50_us"])},
                       "throughput": {}}
                for w in windows:
                    tp, ts = in_order(rep, lambda: measure_peer(lambda: self.throughput(peer_port, proto_args, w, 1)),
                                      lambda: self.throughput(port, proto_args, w, 1))
                    te = self.throughput(echo.port, proto_args + ["--echo"], w, 1)
                    run["throughput"][f"w{w}_c1"] = {"peer": tp, "simgate": ts, "echo": te,
                                                     "ratio": ratio(ts["rps"], tp["rps"]),
                                                     "echo_ratio": ratio(te["rps"], tp["rps"])}
                runs.append(run)
        finally:
            peer.check_stopped()
            if host:
                host.check_stopped()
            if echo:
                echo.check_stopped()
        s = {"latency": {"peer_p50_us": spread([r["latency"]["peer"]["p50_us"] for r in runs]),
                         "simgate_p50_us": spread([r["latency"]["simgate"]["p50_us"] for r in runs]),
                         "echo_p50_us": spread([r["latency"]["echo"]["p50_us"] for r in runs]),
                         "ratio_p50": spread([r["latency"]["ratio_p50"] for r in runs]),
                         "echo_ratio_p50": spread([r["latency"]["echo_ratio_p50"] for r in runs])},
             "throughput": {}}
        for w in windows:
            key = f"w{w}_c1"
            s["throughput"][key] = {"peer_rps": spread([r["throughput"][key]["peer"]["rps"] for r in runs]),
                                    "simgate_rps": spread([r["throughput"][key]["simgate"]["rps"] for r in runs]),
                                    "echo_rps": spread([r["throughput"][key]["echo"]["rps"] for r in runs]),
                                    "ratio": spread([r["throughput"][key]["ratio"] for r in runs]),
                                    "echo_ratio": spread([r["throughput"][key]["echo_ratio"] for r in runs])}
        return {"summary": s, "runs": runs}

    def section_peers(self):
        out = {"status": "ok"}
        # MORSE's request manager: at most 4096 bytes per read, so windows stay below that
        if not self.plugin_built("socket"):
            out["morse"] = {"status": "skipped", "reason": "the socket transport is not built"}
        else:
            m = self.peer_compare("morse", ["/usr/bin/python3", os.path.join(ROOT, "bench", "peers", "morse_peer.py")],
                                  "socket", ["--proto", "socket"], [1, 64], self.env)
            out["morse"] = dict(status="ok", **m)
            self.target("socket throughput (window 64) / MORSE's Python request manager",
                        m["summary"]["throughput"]["w64_c1"]["ratio"], ">=", 50, "x")
            self.target("socket round trip p50 / MORSE's", m["summary"]["latency"]["ratio_p50"], "<=", 0.5, "x")
        if not self.plugin_built("jsonrpc"):
            out["jayson"] = {"status": "skipped", "reason": "the JSON-RPC transport is not built"}
        else:
            if not os.path.isdir(os.path.join(ROOT, "bench", "node_modules", "jayson")):
                raise BenchError("bench/node_modules/jayson is missing: run `npm install` in bench/ "
                                 "(scripts/test and bench/run do)")
            j = self.peer_compare("jayson", ["node", os.path.join(ROOT, "bench", "peers", "jayson_peer.js")],
                                  "jsonrpc", ["--proto", "jsonrpc"], [1, 64], self.env)
            out["jayson"] = dict(status="ok", **j)
            self.target("JSON-RPC throughput (window 64) / jayson@5 TCP server",
                        j["summary"]["throughput"]["w64_c1"]["ratio"], ">=", 10, "x")
        return out

    def demo_config(self, port=0):
        """config/demo.json with the socket transport on an ephemeral port and an absolute MJCF."""
        with open(os.path.join(ROOT, "config", "demo.json")) as f:
            cfg = json.load(f)
        cfg["scene"]["mjcf"] = os.path.join(ROOT, "config", cfg["scene"]["mjcf"])
        for t in cfg.get("transports", {}).values():
            if "options" in t and "port" in t["options"]:
                t["options"]["port"] = port
        cfg["log_level"] = "warning"
        path = os.path.join(self.out, "demo-bench.json")
        with open(path, "w") as f:
            json.dump(cfg, f, indent=1)
        return path, cfg["scene"]["mjcf"]

    def sim_gateway(self, config, factor, duration, load_rate=None, label="gateway"):
        p = Process(f"sim-{label}", [self.exe("simgate_bench_sim"), "--mode", "gateway", "--config", config,
                                     "--realtime-factor", str(factor), "--duration", str(duration + 60),
                                     "--until-stdin-closes"], self.logs, self.env, stdin=subprocess.PIPE)
        try:
            endpoints = p.read_json("endpoints", 60)["endpoints"]
            load = None
            if load_rate:
                port = port_of(endpoints.get("socket", []))
                load = self.loadgen(port, ["--proto", "socket", "--request", "time now"],
                                    ["--mode", "rate", "--rate", str(load_rate), "--duration", str(duration)])
                if load["errors"]:
                    raise BenchError(f"{load['errors']} wrong replies from `time now` under load")
            else:
                time.sleep(duration)
            p.proc.stdin.close()
            result = p.read_json("steps_per_s", 120)
            result["load"] = load
        finally:
            p.check_stopped()
        return result

    def section_sim(self):
        if not os.access(os.path.join(self.bin, "simgate_bench_sim"), os.X_OK):
            return {"status": "skipped", "reason": "simgate_bench_sim (needs the gateway) is not built"}
        config, mjcf = self.demo_config()
        duration = 0.5 if self.smoke else 3.0
        runs = []
        for rep in range(self.repeats):
            bare, gw = in_order(rep, lambda: run_json([self.exe("simgate_bench_sim"), "--mode", "bare", "--mjcf", mjcf,
                                                       "--duration", str(duration)], self.timeout, self.env),
                                lambda: self.sim_gateway(config, 0, duration, label="max"))
            runs.append({"bare": bare, "gateway": gw, "ratio": ratio(gw["steps_per_s"], bare["steps_per_s"])})
        rt_duration = 1.0 if self.smoke else 5.0
        rate = 1000 if self.smoke else 10000
        # the machine's own timer jitter, same period, just before: what the loop cannot beat
        sleep = run_json([self.exe("simgate_bench_sim"), "--mode", "sleep", "--mjcf", mjcf,
                          "--duration", str(rt_duration)], self.timeout, self.env)
        idle = self.sim_gateway(config, 1, rt_duration, label="realtime-idle")
        loaded = self.sim_gateway(config, 1, rt_duration, load_rate=rate, label="realtime-load")
        s = {"bare_steps_per_s": spread([r["bare"]["steps_per_s"] for r in runs]),
             "gateway_steps_per_s": spread([r["gateway"]["steps_per_s"] for r in runs]),
             "ratio": spread([r["ratio"] for r in runs]),
             "sleep_baseline": {"realtime_factor": sleep["realtime_factor"], "jitter_p50_us": sleep["jitter"]["p50_us"],
                                "jitter_p99_us": sleep["jitter"]["p99_us"], "overruns": sleep["overruns"]},
             "realtime_idle": {"realtime_factor": idle["realtime_factor"], "jitter_p99_us": idle["jitter"]["p99_us"],
                               "jitter_p50_us": idle["jitter"]["p50_us"], "overruns": idle["overruns"]},
             "realtime_load": {"realtime_factor": loaded["realtime_factor"],
                               "jitter_p99_us": loaded["jitter"]["p99_us"], "jitter_p50_us": loaded["jitter"]["p50_us"],
                               "overruns": loaded["overruns"], "target_rps": rate,
                               "achieved_rps": loaded["load"]["achieved_rps"],
                               "request_p50_us": loaded["load"]["p50_us"], "request_p99_us": loaded["load"]["p99_us"]}}
        # issue #19: spawn_entity of one free body (recompiling the scene) beside a bare mj_loadXML of it
        spawn = run_json([self.exe("simgate_bench_sim"), "--mode", "spawn", "--mjcf", mjcf,
                          "--duration", str(0.5 if self.smoke else 5.0)], self.timeout, self.env)
        s["spawn"] = {"rounds": spawn["rounds"], "spawn_entity": spawn["spawn_entity"],
                      "delete_entity": spawn["delete_entity"], "with_entity": spawn["with_entity"],
                      "mj_loadXML": spawn["mj_loadXML"]}
        self.target("gateway steps/s (as fast as possible) / bare mj_step", s["ratio"], ">=", 0.95, "x")
        self.target(f"real-time factor under {rate} req/s", loaded["realtime_factor"], ">=", 0.99)
        return {"status": "ok", "summary": s, "runs": runs, "sleep_baseline": sleep, "realtime_idle": idle,
                "realtime_load": loaded}

    def section_memory(self):
        gateway = os.path.join(self.bin, "simgate")
        if not os.access(gateway, os.X_OK) or not self.plugin_built("socket"):
            return {"status": "skipped", "reason": "build/bin/simgate or the socket transport is not built"}
        config, _ = self.demo_config()
        n = 50 if self.smoke else 1000
        endpoints_file = os.path.join(self.out, "endpoints.json")
        p = Process("gateway-memory", [gateway, "run", config, "--endpoints-file", endpoints_file,
                                       "--log-level", "warning"], self.logs, self.env)
        hold = None
        try:
            deadline = time.monotonic() + 60
            while not os.path.exists(endpoints_file):
                if p.proc.poll() is not None:
                    raise BenchError(f"simgate run exited with {p.proc.returncode} ({tail(p.log_path)})")
                if time.monotonic() > deadline:
                    raise BenchError("simgate run wrote no endpoints file within 60 s")
                time.sleep(0.05)
            with open(endpoints_file) as f:
                port = port_of(json.load(f)["socket"])
            time.sleep(0.5 if self.smoke else 1.0)  # let start-up allocations settle
            idle_kib = p.rss_kib()
            hold = Process("hold", [self.exe("simgate_bench_loadgen"), "--mode", "hold", "--port", str(port),
                                    "--count", str(n), "--duration", "120"], self.logs, self.env,
                           stdin=subprocess.PIPE)
            connected = hold.read_json("connected", 60)["connected"]
            # the gateway has accepted them all when a request on a new connection is answered
            self.loadgen(port, ["--proto", "socket", "--request", "time now"], ["--mode", "latency", "--count", "5",
                                                                               "--warmup", "0"])
            time.sleep(0.5)
            loaded_kib = p.rss_kib()
            hold.proc.stdin.close()
            held = hold.read_json("still_open", 60)
            if held["still_open"] != n:
                raise BenchError(f"the gateway dropped {n - held['still_open']} of {n} idle connections")
        finally:
            if hold:
                hold.stop()
            p.check_stopped()
        s = {"idle_mib": idle_kib / 1024, "with_connections_mib": loaded_kib / 1024,
             "added_mib": (loaded_kib - idle_kib) / 1024, "connections": connected,
             "per_connection_kib": (loaded_kib - idle_kib) / max(connected, 1)}
        self.target("idle gateway resident memory", s["idle_mib"], "<=", 40, "MiB")
        self.target(f"memory added by {n} idle connections", s["added_mib"], "<=", 64 * n / 1000, "MiB")
        return {"status": "ok", "summary": s}

    # ---- issue #18: bring your own robot

    def sensors40_config(self):
        """A deployment serving bench/sensors40.xml's arm and its 40-value `sensors` component
        on the socket transport (ephemeral loopback port), in real time."""
        cfg = {"scene": {"mjcf": os.path.join(ROOT, "bench", "sensors40.xml"), "realtime_factor": 1.0},
               "transports": {"socket": {"plugin": "socket", "options": {"host": "127.0.0.1", "port": 0}}},
               "robots": [{"name": "arm", "type": "robot", "body": "arm",
                           "components": [{"name": "sensors", "type": "sensors"}]}],
               "services": {"default": ["socket"]},
               "log_level": "warning"}
        path = os.path.join(self.out, "sensors40-bench.json")
        with open(path, "w") as f:
            json.dump(cfg, f, indent=1)
        return path

    @staticmethod
    def sensor_values(port):
        """The number of values `arm.sensors get_local_data` answers (timestamp aside)."""
        data = socket_call(port, "arm.sensors get_local_data")
        return sum(len(v) if isinstance(v, list) else 1 for k, v in data.items() if k != "timestamp")

    def section_byor(self):
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not os.access(sim, os.X_OK) or not self.plugin_built("socket"):
            return {"status": "skipped", "reason": "simgate_bench_sim or the socket transport is not built"}
        out = {"status": "ok"}

        # a. the humanoid: every round pairs N gateway steps with N bare steps (stepping_bench.cc)
        duration = 1.0 if self.smoke else 12.0
        h = run_json([sim, "--mode", "humanoid", "--duration", str(duration)], self.timeout, self.env)
        out["humanoid"] = h
        full, stock = h["variants"]["with_sensors"], h["variants"]["stock"]
        self.target("humanoid: gateway steps/s with armature, armature_pose, actuators, pose, odometry, sensors / bare mj_step",
                    full["ratio"], ">=", 0.95, "x")
        self.target("humanoid as shipped (no <sensor>): with armature, armature_pose, actuators, pose, odometry / bare mj_step",
                    stock["ratio"], ">=", 0.95, "x")

        # b. a 40-value sensors component against `time now`, same gateway, same connection kind
        p = Process("byor-sensors40", [sim, "--mode", "gateway", "--config", self.sensors40_config(),
                                       "--realtime-factor", "1", "--duration", "3600", "--until-stdin-closes"],
                    self.logs, self.env, stdin=subprocess.PIPE)
        try:
            port = port_of(p.read_json("endpoints", 60)["endpoints"]["socket"])
            values = self.sensor_values(port)
            if values != 40:
                raise BenchError(f"arm.sensors answers {values} values, not 40 (bench/sensors40.xml)")
            # many short pairs, each two runs side by side: on a shared host a quiet or busy
            # moment then hits both sides of some pairs, and the median ratio is not its
            runs = []
            for rep in range(1 if self.smoke else 15):
                now, sensors = in_rotation(
                    rep, lambda: self.latency(port, ["--proto", "socket", "--request", "time now"]),
                    lambda: self.latency(port, ["--proto", "socket", "--request", "arm.sensors get_local_data"]))
                runs.append({"time_now": now, "sensors": sensors, "ratio_p50": ratio(sensors["p50_us"], now["p50_us"]),
                             "ratio_p99": ratio(sensors["p99_us"], now["p99_us"])})
            p.proc.stdin.close()
            p.read_json("steps_per_s", 120)
        finally:
            p.check_stopped()
        out["sensors"] = {"values": values, "runs": runs,
                          "time_now_p50_us": spread([r["time_now"]["p50_us"] for r in runs]),
                          "sensors_p50_us": spread([r["sensors"]["p50_us"] for r in runs]),
                          "time_now_p99_us": spread([r["time_now"]["p99_us"] for r in runs]),
                          "sensors_p99_us": spread([r["sensors"]["p99_us"] for r in runs]),
                          "ratio_p50": spread([r["ratio_p50"] for r in runs]),
                          "ratio_p99": spread([r["ratio_p99"] for r in runs])}
        self.target("40-value sensors get_local_data sync round trip p50 / time now p50 (socket)",
                    out["sensors"]["ratio_p50"], "<=", 1.3, "x")

        # c. the laser: the component's 360-ray update against the same bare mj_ray loop
        laser = run_json([sim, "--mode", "laser", "--duration", "0.5" if self.smoke else "5"], self.timeout, self.env)
        out["laser"] = laser
        self.target("360-ray laser_scanner update speed / bare mj_ray loop", laser["update_speed_ratio"], ">=", 0.9, "x")
        out["summary"] = {"humanoid_ratio": full["ratio"], "humanoid_stock_ratio": stock["ratio"],
                          "humanoid_gateway_steps_per_s": full["gateway_steps_per_s"],
                          "humanoid_bare_steps_per_s": full["bare_steps_per_s"],
                          "sensors_ratio_p50": out["sensors"]["ratio_p50"],
                          "sensors_p50_us": out["sensors"]["sensors_p50_us"],
                          "time_now_p50_us": out["sensors"]["time_now_p50_us"],
                          "laser_update_speed_ratio": laser["update_speed_ratio"],
                          "laser_update_us_per_scan": laser["update_us_per_scan"],
                          "laser_bare_us_per_scan": laser["bare_us_per_scan"]}
        return out

    def section_world(self):
        """Issue #19: client-driven stepping (`simulation step [1]` back to back on the socket
        transport of a gateway started paused) against its physical limit, one `time now`
        round trip plus one bare mj_step; and save_state / restore_state against
        mj_copyData of the same model."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not os.access(sim, os.X_OK) or not self.plugin_built("socket"):
            return {"status": "skipped", "reason": "simgate_bench_sim or the socket transport is not built"}
        demo, mjcf = self.demo_config()
        with open(demo) as f:
            cfg = json.load(f)
        cfg["scene"]["start_paused"] = True
        config = os.path.join(self.out, "demo-paused-bench.json")
        with open(config, "w") as f:
            json.dump(cfg, f, indent=1)
        duration = 0.5 if self.smoke else 2.0
        p = Process("world-paused", [sim, "--mode", "gateway", "--config", config, "--realtime-factor", "1",
                                     "--duration", "3600", "--until-stdin-closes"],
                    self.logs, self.env, stdin=subprocess.PIPE)
        runs = []
        try:
            port = port_of(p.read_json("endpoints", 60)["endpoints"]["socket"])
            for rep in range(self.repeats):
                # the three side by side in rotating order: a quiet or busy moment of the host
                # hits each of them in some repeat
                now, step, bare = in_rotation(
                    rep, lambda: self.latency(port, ["--proto", "socket", "--request", "time now"]),
                    lambda: self.throughput(port, ["--proto", "socket", "--request", "simulation step [1]"], 1, 1),
                    lambda: run_json([sim, "--mode", "bare", "--mjcf", mjcf, "--duration", str(duration)],
                                     self.timeout, self.env))
                step_us = 1e6 / bare["steps_per_s"]
                limit = 1e6 / (now["p50_us"] + step_us)
                runs.append({"time_now": now, "step": step, "bare": bare, "bare_step_us": step_us,
                             "limit_steps_per_s": limit, "ratio": ratio(step["rps"], limit)})
            step_latency = self.latency(port, ["--proto", "socket", "--request", "simulation step [1]"])
            p.proc.stdin.close()
            p.read_json("steps_per_s", 120)
        finally:
            p.check_stopped()
        snapshot = run_json([sim, "--mode", "snapshot", "--mjcf", mjcf, "--duration", str(duration)],
                            self.timeout, self.env)
        s = {"step_calls_per_s": spread([r["step"]["rps"] for r in runs]),
             "time_now_p50_us": spread([r["time_now"]["p50_us"] for r in runs]),
             "bare_step_us": spread([r["bare_step_us"] for r in runs]),
             "limit_steps_per_s": spread([r["limit_steps_per_s"] for r in runs]),
             "ratio": spread([r["ratio"] for r in runs]),
             "step_p50_us": step_latency["p50_us"], "step_p99_us": step_latency["p99_us"],
             "save_state_us": snapshot["save_state_us"], "restore_state_us": snapshot["restore_state_us"],
             "mj_copyData_us": snapshot["mj_copyData_us"]}
        self.target("simulation step [1] calls/s / (1 / (time now p50 + bare mj_step))", s["ratio"], ">=", 0.8, "x")
        return {"status": "ok", "summary": s, "runs": runs, "step_latency": step_latency, "snapshot": snapshot}

    def section_progress(self):
        """Issue #20: 100 concurrent JSON-RPC calls getting progress reports at 1 kHz each
        (progress_interval_ms 1, 0.25 ms steps, real time) vs the same calls without progress:
        the real-time factor of each kind of round, alternating in one gateway."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not os.access(sim, os.X_OK) or not self.plugin_built("jsonrpc"):
            return {"status": "skipped", "reason": "simgate_bench_sim or the JSON-RPC transport is not built"}
        _, mjcf = self.demo_config()
        duration, round_s = (0.6, 0.25) if self.smoke else (12.0, 1.0)
        runs = [run_json([sim, "--mode", "progress", "--mjcf", mjcf, "--duration", str(duration), "--round",
                          str(round_s), "--calls", "100"], self.timeout, self.env) for _ in range(self.repeats)]
        s = {"realtime_factor_plain": spread([r["realtime_factor"]["plain"] for r in runs]),
             "realtime_factor_progress": spread([r["realtime_factor"]["progress"] for r in runs]),
             "ratio": spread([r["ratio"] for r in runs]),
             "progress_hz_per_call": spread([r["progress_hz_per_call"] for r in runs]),
             "calls": runs[0]["calls"], "timestep": runs[0]["timestep"], "round_s": round_s}
        self.target("real-time factor with progress at 1 kHz to 100 calls", s["realtime_factor_progress"], ">=",
                    0.99, "x")
        return {"status": "ok", "summary": s, "runs": runs}

    def section_streams(self):
        """Issue #21: 50 pose sensors streaming at 100 Hz on the socket, JSON-RPC and DDS
        transports at once, every stream read (the real-time factor and the CPU against the
        same gateway without streams; the step-end to socket-read latency beside the sync round
        trip of the same run), and a pose stream through the DDS transport against a raw Cyclone
        writer of the same type."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not os.access(sim, os.X_OK) or not self.plugin_built("socket") or not self.plugin_built("jsonrpc"):
            return {"status": "skipped", "reason": "simgate_bench_sim or a TCP transport is not built"}
        _, mjcf = self.demo_config()
        duration = 0.6 if self.smoke else 5.0
        argv = [sim, "--mode", "streams", "--mjcf", mjcf, "--duration", str(duration), "--calls", "50"]
        if self.plugin_built("dds"):
            argv.append("--dds")
        runs = [run_json(argv, self.timeout, self.env) for _ in range(self.repeats)]
        s = {"realtime_factor_baseline": spread([r["realtime_factor"]["baseline"] for r in runs]),
             "realtime_factor_streams": spread([r["realtime_factor"]["streams"] for r in runs]),
             "cpu_ms_per_1000_produced": spread([r["cpu_ms_per_1000_samples_produced"] for r in runs]),
             "cpu_ms_per_1000_delivered": spread([r["cpu_ms_per_1000_samples_delivered"] for r in runs]),
             "produced_per_s": spread([r["samples"]["produced_per_s"] for r in runs]),
             "latency_p50_us": spread([r["socket_latency_step_to_read"]["p50_us"] for r in runs]),
             "latency_p99_us": spread([r["socket_latency_step_to_read"]["p99_us"] for r in runs]),
             "round_trip_p50_us": spread([r["socket_sync_round_trip"]["p50_us"] for r in runs]),
             "round_trip_p99_us": spread([r["socket_sync_round_trip"]["p99_us"] for r in runs]),
             "one_latency_p50_us": spread([r["one_stream"]["socket_latency_step_to_read"]["p50_us"] for r in runs]),
             "one_latency_p99_us": spread([r["one_stream"]["socket_latency_step_to_read"]["p99_us"] for r in runs]),
             "one_round_trip_p50_us": spread([r["one_stream"]["socket_sync_round_trip"]["p50_us"] for r in runs]),
             "components": runs[0]["components"], "transports": runs[0]["transports"]}
        self.target("real-time factor, 50 components streaming at 100 Hz on every transport",
                    s["realtime_factor_streams"], ">=", 0.99, "x")
        out = {"status": "ok", "summary": s, "runs": runs}
        dds = os.path.join(self.bin, "simgate_bench_dds_streams")
        if os.access(dds, os.X_OK) and self.plugin_built("dds"):
            dds_runs = [run_json([dds, "--duration", "0.5" if self.smoke else "3"], self.timeout, self.env)
                        for _ in range(self.repeats)]
            s["dds_ratio"] = spread([r["ratio"] for r in dds_runs])
            s["dds_simgate_per_s"] = spread([r["simgate_samples_per_s"] for r in dds_runs])
            s["dds_raw_per_s"] = spread([r["raw_samples_per_s"] for r in dds_runs])
            s["dds_thread_per_s"] = spread([r["simgate_thread_samples_per_s"] for r in dds_runs])
            self.target("DDS pose stream samples/s over a raw Cyclone writer's", s["dds_ratio"], ">=", 0.8, "x")
            out["dds_runs"] = dds_runs
        return out

    def section_cameras(self):
        """Issue #22: frames/s of the camera path against a bare mjr_render + mjr_readPixels
        loop on the same kind of EGL context (simgate_bench_sim --mode camera_fps), and the
        real-time factor with a camera streaming at 10 Hz to a JSON-RPC subscriber against
        none (--mode camera_rtf)."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not os.access(sim, os.X_OK) or not self.plugin_built("jsonrpc") or not self.plugin_built("socket"):
            return {"status": "skipped", "reason": "simgate_bench_sim or the rover's transports are not built"}
        mjcf = os.path.join(ROOT, "config", "scenes", "rover_room.xml")
        config = os.path.join(ROOT, "config", "rover.json")
        # per side, size and kind: at most `frames` frames or `seconds` s, in batches
        frames, seconds, batch = (6, 0.5, 3) if self.smoke else (200, 5.0, 10)
        rtf_seconds = 2.0 if self.smoke else 10.0
        fps_runs, rtf_runs = [], []
        for _ in range(self.repeats):
            r = run_json([sim, "--mode", "camera_fps", "--mjcf", mjcf, "--site", "laser", "--frames", str(frames),
                          "--duration", str(seconds), "--batch", str(batch)], self.timeout, self.env)
            if "skipped" in r:
                return {"status": "skipped", "reason": r["skipped"]}
            fps_runs.append(r)
            r = run_json([sim, "--mode", "camera_rtf", "--config", config, "--camera", "rover.camera",
                          "--duration", str(rtf_seconds)], self.timeout, self.env)
            if "skipped" in r:
                return {"status": "skipped", "reason": r["skipped"]}
            rtf_runs.append(r)

        def over_runs(values, within=None):
            # one run: the spread of its rounds; several: of the runs' medians
            if len(values) == 1 and within is not None:
                return within
            return spread(values)

        rows = []
        for i, row in enumerate(fps_runs[0]["rows"]):
            mine = [run["rows"][i] for run in fps_runs]
            rows.append({"size": f"{row['width']}x{row['height']}", "kind": row["kind"],
                         "bare_fps": spread([x["bare_fps"] for x in mine]),
                         "raw_fps": spread([x["raw_fps"] for x in mine]),
                         "png_fps": spread([x["png_fps"] for x in mine]),
                         "raw_ratio": over_runs([x["raw_ratio"]["median"] for x in mine], row["raw_ratio"]),
                         "png_ratio": over_runs([x["png_ratio"]["median"] for x in mine], row["png_ratio"]),
                         "scene_copy_p50_us": spread([x["scene_copy"]["p50_us"] for x in mine]),
                         "png_kib": row["png_base64_bytes"] / 1024,
                         "frames_per_side": row["frames_per_side"]})
        s = {"rows": rows, "gl_renderer": fps_runs[0]["gl_renderer"], "gl_platform": fps_runs[0]["gl_platform"],
             "batch": batch,
             "rtf_without": spread([r["without"]["realtime_factor"] for r in rtf_runs]),
             "rtf_with": spread([r["with"]["realtime_factor"] for r in rtf_runs]),
             "rtf_ratio": spread([r["ratio"] for r in rtf_runs]),
             "samples_per_s": spread([r["with"]["samples_per_s"] for r in rtf_runs]),
             "cpu_per_s_without": spread([r["without"]["gateway_cpu_per_s"] for r in rtf_runs]),
             "cpu_per_s_with": spread([r["with"]["gateway_cpu_per_s"] for r in rtf_runs]),
             "sample_kib": spread([r["with"]["mean_sample_bytes"] / 1024 for r in rtf_runs]),
             "rtf_seconds": rtf_seconds, "frequency_hz": rtf_runs[0]["frequency_hz"],
             "image": rtf_runs[0]["image"]}
        for row in rows:
            if row["kind"] != "rgb":
                continue
            self.target(f"camera frames/s {row['size']} RGB, Renderer (raw pixels) / bare mjr_render loop",
                        row["raw_ratio"], ">=", 0.9, "x")
            self.target(f"camera frames/s {row['size']} RGB, Renderer + PNG record / bare mjr_render loop",
                        row["png_ratio"], ">=", 0.9, "x")
        self.target(f"real-time factor, camera streaming {s['image']['width']}x{s['image']['height']} at "
                    f"{s['frequency_hz']:g} Hz to a JSON-RPC subscriber", s["rtf_with"], ">=", 0.99)
        return {"status": "ok", "summary": s, "fps_runs": fps_runs, "rtf_runs": rtf_runs}

    def section_web(self):
        """Issue #23: the real-time factor while 20 WebSocket clients, as many browser pages,
        receive the simulation's body poses at 60 Hz, against no client (simgate_bench_sim
        --mode web_poses on config/demo.json)."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not os.access(sim, os.X_OK) or not self.plugin_built("websocket") or not self.plugin_built("socket"):
            return {"status": "skipped", "reason": "simgate_bench_sim or the demo's transports are not built"}
        config = os.path.join(ROOT, "config", "demo.json")
        seconds = 2.0 if self.smoke else 10.0
        runs = [run_json([sim, "--mode", "web_poses", "--config", config, "--calls", "20", "--frequency", "60",
                          "--duration", str(seconds)], self.timeout, self.env) for _ in range(self.repeats)]
        s = {"rtf_without": spread([r["without"]["realtime_factor"] for r in runs]),
             "rtf_with": spread([r["with"]["realtime_factor"] for r in runs]),
             "rtf_ratio": spread([r["ratio"] for r in runs]),
             "samples_per_s_per_client": spread([r["samples_per_s_per_client"]["mean"] for r in runs]),
             "fewest_per_s": spread([r["samples_per_s_per_client"]["min"] for r in runs]),
             "sample_bytes": spread([r["mean_sample_bytes"] for r in runs]),
             "cpu_per_s_without": spread([r["without"]["gateway_cpu_per_s"] for r in runs]),
             "cpu_per_s_with": spread([r["with"]["gateway_cpu_per_s"] for r in runs]),
             "clients": runs[0]["clients"], "frequency_hz": runs[0]["frequency_hz"], "bodies": runs[0]["bodies"],
             "seconds": seconds}
        self.target(f"real-time factor, body poses at {s['frequency_hz']:g} Hz to {s['clients']} WebSocket clients",
                    s["rtf_with"], ">=", 0.99)
        return {"status": "ok", "summary": s, "runs": runs}

    def section_foxglove(self):
        """Issue #38: the real-time factor while 4 Foxglove clients each receive /tf at 60 Hz
        (50 moving bodies) and a 640x480 camera at 10 Hz, against no client (simgate_bench_sim
        --mode foxglove_rtf on bench/pendulums50.xml)."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not os.access(sim, os.X_OK) or not self.plugin_built("foxglove"):
            return {"status": "skipped", "reason": "simgate_bench_sim or the foxglove transport is not built"}
        mjcf = os.path.join(ROOT, "bench", "pendulums50.xml")
        seconds = 2.0 if self.smoke else 10.0
        runs = []
        for _ in range(self.repeats):
            r = run_json([sim, "--mode", "foxglove_rtf", "--mjcf", mjcf, "--calls", "4", "--frequency", "60",
                          "--duration", str(seconds)], self.timeout, self.env)
            runs.append(r)
        s = {"rtf_without": spread([r["without"]["realtime_factor"] for r in runs]),
             "rtf_with": spread([r["with"]["realtime_factor"] for r in runs]),
             "rtf_ratio": spread([r["ratio"] for r in runs]),
             "transforms_per_s_fewest": spread([r["transforms_per_s_per_client"]["min"] for r in runs]),
             "images_per_s_fewest": spread([r["images_per_s_per_client"]["min"] for r in runs]),
             "mib_per_s": spread([r["mib_per_s"] for r in runs]),
             "image_kib": runs[0]["image_message_bytes"] / 1024,
             "cpu_per_s_without": spread([r["without"]["gateway_cpu_per_s"] for r in runs]),
             "cpu_per_s_with": spread([r["with"]["gateway_cpu_per_s"] for r in runs]),
             "clients": runs[0]["clients"], "frequency_hz": runs[0]["frequency_hz"], "bodies": runs[0]["bodies"],
             "seconds": seconds}
        self.target(f"real-time factor, /tf at {s['frequency_hz']:g} Hz ({s['bodies']} bodies) and a 640x480 camera "
                    f"at 10 Hz to {s['clients']} Foxglove clients", s["rtf_with"], ">=", 0.99)
        return {"status": "ok", "summary": s, "runs": runs}

    def section_ros2(self):
        """Issue #41: the ros2 transport's StepSimulation round trip (a raw ROS 2 client as
        rmw_cyclonedds makes one: simgate_bench_dds --mode ros2-step) against simgate's own DDS
        request for the same step (`simulation step {"n": 1}` by DdsClient: --mode step), on one
        gateway of the demo scene started paused, interleaved per repeat; then /tf of 50 moving
        bodies (bench/pendulums50.xml) at 100 Hz to a ROS 2 reader at real time: the real-time
        factor over the window (`time statistics`) and /tf's rate."""
        dds = os.path.join(self.bin, "simgate_bench_dds")
        if not os.access(dds, os.X_OK) or not all(self.plugin_built(t) for t in ("ros2", "dds", "socket")):
            return {"status": "skipped", "reason": "simgate_bench_dds or the ros2, dds or socket transport is not built"}
        domain = 19  # away from the tests' and demos' domains
        tag = f"simgate-bench-{os.getpid()}"
        with open(os.path.join(ROOT, "config", "demo.json")) as f:
            cfg = json.load(f)
        cfg["scene"]["mjcf"] = os.path.join(ROOT, "config", cfg["scene"]["mjcf"])
        cfg["scene"]["start_paused"] = True
        cfg["transports"] = {"socket": {"plugin": "socket", "options": {"host": "127.0.0.1", "port": 0}},
                             "dds": {"plugin": "dds", "options": {"domain": domain, "partition": tag}},
                             "ros2": {"plugin": "ros2", "options": {"domain": domain, "clock_hz": 0, "tf": False}}}
        cfg["services"] = {"default": ["socket"], "simulation": ["socket", "dds", "ros2"]}
        cfg.pop("streams", None)
        cfg["log_level"] = "warning"
        config = os.path.join(self.out, "ros2-step-bench.json")
        with open(config, "w") as f:
            json.dump(cfg, f, indent=1)
        common = ["--domain", str(domain), "--count", str(self.count), "--timeout", "120"]
        p = Process("ros2-step", [self.exe("simgate_bench_sim"), "--mode", "gateway", "--config", config,
                                  "--realtime-factor", "1", "--duration", "3600", "--until-stdin-closes"],
                    self.logs, self.env, stdin=subprocess.PIPE)
        runs = []
        try:
            p.read_json("endpoints", 60)
            for rep in range(self.repeats):
                own, ros2 = in_order(
                    rep,
                    lambda: run_json([dds, "--mode", "step", "--partition", tag] + common, self.timeout, self.env),
                    lambda: run_json([dds, "--mode", "ros2-step"] + common, self.timeout, self.env))
                if own["errors"] or ros2["errors"]:
                    raise BenchError(f"steps failed: DDS {own['errors']}, ROS 2 {ros2['errors']}")
                runs.append({"dds": own, "ros2": ros2, "ratio_p50": ratio(ros2["p50_us"], own["p50_us"])})
            p.proc.stdin.close()
            p.read_json("steps_per_s", 120)
        finally:
            p.check_stopped()
        s = {"ros2_p50_us": spread([r["ros2"]["p50_us"] for r in runs]),
             "ros2_p99_us": spread([r["ros2"]["p99_us"] for r in runs]),
             "dds_p50_us": spread([r["dds"]["p50_us"] for r in runs]),
             "dds_p99_us": spread([r["dds"]["p99_us"] for r in runs]),
             "ratio_p50": spread([r["ratio_p50"] for r in runs])}
        self.target("ROS 2 StepSimulation round trip p50 / simgate's DDS `simulation step` p50", s["ratio_p50"],
                    "<=", 1.3, "x")

        # /tf of 50 bodies at 100 Hz, at real time
        seconds = 2.0 if self.smoke else 10.0
        tf_cfg = {"scene": {"mjcf": os.path.join(ROOT, "bench", "pendulums50.xml"), "realtime_factor": 1.0},
                  "transports": {"socket": {"plugin": "socket", "options": {"host": "127.0.0.1", "port": 0}},
                                 "ros2": {"plugin": "ros2", "options": {"domain": domain}}},
                  "services": {"simulation": ["socket", "ros2"], "time": ["socket"]},
                  "streams": {"simulation": {"transports": ["ros2"], "frequency": 100}},
                  "log_level": "warning"}
        tf_config = os.path.join(self.out, "ros2-tf-bench.json")
        with open(tf_config, "w") as f:
            json.dump(tf_cfg, f, indent=1)
        tf_runs = []
        for rep in range(self.repeats):
            g = Process(f"ros2-tf-{rep}", [self.exe("simgate_bench_sim"), "--mode", "gateway", "--config", tf_config,
                                           "--realtime-factor", "1", "--duration", "3600", "--until-stdin-closes"],
                        self.logs, self.env, stdin=subprocess.PIPE)
            try:
                port = port_of(g.read_json("endpoints", 60)["endpoints"]["socket"])
                reader = Process(f"ros2-tf-reader-{rep}", [dds, "--mode", "ros2-tf", "--domain", str(domain),
                                                           "--duration", str(seconds), "--timeout", "60"],
                                 self.logs, self.env)
                time.sleep(1.0)  # the reader matched and reading (its own wait is bounded)
                a = socket_call(port, "time statistics")
                tf = reader.read_json("messages_per_s", seconds + 90)
                b = socket_call(port, "time statistics")
                reader.check_stopped()
                rtf = (b["sim_time"] - a["sim_time"]) / (b["wall_time"] - a["wall_time"])
                tf_runs.append({"rtf": rtf, "tf": tf})
                g.proc.stdin.close()
                g.read_json("steps_per_s", 120)
            finally:
                g.check_stopped()
        s["tf_rtf"] = spread([r["rtf"] for r in tf_runs])
        s["tf_messages_per_s"] = spread([r["tf"]["messages_per_s"] for r in tf_runs])
        s["tf_transforms_per_message"] = tf_runs[0]["tf"]["transforms_per_message"]
        s["tf_seconds"] = seconds
        self.target(f"real-time factor, /tf of {s['tf_transforms_per_message']:g} bodies at 100 Hz to a ROS 2 reader",
                    s["tf_rtf"], ">=", 0.99)
        return {"status": "ok", "summary": s, "runs": runs, "tf_runs": tf_runs}

    def recording_rounds(self, config, rep, rounds, round_s, count, directory):
        """One gateway of the demo config (simgate_bench_sim --mode gateway --record-dir),
        recording in every other round (`simulation start_recording` before the round,
        `stop_recording` after it: it answers once the file is closed). As fast as possible:
        steps/s over `round_s` with no client (`time statistics` before and after); then at
        real time (`time set_time_scale [1]`), `count` sync `time now` round trips on the
        socket transport, one outstanding (loadgen). Each pair of rounds runs in alternating
        order. Returns the speed pairs (each with its recording's status and file) and the
        round-trip pairs.

        The round trips are timed at real time, as the demo runs: as fast as possible, the
        `time now` p50 of a gateway jumps between ~20-40 µs and ~4 ms (a scheduler tick here)
        from one run to the next, recording or not (docs/performance.md, issue #39)."""
        p = Process(f"recording-{rep}", [self.exe("simgate_bench_sim"), "--mode", "gateway", "--config", config,
                                         "--realtime-factor", "0", "--duration", "3600", "--until-stdin-closes",
                                         "--record-dir", directory], self.logs, self.env, stdin=subprocess.PIPE)
        speed, latency = [], []
        try:
            port = port_of(p.read_json("endpoints", 60)["endpoints"]["socket"])

            def steps_per_s():
                a = socket_call(port, "time statistics")
                time.sleep(round_s)
                b = socket_call(port, "time statistics")
                return (b["steps"] - a["steps"]) / (b["wall_time"] - a["wall_time"])

            def round_trips():
                return self.latency(port, ["--proto", "socket", "--request", "time now"], count)

            def recorded(measure, name):
                socket_call(port, f"simulation start_recording {json.dumps([name])}")
                value = measure()
                status = socket_call(port, "simulation stop_recording")
                if status.get("error") is not None:
                    raise BenchError(f"the recording {name} stopped early: {status['error']}")
                status["file"] = os.path.join(directory, name + ".mcap")
                return value, status

            for k in range(rounds):
                plain, (rec, status) = in_order(rep + k, steps_per_s, lambda: recorded(steps_per_s, f"speed-{k}"))
                speed.append({"plain_steps_per_s": plain, "recorded_steps_per_s": rec, "status": status,
                              "ratio": ratio(rec, plain)})
            socket_call(port, "time set_time_scale [1]")
            for k in range(rounds):
                plain, (rec, status) = in_order(rep + k, round_trips, lambda: recorded(round_trips, f"latency-{k}"))
                latency.append({"plain": plain, "recorded": rec, "status": status,
                                "ratio_p50": ratio(rec["p50_us"], plain["p50_us"]),
                                "ratio_p99": ratio(rec["p99_us"], plain["p99_us"])})
            p.proc.stdin.close()
            p.read_json("steps_per_s", 120)
        finally:
            p.check_stopped()
        return speed, latency

    def replay(self, path):
        """`simgate replay --verify --json` of a recording: its report; an error unless every
        step's state was the recording's."""
        argv = [self.exe("simgate"), "replay", path, "--verify", "--json"]
        try:
            done = subprocess.run(argv, capture_output=True, text=True, timeout=self.timeout, env=self.env, cwd=ROOT)
        except subprocess.TimeoutExpired:
            raise BenchError(f"simgate replay {path}: still running after {self.timeout} s")
        lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
        report = json.loads(lines[-1]) if lines else None
        if done.returncode != 0 or report is None or report.get("mismatch") is not None:
            detail = report.get("mismatch") if report else done.stderr.strip()[-400:]
            raise BenchError(f"simgate replay --verify {path}: exit code {done.returncode}: {detail}")
        return report

    def section_recording(self):
        """Issue #39: the flight recorder's cost on config/demo.json (every output stream the
        config declares recorded with the inputs and each step's state fingerprints), in
        rounds of one gateway, recording and not in turn: steps/s as fast as possible, and the
        `time now` round trip (socket) at real time; then each as-fast-as-possible round's
        recording replayed (`simgate replay --verify --json`: steps / wall_seconds) against a
        bare mj_step loop on the same MJCF (simgate_bench_sim --mode bare), in turn too."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not (os.access(sim, os.X_OK) and os.access(os.path.join(self.bin, "simgate"), os.X_OK)) or \
                not all(self.plugin_built(t) for t in ("socket", "websocket", "foxglove")):
            return {"status": "skipped", "reason": "simgate, simgate_bench_sim or the demo's transports are not built"}
        config, mjcf = self.demo_config()
        with open(config) as f:
            timestep = json.load(f)["scene"]["timestep"]
        rounds, round_s, count = (1, 0.3, 200) if self.smoke else (5, 1.0, 5000)
        speed, latency, replays = [], [], []
        for rep in range(self.repeats):
            directory = tempfile.mkdtemp(prefix="recordings-", dir=self.out)
            try:
                sp, la = self.recording_rounds(config, rep, rounds, round_s, count, directory)
                for k, row in enumerate(sp):
                    replay, bare = in_order(rep + k, lambda: self.replay(row["status"]["file"]),
                                            lambda: run_json([sim, "--mode", "bare", "--mjcf", mjcf, "--duration",
                                                              str(round_s)], self.timeout, self.env))
                    steps_per_s = replay["steps"] / replay["wall_seconds"]
                    replays.append({"replay": replay, "bare": bare, "replay_steps_per_s": steps_per_s,
                                    "ratio": ratio(steps_per_s, bare["steps_per_s"])})
            finally:
                shutil.rmtree(directory, ignore_errors=True)  # a few MiB a round
            speed += sp
            latency += la
        for row in speed:  # the file's size over what it covers (simulated time)
            st = row["status"]
            row["kib_per_sim_s"] = st["bytes"] / 1024 / (st["steps"] * timestep)
            row["mib_per_s"] = row["kib_per_sim_s"] / 1024 * row["recorded_steps_per_s"] * timestep
        s = {"plain_steps_per_s": spread([r["plain_steps_per_s"] for r in speed]),
             "recorded_steps_per_s": spread([r["recorded_steps_per_s"] for r in speed]),
             "speed_ratio": spread([r["ratio"] for r in speed]),
             "plain_p50_us": spread([r["plain"]["p50_us"] for r in latency]),
             "recorded_p50_us": spread([r["recorded"]["p50_us"] for r in latency]),
             "latency_ratio_p50": spread([r["ratio_p50"] for r in latency]),
             "plain_p99_us": spread([r["plain"]["p99_us"] for r in latency]),
             "recorded_p99_us": spread([r["recorded"]["p99_us"] for r in latency]),
             "latency_ratio_p99": spread([r["ratio_p99"] for r in latency]),
             "file_mib": spread([r["status"]["bytes"] / 2 ** 20 for r in speed]),
             "kib_per_sim_s": spread([r["kib_per_sim_s"] for r in speed]),
             "mib_per_s": spread([r["mib_per_s"] for r in speed]),
             "samples_per_round": spread([r["status"]["samples"] for r in speed]),
             "inputs_per_latency_round": spread([r["status"]["inputs"] for r in latency]),
             "replay_steps": spread([r["replay"]["steps"] for r in replays]),
             "replay_steps_per_s": spread([r["replay_steps_per_s"] for r in replays]),
             "bare_steps_per_s": spread([r["bare"]["steps_per_s"] for r in replays]),
             "replay_ratio": spread([r["ratio"] for r in replays]),
             "rounds": len(speed), "round_s": round_s, "round_trips": count}
        print(f"[bench] recording: steps/s recorded / not {s['speed_ratio']['median']:.3f}, time now p50 "
              f"{s['recorded_p50_us']['median']:.1f} / {s['plain_p50_us']['median']:.1f} us, replay / bare mj_step "
              f"{s['replay_ratio']['median']:.3f}", file=sys.stderr, flush=True)
        self.target("recording the demo: steps/s (as fast as possible) / not recording", s["speed_ratio"], ">=",
                    0.97, "x")
        self.target("recording the demo: time now round trip p50 / not recording", s["latency_ratio_p50"], "<=",
                    1.1, "x")
        self.target("simgate replay --verify of the demo's recording: steps/s / bare mj_step", s["replay_ratio"],
                    ">=", 0.9, "x")
        # beside the summary, whose figures are all positive: this one is 0 on a good run
        dropped = sum(r["status"]["samples_dropped"] for r in speed + latency)
        return {"status": "ok", "summary": s, "samples_dropped": dropped, "speed": speed, "latency": latency,
                "replays": replays}

    def gym_pythonpath(self):
        """Where ensure_python_test_clients installed tests/python's pins (the directory named
        after them, as scripts/lib.sh and cmake/SimgateHelpers.cmake name it), or None."""
        with open(os.path.join(ROOT, "tests", "python", "pypi-requirements.txt")) as f:
            pins = [line.strip() for line in f if line.strip() and not line.startswith("#")]
        cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        path = os.path.join(cache, "simgate", "python-" + "_".join(pins).replace("==", "-"))
        return path if os.path.isdir(path) else None

    def section_gym(self):
        """Issue #40: env.step() of simgate.gym against the raw JSON-RPC round trip of the same
        batch (a bare socket loop on a second connection to the same simgate, alternating
        rounds: bench/gym_bench.py) and against bare mj_step on the same MJCF."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        pythonpath = self.gym_pythonpath()
        if pythonpath is None:
            return {"status": "skipped", "reason": "gymnasium and numpy are not installed "
                    "((source scripts/lib.sh; ensure_python_test_clients))"}
        if not (os.access(sim, os.X_OK) and os.access(os.path.join(self.bin, "simgate"), os.X_OK)) or \
                not all(self.plugin_built(t) for t in ("socket", "jsonrpc")):
            return {"status": "skipped", "reason": "simgate, simgate_bench_sim or the jsonrpc transport is not built"}
        models = {"cartpole": os.path.join(ROOT, "tests", "python", "cartpole.xml")}
        humanoid = "/usr/share/mujoco/model/humanoid/humanoid.xml"
        if os.path.exists(humanoid):
            models["humanoid"] = humanoid
        steps, rounds, bare_s = (200, 2, 0.2) if self.smoke else (3000, 4, 1.0)
        env = dict(self.env, SIMGATE_BIN=os.path.join(self.bin, "simgate"), PYTHONNOUSERSITE="1",
                   PYTHONPATH=pythonpath + os.pathsep + os.path.join(ROOT, "python"))
        out = {}
        for name, mjcf in models.items():
            runs = []
            for rep in range(self.repeats):
                g, bare = in_order(rep, lambda: run_json(
                    ["/usr/bin/python3", os.path.join(ROOT, "bench", "gym_bench.py"), "--model", mjcf,
                     "--steps", str(steps), "--rounds", str(rounds)], self.timeout, env),
                    lambda: run_json([sim, "--mode", "bare", "--mjcf", mjcf, "--duration", str(bare_s)],
                                     self.timeout, self.env))
                runs.append((g, bare))
            rows = [r for g, _ in runs for r in g["rounds"]]
            bares = [b["steps_per_s"] for _, b in runs]
            out[name] = {"env_steps_per_s": spread([r["env_steps_per_s"] for r in rows]),
                         "raw_steps_per_s": spread([r["raw_steps_per_s"] for r in rows]),
                         "env_us": spread([r["env_us"] for r in rows]),
                         "raw_us": spread([r["raw_us"] for r in rows]),
                         "env_over_raw": spread([r["ratio"] for r in rows]),
                         "bare_steps_per_s": spread(bares),
                         "env_over_bare": spread([ratio(r["env_steps_per_s"], b) for (g, _), b in zip(runs, bares)
                                                  for r in g["rounds"]]),
                         "actuators": runs[0][0]["actuators"], "observation_size": runs[0][0]["observation_size"],
                         "requests_per_step": runs[0][0]["requests_per_step"], "rounds": len(rows), "steps": steps}
            print(f"[bench] gym {name}: env.step {out[name]['env_us']['median']:.1f} us, raw batch "
                  f"{out[name]['raw_us']['median']:.1f} us, env/raw {out[name]['env_over_raw']['median']:.3f}",
                  file=sys.stderr, flush=True)
            self.target(f"simgate.gym env.step() time / the raw JSON-RPC round trip of its batch ({name})",
                        out[name]["env_over_raw"], "<=", 1.3, "x")
        return {"status": "ok", "summary": out}

    def section_farm(self):
        """Issue #43: many worlds of one model stepped remotely by `simulation step_many` (one
        JSON-RPC connection, bench/farm_bench.py), against bare mj_step of as many worlds on as
        many threads (the pool's: one per core) and against one round trip per world and step.
        Then the pipelined calls again with a pool of one thread fewer than the cores, against
        bare mj_step on as many: the client and the transport's thread have a core to
        themselves there, as they would on a machine of their own."""
        sim = os.path.join(self.bin, "simgate_bench_sim")
        if not (os.access(sim, os.X_OK) and os.access(os.path.join(self.bin, "simgate"), os.X_OK)) or \
                not self.plugin_built("jsonrpc"):
            return {"status": "skipped", "reason": "simgate, simgate_bench_sim or the jsonrpc transport is not built"}
        models = {"cartpole": os.path.join(ROOT, "tests", "python", "cartpole.xml")}
        humanoid = "/usr/share/mujoco/model/humanoid/humanoid.xml"
        if os.path.exists(humanoid):
            models["humanoid"] = humanoid
        worlds, seconds, rounds = (8, 0.2, 1) if self.smoke else (64, 1.0, 2)
        threads = os.cpu_count() or 1
        out = {}
        for name, mjcf in models.items():
            runs = []
            for rep in range(self.repeats):
                farm, bare = in_order(rep, lambda: run_json(
                    ["/usr/bin/python3", os.path.join(ROOT, "bench", "farm_bench.py"), "--simgate",
                     os.path.join(self.bin, "simgate"), "--model", mjcf, "--worlds", str(worlds), "--rounds",
                     str(rounds), "--seconds", str(seconds)], self.timeout, self.env),
                    lambda: run_json([sim, "--mode", "bare", "--mjcf", mjcf, "--duration", str(seconds), "--copies",
                                      str(worlds), "--threads", str(threads)], self.timeout, self.env))
                runs.append((farm, bare))
            bares = [b["steps_per_s"] for _, b in runs]
            summary = {"worlds": worlds, "threads": threads, "bare_steps_per_s": spread(bares),
                       "round_trips_steps_per_s": spread([x for f, _ in runs for x in f["round_trips"]]),
                       "on_divergence": runs[0][0]["on_divergence"], "step_many": {},
                       "pipelined": {"steps_per_s": spread([x for f, _ in runs for x in f["pipelined"]]),
                                     "over_bare": spread([x / b for (f, _), b in zip(runs, bares)
                                                          for x in f["pipelined"]])}}
            for n in runs[0][0]["step_many"]:
                rates = [x for f, _ in runs for x in f["step_many"][n]]
                summary["step_many"][n] = {
                    "steps_per_s": spread(rates),
                    "over_bare": spread([x / b for (f, _), b in zip(runs, bares) for x in f["step_many"][n]]),
                    "over_round_trips": spread([x / rt for f, _ in runs for x, rt in zip(f["step_many"][n],
                                                                                        f["round_trips"])])}
            if threads > 1:
                fewer = threads - 1
                spare = []
                for rep in range(self.repeats):
                    farm, bare = in_order(rep, lambda: run_json(
                        ["/usr/bin/python3", os.path.join(ROOT, "bench", "farm_bench.py"), "--simgate",
                         os.path.join(self.bin, "simgate"), "--model", mjcf, "--worlds", str(worlds), "--rounds",
                         str(rounds), "--seconds", str(seconds), "--threads", str(fewer), "--pipelined-only"],
                        self.timeout, self.env),
                        lambda: run_json([sim, "--mode", "bare", "--mjcf", mjcf, "--duration", str(seconds),
                                          "--copies", str(worlds), "--threads", str(fewer)], self.timeout, self.env))
                    spare.append((farm, bare))
                spare_bares = [b["steps_per_s"] for _, b in spare]
                summary["pipelined_spare_core"] = {
                    "threads": fewer, "bare_steps_per_s": spread(spare_bares),
                    "steps_per_s": spread([x for f, _ in spare for x in f["pipelined"]]),
                    "over_bare": spread([x / b for (f, _), b in zip(spare, spare_bares) for x in f["pipelined"]])}
            out[name] = summary
            print(f"[bench] farm {name}: " + ", ".join(
                f"step_many n={n} {fmt(v['steps_per_s']['median'], 0)} steps/s = "
                f"{fmt(v['over_bare']['median'], 3)}x bare" for n, v in summary["step_many"].items()) +
                f", pipelined base64 n=10 {fmt(summary['pipelined']['steps_per_s']['median'], 0)} steps/s = "
                f"{fmt(summary['pipelined']['over_bare']['median'], 3)}x bare" +
                (f"; on {summary['pipelined_spare_core']['threads']} threads "
                 f"{fmt(summary['pipelined_spare_core']['steps_per_s']['median'], 0)} steps/s = "
                 f"{fmt(summary['pipelined_spare_core']['over_bare']['median'], 3)}x bare"
                 if "pipelined_spare_core" in summary else ""), file=sys.stderr, flush=True)
            if not self.smoke:
                self.target(f"{worlds} {name} worlds stepped by step_many (n=10 steps a call, two halves "
                            f"in flight, base64 arrays, one JSON-RPC connection): steps/s / bare mj_step "
                            f"on {threads} threads", summary["pipelined"]["over_bare"], ">=", 0.8, "x")
                if "pipelined_spare_core" in summary:
                    spare = summary["pipelined_spare_core"]
                    self.target(f"the same on a pool of {spare['threads']} threads, one core left to the client "
                                f"and the transport: steps/s / bare mj_step on {spare['threads']} threads",
                                spare["over_bare"], ">=", 0.8, "x")
        return {"status": "ok", "summary": out}

    # ---- driver

    def machine(self):
        cpu = "unknown"
        try:
            with open("/proc/cpuinfo") as f:
                for line in f:
                    if line.startswith("model name"):
                        cpu = line.split(":", 1)[1].strip()
                        break
        except OSError:
            pass
        try:
            commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                                    text=True, timeout=10).stdout.strip()
        except (OSError, subprocess.TimeoutExpired):
            commit = ""
        mem_kib = 0
        with open("/proc/meminfo") as f:
            mem_kib = int(f.readline().split()[1])
        cache = {}
        try:
            with open(os.path.join(self.build, "CMakeCache.txt")) as f:
                for line in f:
                    for key in ("CMAKE_BUILD_TYPE", "SIMGATE_SANITIZE"):
                        if line.startswith(key + ":"):
                            cache[key] = line.split("=", 1)[1].strip()
        except OSError:
            pass
        return {"cpu": cpu, "vcpus": os.cpu_count(), "memory_gib": round(mem_kib / 1024 / 1024, 1),
                "kernel": platform.release(), "python": platform.python_version(),
                "load_average_at_start": os.getloadavg(), "commit": commit,
                "build_type": cache.get("CMAKE_BUILD_TYPE", ""), "sanitize": cache.get("SIMGATE_SANITIZE", ""),
                "pinning": PINNING}

    def run(self):
        started = time.monotonic()
        self.results["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        self.results["mode"] = "smoke" if self.smoke else "full"
        self.results["repeats"] = self.repeats
        self.results["machine"] = self.machine()
        only = set(self.args.only.split(",")) if self.args.only else None
        for name in ("socket", "jsonrpc", "websocket", "dds", "peers", "sim", "memory", "byor", "world", "progress", "streams",
                     "cameras", "web", "foxglove", "recording", "gym", "ros2", "mcp", "farm"):
            if only and name not in only:
                continue
            t0 = time.monotonic()
            print(f"[bench] {name} ...", file=sys.stderr, flush=True)
            try:
                section = getattr(self, "section_" + name)()
            except Exception as e:  # one failed section must not hide the others
                section = {"status": "error", "reason": f"{type(e).__name__}: {e}"}
            section["seconds"] = round(time.monotonic() - t0, 1)
            self.results["sections"][name] = section
            print(f"[bench] {name}: {section['status']} ({section['seconds']} s)"
                  + (f" {section.get('reason')}" if section["status"] != "ok" else ""), file=sys.stderr, flush=True)
        self.results["seconds"] = round(time.monotonic() - started, 1)
        with open(os.path.join(self.out, "results.json"), "w") as f:
            json.dump(self.results, f, indent=1)
        with open(os.path.join(self.out, "results.md"), "w") as f:
            f.write(markdown(self.results))
        failed = [n for n, s in self.results["sections"].items() if s["status"] == "error"]
        return 1 if failed else 0


# ---------------------------------------------------------------------------------------
# the Markdown report


def fmt(v, digits=1):
    if v is None:
        return "–"
    if isinstance(v, dict):
        if v.get("n", 1) > 1:
            return f"{fmt(v['median'], digits)} ({fmt(v['min'], digits)}–{fmt(v['max'], digits)})"
        return fmt(v["median"], digits)
    if abs(v) >= 10000:
        return f"{v:,.0f}"
    return f"{v:.{digits}f}"


def markdown(r):
    m = r["machine"]
    lines = [f"# simgate benchmark results ({r['mode']})", "",
             f"- Date: {r['date']}; commit {m['commit'] or '?'}; build {m['build_type'] or '?'}"
             + (f", sanitizer {m['sanitize']}" if m.get("sanitize") else ""),
             f"- Machine: {m['cpu']}, {m['vcpus']} vCPUs, {m['memory_gib']} GiB, Linux {m['kernel']}; "
             f"load average at start {', '.join(f'{x:.1f}' for x in m['load_average_at_start'])}",
             f"- Pinning: {m['pinning']}",
             f"- Repeats: {r['repeats']}; figures are medians with (min–max) over the repeats; every ratio "
             "pairs two measurements of the same repeat; latencies in µs, throughput in replies/s.",
             f"- Whole run: {r['seconds']} s", ""]
    s = r["sections"]

    def status_line(name):
        sec = s.get(name)
        if sec is None:
            return f"_{name}: not run_"
        if sec["status"] != "ok":
            return f"_{name}: {sec['status']}: {sec.get('reason', '')}_"
        return None

    # targets first: what the issue asks
    lines += ["## Targets", "", "| target | this run | goal | met |", "|---|---|---|---|"]
    for t in r["targets"]:
        met = {True: "yes", False: "**no**", None: "–"}[t["met"]]
        lines.append(f"| {t['target']} | {fmt(t['value'], 2)} {t['unit']} | {t['op']} {t['threshold']} {t['unit']} | {met} |")
    lines.append("")

    # the same two targets' ratios against the plain Asio server (the echo sleeping in epoll)
    both = [(label, s[name]["summary"]) for name, label in (("socket", "socket"), ("jsonrpc", "JSON-RPC"))
            if s.get(name, {}).get("status") == "ok"]
    if both:
        lines += ["Against both echoes: the echo limit polls before sleeping as the transports do "
                  f"(`--spin-us {ECHO_SPIN_US}`); the plain Asio server is the same echo sleeping in `epoll_wait`.", "",
                  "| ratio | / echo limit (polling) | / plain Asio server (sleeping) |", "|---|---|---|"]
        for label, sm in both:
            lat, w64 = sm["latency"], sm["throughput"].get("w64_c1", {})
            lines.append(f"| {label} sync round trip p50 | {fmt(lat['ratio_p50'], 2)} | {fmt(lat.get('plain_ratio_p50'), 2)} |")
            lines.append(f"| {label} pipelined throughput (window 64, 1 connection) | {fmt(w64.get('ratio'), 2)} | "
                         f"{fmt(w64.get('plain_ratio'), 2)} |")
        lines.append("")

    for name, title in (("socket", "Socket transport (MORSE text protocol) vs Asio line echo"),
                        ("jsonrpc", "JSON-RPC transport vs Asio line echo (JSON-RPC-sized lines)")):
        lines += [f"## {title}", ""]
        st = status_line(name)
        if st:
            lines += [st, ""]
            continue
        sm = s[name]["summary"]
        lat = sm["latency"]
        lines += ["| measure | simgate | echo limit (polling) | plain Asio server (sleeping) | simgate / echo "
                  "| simgate / plain |", "|---|---|---|---|---|---|",
                  f"| sync round trip p50 (µs) | {fmt(lat['server_p50_us'])} | {fmt(lat['echo_p50_us'])} | "
                  f"{fmt(lat.get('plain_p50_us'))} | {fmt(lat['ratio_p50'], 2)} | {fmt(lat.get('plain_ratio_p50'), 2)} |",
                  f"| sync round trip p99 (µs) | {fmt(lat['server_p99_us'])} | {fmt(lat['echo_p99_us'])} | "
                  f"{fmt(lat.get('plain_p99_us'))} | {fmt(lat['ratio_p99'], 2)} | {fmt(lat.get('plain_ratio_p99'), 2)} |"]
        for key, t in sm["throughput"].items():
            w, c = key[1:].split("_c")
            lines.append(f"| throughput, window {w}, {c} conn. (req/s) | {fmt(t['server_rps'])} | "
                         f"{fmt(t['echo_rps'])} | {fmt(t.get('plain_rps'))} | {fmt(t['ratio'], 2)} | "
                         f"{fmt(t.get('plain_ratio'), 2)} |")
        lines.append("")

    lines += ["## DDS transport vs raw Cyclone ping-pong", ""]
    st = status_line("dds")
    if st:
        lines += [st, ""]
    else:
        d = s["dds"]["summary"]
        lines += ["| measure | simgate | raw Cyclone | simgate / raw |", "|---|---|---|---|",
                  f"| round trip p50 (µs) | {fmt(d['simgate_p50_us'])} | {fmt(d['raw_p50_us'])} | {fmt(d['ratio_p50'], 2)} |",
                  f"| round trip p99 (µs) | {fmt(d['simgate_p99_us'])} | {fmt(d['raw_p99_us'])} | {fmt(d['ratio_p99'], 2)} |", ""]

    lines += ["## Peers (same client)", ""]
    st = status_line("peers")
    if st:
        lines += [st, ""]
    else:
        lines += ["The echo limit (polling, as the transports do) runs in the same repeat with the same "
                  "lines: echo / peer is the best ratio any server could reach against that peer here.", "",
                  "| measure | simgate | peer | echo limit | simgate / peer | echo / peer |",
                  "|---|---|---|---|---|---|"]
        for key, label, transport in (("morse", "MORSE Python SocketRequestManager", "socket"),
                                      ("jayson", "jayson@5 TCP server", "JSON-RPC")):
            p = s["peers"].get(key, {})
            if p.get("status") != "ok":
                lines.append(f"| {label} | {p.get('status', 'not run')}: {p.get('reason', '')} | | | | |")
                continue
            sm = p["summary"]
            la = sm["latency"]
            lines.append(f"| {transport} vs {label}: round trip p50 (µs) | {fmt(la['simgate_p50_us'])} | "
                         f"{fmt(la['peer_p50_us'])} | {fmt(la.get('echo_p50_us'))} | {fmt(la['ratio_p50'], 3)} | "
                         f"{fmt(la.get('echo_ratio_p50'), 3)} |")
            for k, t in sm["throughput"].items():
                w = k[1:].split("_c")[0]
                lines.append(f"| {transport} vs {label}: throughput, window {w} (req/s) | {fmt(t['simgate_rps'])} | "
                             f"{fmt(t['peer_rps'])} | {fmt(t.get('echo_rps'))} | {fmt(t['ratio'], 1)} | "
                             f"{fmt(t.get('echo_ratio'), 1)} |")
        lines.append("")

    lines += ["## Simulation (demo scene)", ""]
    st = status_line("sim")
    if st:
        lines += [st, ""]
    else:
        sm = s["sim"]["summary"]
        idle, load = sm["realtime_idle"], sm["realtime_load"]
        lines += ["| measure | value |", "|---|---|",
                  f"| bare mj_step loop (steps/s) | {fmt(sm['bare_steps_per_s'])} |",
                  f"| gateway, as fast as possible (steps/s) | {fmt(sm['gateway_steps_per_s'])} |",
                  f"| gateway / bare | {fmt(sm['ratio'], 3)} |",
                  f"| baseline: a loop that only sleeps until each step time (same period): real-time factor / "
                  f"jitter p50, p99 (µs) / overruns | {fmt(sm['sleep_baseline']['realtime_factor'], 4)} / "
                  f"{fmt(sm['sleep_baseline']['jitter_p50_us'])}, {fmt(sm['sleep_baseline']['jitter_p99_us'])} / "
                  f"{sm['sleep_baseline']['overruns']} |",
                  f"| real time, idle: real-time factor / step jitter p50, p99 (µs) / overruns | "
                  f"{fmt(idle['realtime_factor'], 4)} / {fmt(idle['jitter_p50_us'])}, {fmt(idle['jitter_p99_us'])} / {idle['overruns']} |",
                  f"| real time, {load['target_rps']} req/s offered ({fmt(load['achieved_rps'])} answered/s): "
                  f"real-time factor / step jitter p50, p99 (µs) / overruns | {fmt(load['realtime_factor'], 4)} / "
                  f"{fmt(load['jitter_p50_us'])}, {fmt(load['jitter_p99_us'])} / {load['overruns']} |",
                  f"| request latency under that load p50 / p99 (µs) | {fmt(load['request_p50_us'])} / "
                  f"{fmt(load['request_p99_us'])} |"]
        if "spawn" in sm:
            sp = sm["spawn"]
            lines += [f"| spawn_entity of one free body, request to SUCCESS p50 / p99 (ms), {sp['rounds']} rounds | "
                      f"{fmt(sp['spawn_entity']['p50_ms'], 2)} / {fmt(sp['spawn_entity']['p99_ms'], 2)} |",
                      f"| delete_entity of it p50 / p99 (ms) | {fmt(sp['delete_entity']['p50_ms'], 2)} / "
                      f"{fmt(sp['delete_entity']['p99_ms'], 2)} |",
                      f"| beside: the edit alone (spec copy + attach + compile) p50 / p99 (ms) | "
                      f"{fmt(sp['with_entity']['p50_ms'], 2)} / {fmt(sp['with_entity']['p99_ms'], 2)} |",
                      f"| beside: a bare mj_loadXML of the scene p50 / p99 (ms) | {fmt(sp['mj_loadXML']['p50_ms'], 2)} / "
                      f"{fmt(sp['mj_loadXML']['p99_ms'], 2)} |"]
        lines.append("")

    lines += ["## Memory (simgate run, demo config)", ""]
    st = status_line("memory")
    if st:
        lines += [st, ""]
    else:
        mm = s["memory"]["summary"]
        lines += ["| measure | value |", "|---|---|",
                  f"| idle gateway resident (MiB) | {fmt(mm['idle_mib'])} |",
                  f"| with {mm['connections']} idle connections (MiB) | {fmt(mm['with_connections_mib'])} |",
                  f"| added (MiB) / per connection (KiB) | {fmt(mm['added_mib'])} / {fmt(mm['per_connection_kib'])} |", ""]

    lines += ["## Bring your own robot (issue #18)", ""]
    st = status_line("byor")
    if st:
        lines += [st, ""]
    else:
        b = s["byor"]
        h, se, la = b["humanoid"], b["sensors"], b["laser"]
        lines += [f"Debian's humanoid ({h['model']}), {h['steps_per_round']} steps per round from the initial state, "
                  f"{h['rounds']} rounds; gateway / bare is the median of the rounds' ratios (min–max).", "",
                  "| measure | bare | simgate | simgate / bare |", "|---|---|---|---|"]
        for key, label in (("stock", "humanoid as shipped: armature, armature_pose, actuators, pose, odometry"),
                           ("with_sensors", "humanoid + 40 sensor values: the same and sensors")):
            v = h["variants"][key]
            lines.append(f"| {label} (steps/s) | {fmt(v['bare_steps_per_s'])} | {fmt(v['gateway_steps_per_s'])} | "
                         f"{fmt(v['ratio'], 3)} ({fmt(v['ratio_min'], 3)}–{fmt(v['ratio_max'], 3)}) |")
        lines += ["", f"| measure | time now | arm.sensors get_local_data ({se['values']} values) | sensors / time now |",
                  "|---|---|---|---|",
                  f"| socket sync round trip p50 (µs) | {fmt(se['time_now_p50_us'])} | {fmt(se['sensors_p50_us'])} | "
                  f"{fmt(se['ratio_p50'], 2)} |",
                  f"| socket sync round trip p99 (µs) | {fmt(se['time_now_p99_us'])} | {fmt(se['sensors_p99_us'])} | "
                  f"{fmt(se['ratio_p99'], 2)} |", "",
                  "| measure | bare mj_ray loop | laser_scanner | speed ratio |", "|---|---|---|---|",
                  f"| {la['rays']}-ray scan, {la['geoms']} geoms (µs per scan) | {fmt(la['bare_us_per_scan'])} | "
                  f"{fmt(la['update_us_per_scan'])} | {fmt(la['update_speed_ratio'], 3)} |",
                  f"| get_local_data with its JSON (µs per scan, {la['get_local_data_bytes']} bytes) | | "
                  f"{fmt(la['get_local_data_us_per_scan'])} | |", ""]

    lines += ["## Controlling the world (issue #19)", ""]
    st = status_line("world")
    if st:
        lines += [st, ""]
    else:
        w = s["world"]["summary"]
        lines += ["Client-driven stepping on the demo scene, started paused, socket transport: `simulation step [1]` "
                  "back to back (one outstanding) against its limit, one `time now` round trip plus one bare "
                  "`mj_step`, measured side by side in each repeat.", "",
                  "| measure | value |", "|---|---|",
                  f"| `simulation step [1]` calls/s | {fmt(w['step_calls_per_s'])} |",
                  f"| `time now` round trip p50 (µs) | {fmt(w['time_now_p50_us'])} |",
                  f"| bare mj_step (µs) | {fmt(w['bare_step_us'])} |",
                  f"| limit: 1 / (time now p50 + mj_step) (calls/s) | {fmt(w['limit_steps_per_s'])} |",
                  f"| step calls/s / limit | {fmt(w['ratio'], 2)} |",
                  f"| `simulation step [1]` round trip p50 / p99 (µs) | {fmt(w['step_p50_us'])} / "
                  f"{fmt(w['step_p99_us'])} |",
                  f"| save_state / restore_state / mj_copyData (µs) | {fmt(w['save_state_us'], 2)} / "
                  f"{fmt(w['restore_state_us'], 2)} / {fmt(w['mj_copyData_us'], 2)} |", ""]

    lines += ["## Progress reports (issue #20)", ""]
    st = status_line("progress")
    if st:
        lines += [st, ""]
    else:
        g = s["progress"]["summary"]
        lines += [f"{g['calls']} concurrent JSON-RPC calls (one connection each) on the demo scene at real time "
                  f"({g['timestep'] * 1000:g} ms steps), each running {g['round_s']} s, in alternating rounds "
                  "of one gateway: with `_meta: {\"progress\": true}` (progress_interval_ms 1) and without.", "",
                  "| measure | value |", "|---|---|",
                  f"| real-time factor, calls without progress | {fmt(g['realtime_factor_plain'], 4)} |",
                  f"| real-time factor, calls with progress | {fmt(g['realtime_factor_progress'], 4)} |",
                  f"| with / without | {fmt(g['ratio'], 4)} |",
                  f"| rpc.progress received per call per second | {fmt(g['progress_hz_per_call'])} |", ""]

    lines += ["## Data streams (issue #21)", ""]
    st = status_line("streams")
    if st:
        lines += [st, ""]
    else:
        g = s["streams"]["summary"]
        lines += [f"{g['components']} pose sensors at 100 Hz of simulated time, streamed on "
                  f"{', '.join(g['transports'])} at once, every stream read (one socket connection per stream "
                  "port, one JSON-RPC connection subscribed to all), against the same gateway without streams.", "",
                  "| measure | value |", "|---|---|",
                  f"| real-time factor without streams | {fmt(g['realtime_factor_baseline'], 4)} |",
                  f"| real-time factor with streams | {fmt(g['realtime_factor_streams'], 4)} |",
                  f"| samples produced per second | {fmt(g['produced_per_s'])} |",
                  f"| gateway CPU per 1 000 samples produced (ms) | {fmt(g['cpu_ms_per_1000_produced'], 2)} |",
                  f"| gateway CPU per 1 000 samples delivered (ms) | {fmt(g['cpu_ms_per_1000_delivered'], 2)} |",
                  f"| step end to socket read p50 / p99 (µs) | {fmt(g['latency_p50_us'])} / {fmt(g['latency_p99_us'])} |",
                  f"| sync round trip (`time now`) p50 / p99 (µs) | {fmt(g['round_trip_p50_us'])} / "
                  f"{fmt(g['round_trip_p99_us'])} |",
                  f"| one stream alone: step end to socket read p50 / p99 (µs), sync round trip p50 | "
                  f"{fmt(g['one_latency_p50_us'])} / {fmt(g['one_latency_p99_us'])}, {fmt(g['one_round_trip_p50_us'])} |"]
        if "dds_ratio" in g:
            lines += [f"| DDS pose stream samples/s: simgate / raw Cyclone writer | {fmt(g['dds_simgate_per_s'], 0)} / "
                      f"{fmt(g['dds_raw_per_s'], 0)} = {fmt(g['dds_ratio'], 3)} |",
                      f"| the same, written by the DDS thread (`stream_writes` `thread`) | "
                      f"{fmt(g['dds_thread_per_s'], 0)} |"]
        lines += [""]

    lines += ["## Cameras (issue #22)", ""]
    st = status_line("cameras")
    if st:
        lines += [st, ""]
    else:
        sec = s["cameras"]
        g = sec["summary"]
        diff = {f"{x['width']}x{x['height']} {x['kind']}": x["mean_abs_difference"] for x in sec["fps_runs"][0]["rows"]}
        lines += [f"The rover's room (config/scenes/rover_room.xml) seen from the rover cameras' site, on "
                  f"{g['gl_renderer'] or 'an unnamed GL renderer'} (EGL, {g['gl_platform']} display). Bare: "
                  "mjv_updateScene + mjr_render + mjr_readPixels on a GlContext, one frame after the other. "
                  "Renderer: the scene copied (SceneCopy::update, what a camera does under the simulation lock), "
                  "rendered and read back on the render thread, rows flipped (depth linearised), the caller "
                  "waiting for each frame; + PNG: with the image record get_image and capture return (PNG, "
                  f"base64), made on the render thread. Sides alternate in batches of {g['batch']} frames; "
                  "ratios are medians of the rounds' ratios.", "",
                  "| size, kind | bare frames/s | Renderer frames/s | Renderer / bare | + PNG frames/s | "
                  "+ PNG / bare | scene copy p50 (µs) | PNG base64 (KiB) | mean abs. difference |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for row in g["rows"]:
            key = f"{row['size']} {row['kind']}"
            unit = "levels" if row["kind"] == "rgb" else "m"
            lines.append(f"| {row['size']} {row['kind']} | {fmt(row['bare_fps'])} | {fmt(row['raw_fps'])} | "
                         f"{fmt(row['raw_ratio'], 3)} | {fmt(row['png_fps'])} | {fmt(row['png_ratio'], 3)} | "
                         f"{fmt(row['scene_copy_p50_us'], 2)} | {fmt(row['png_kib'])} | "
                         f"{diff.get(key, 0):.3g} {unit} |")
        lines += ["", f"config/rover.json at real time, {g['rtf_seconds']:g} s without a subscriber, then "
                  f"{g['rtf_seconds']:g} s with a JSON-RPC client subscribed to rover.camera "
                  f"({g['image']['width']}x{g['image']['height']} {g['image']['encoding']}, "
                  f"{g['frequency_hz']:g} Hz of simulated time; the PNG made on the transport's thread).", "",
                  "| measure | value |", "|---|---|",
                  f"| real-time factor, no subscriber | {fmt(g['rtf_without'], 4)} |",
                  f"| real-time factor, camera streaming | {fmt(g['rtf_with'], 4)} |",
                  f"| with / without | {fmt(g['rtf_ratio'], 4)} |",
                  f"| images received per second | {fmt(g['samples_per_s'], 2)} |",
                  f"| mean sample (KiB) | {fmt(g['sample_kib'])} |",
                  f"| gateway CPU (s per s), without / with | {fmt(g['cpu_per_s_without'], 3)} / "
                  f"{fmt(g['cpu_per_s_with'], 3)} |", ""]

    lines += ["## Browsers (issue #23)", ""]
    st = status_line("web")
    if st:
        lines += [st, ""]
    else:
        g = s["web"]["summary"]
        lines += [f"config/demo.json at real time, {g['seconds']:g} s with no client, then {g['seconds']:g} s with "
                  f"{g['clients']} WebSocket clients each subscribed to the simulation's body poses ({g['bodies']} "
                  f"bodies) at {g['frequency_hz']:g} Hz, as the web app's pages are.", "",
                  "| measure | value |", "|---|---|",
                  f"| real-time factor, no client | {fmt(g['rtf_without'], 4)} |",
                  f"| real-time factor, {g['clients']} clients | {fmt(g['rtf_with'], 4)} |",
                  f"| with / without | {fmt(g['rtf_ratio'], 4)} |",
                  f"| samples per second per client (mean; fewest) | {fmt(g['samples_per_s_per_client'])}; "
                  f"{fmt(g['fewest_per_s'])} |",
                  f"| mean sample (bytes) | {fmt(g['sample_bytes'], 0)} |",
                  f"| gateway CPU (s per s), without / with | {fmt(g['cpu_per_s_without'], 3)} / "
                  f"{fmt(g['cpu_per_s_with'], 3)} |", ""]

    lines += ["## Foxglove (issue #38)", ""]
    st = status_line("foxglove")
    if st:
        lines += [st, ""]
    else:
        g = s["foxglove"]["summary"]
        lines += [f"bench/pendulums50.xml at real time, {g['seconds']:g} s with no client, then {g['seconds']:g} s with "
                  f"{g['clients']} Foxglove clients each subscribed to /tf ({g['bodies']} transforms) at "
                  f"{g['frequency_hz']:g} Hz and to a 640x480 camera at 10 Hz (foxglove.CompressedImage, "
                  f"{g['image_kib']:.0f} KiB a message).", "",
                  "| measure | value |", "|---|---|",
                  f"| real-time factor, no client | {fmt(g['rtf_without'], 4)} |",
                  f"| real-time factor, {g['clients']} clients | {fmt(g['rtf_with'], 4)} |",
                  f"| with / without | {fmt(g['rtf_ratio'], 4)} |",
                  f"| /tf messages per second, the slowest client | {fmt(g['transforms_per_s_fewest'])} |",
                  f"| images per second, the slowest client | {fmt(g['images_per_s_fewest'], 2)} |",
                  f"| sent to all clients (MiB/s) | {fmt(g['mib_per_s'])} |",
                  f"| gateway CPU (s per s), without / with | {fmt(g['cpu_per_s_without'], 3)} / "
                  f"{fmt(g['cpu_per_s_with'], 3)} |", ""]

    lines += ["## Flight recorder (issue #39)", ""]
    st = status_line("recording")
    if st:
        lines += [st, ""]
    else:
        g = s["recording"]["summary"]
        dropped = s["recording"]["samples_dropped"]
        lines += [f"config/demo.json, one gateway a repeat, recording every output stream, the inputs and each "
                  f"step's state fingerprints to MCAP in every other round (`simulation start_recording` / "
                  f"`stop_recording`), pairs of rounds in alternating order ({g['rounds']} pairs of each kind): "
                  f"steps/s as fast as possible over {g['round_s']:g} s with no client; at real time, "
                  f"{g['round_trips']} `time now` round trips (socket, one outstanding). Ratios are the medians of "
                  "the pairs'. Then each as-fast-as-possible round's recording replayed (`simgate replay --verify "
                  "--json`) against a bare mj_step loop on the same MJCF.", "",
                  "| measure | not recording | recording | recording / not |", "|---|---|---|---|",
                  f"| steps/s, as fast as possible | {fmt(g['plain_steps_per_s'])} | {fmt(g['recorded_steps_per_s'])} | "
                  f"{fmt(g['speed_ratio'], 3)} |",
                  f"| `time now` round trip p50 (µs), real time | {fmt(g['plain_p50_us'])} | "
                  f"{fmt(g['recorded_p50_us'])} | {fmt(g['latency_ratio_p50'], 2)} |",
                  f"| `time now` round trip p99 (µs), real time | {fmt(g['plain_p99_us'])} | "
                  f"{fmt(g['recorded_p99_us'])} | {fmt(g['latency_ratio_p99'], 2)} |", "",
                  "| measure | value |", "|---|---|",
                  f"| file of a {g['round_s']:g} s round as fast as possible (MiB) | {fmt(g['file_mib'], 2)} |",
                  f"| KiB per simulated second (per second at real time) / MiB per second as fast as possible | "
                  f"{fmt(g['kib_per_sim_s'])} / {fmt(g['mib_per_s'], 2)} |",
                  f"| stream samples recorded a round / dropped in all rounds | {fmt(g['samples_per_round'], 0)} / "
                  f"{dropped} |",
                  f"| inputs recorded in a round of round trips | {fmt(g['inputs_per_latency_round'], 0)} |",
                  f"| replay: steps of a recording / steps/s / bare mj_step steps/s | {fmt(g['replay_steps'], 0)} / "
                  f"{fmt(g['replay_steps_per_s'])} / {fmt(g['bare_steps_per_s'])} |",
                  f"| replay / bare | {fmt(g['replay_ratio'], 3)} |", ""]

    lines += ["## Gymnasium environment (issue #40)", ""]
    st = status_line("gym")
    if st:
        lines += [st, ""]
    else:
        lines += ["simgate.gym's `env.step()` (one JSON-RPC batch: set_controls, lockstep_step, the observation's "
                  "reads) against a bare socket loop sending the same batch on a second connection to the same "
                  "simgate (json.dumps / json.loads each step), alternating rounds; and against a bare mj_step loop "
                  "on the same MJCF (simgate_bench_sim --mode bare). Over loopback, one process each side.", "",
                  "| model | requests / step | env.step (µs) | raw batch (µs) | env / raw | env.step steps/s | "
                  "bare mj_step steps/s | env / bare |", "|---|---|---|---|---|---|---|---|"]
        for name, g in s["gym"]["summary"].items():
            lines.append(f"| {name} ({g['actuators']} actuators, {g['observation_size']} observed) | "
                         f"{g['requests_per_step']} | {fmt(g['env_us'])} | {fmt(g['raw_us'])} | "
                         f"{fmt(g['env_over_raw'], 3)} | {fmt(g['env_steps_per_s'], 0)} | "
                         f"{fmt(g['bare_steps_per_s'], 0)} | {fmt(g['env_over_bare'], 4)} |")
        lines.append("")

    lines += ["## Many worlds: step_many (issue #43)", ""]
    st = status_line("farm")
    if st:
        lines += [st, ""]
    else:
        lines += ["World steps per second of many worlds of one model: stepped remotely by `simulation "
                  "step_many` (one JSON-RPC connection, the controls of every world set and qpos, qvel and "
                  "sensordata returned at each call, bench/farm_bench.py), by one `w<k>/simulation step` round "
                  "trip per world and step, and by bare mj_step on as many threads as simgate's pool "
                  "(simgate_bench_sim --mode bare --copies --threads), alternating.", "",
                  "| model | worlds / threads | steps a call | step_many steps/s | / bare | / round trips | "
                  "bare steps/s | round trips steps/s |", "|---|---|---|---|---|---|---|---|"]
        for name, g in s["farm"]["summary"].items():
            for n, v in g["step_many"].items():
                lines.append(f"| {name} | {g['worlds']} / {g['threads']} | {n} | {fmt(v['steps_per_s'], 0)} | "
                             f"{fmt(v['over_bare'], 3)} | {fmt(v['over_round_trips'], 1)} | "
                             f"{fmt(g['bare_steps_per_s'], 0)} | {fmt(g['round_trips_steps_per_s'], 0)} |")
            p = g["pipelined"]
            lines.append(f"| {name} | {g['worlds']} / {g['threads']} | 10, two halves in flight, base64 | "
                         f"{fmt(p['steps_per_s'], 0)} | {fmt(p['over_bare'], 3)} | | "
                         f"{fmt(g['bare_steps_per_s'], 0)} | |")
            if "pipelined_spare_core" in g:
                p = g["pipelined_spare_core"]
                lines.append(f"| {name} | {g['worlds']} / {p['threads']} | 10, two halves in flight, base64 | "
                             f"{fmt(p['steps_per_s'], 0)} | {fmt(p['over_bare'], 3)} | | "
                             f"{fmt(p['bare_steps_per_s'], 0)} | |")
        lines.append("")

    lines += ["## ROS 2 (issue #41)", ""]
    st = status_line("ros2")
    if st:
        lines += [st, ""]
    else:
        g = s["ros2"]["summary"]
        lines += ["A raw ROS 2 client (rmw_cyclonedds' conventions) calling `/step_simulation {steps: 1}` against "
                  "simgate's DdsClient calling `simulation step {\"n\": 1}` on the same gateway (the demo scene, "
                  "paused), interleaved; then /tf of bench/pendulums50.xml's bodies at 100 Hz to a ROS 2 reader at "
                  "real time.", "",
                  "| measure | value |", "|---|---|",
                  f"| StepSimulation round trip p50 / p99 (µs) | {fmt(g['ros2_p50_us'])} / {fmt(g['ros2_p99_us'])} |",
                  f"| DDS `simulation step` round trip p50 / p99 (µs) | {fmt(g['dds_p50_us'])} / {fmt(g['dds_p99_us'])} |",
                  f"| ratio p50 | {fmt(g['ratio_p50'], 2)} |",
                  f"| /tf: messages/s, transforms per message | {fmt(g['tf_messages_per_s'])}, "
                  f"{g['tf_transforms_per_message']:g} |",
                  f"| real-time factor over {g['tf_seconds']:g} s | {fmt(g['tf_rtf'], 4)} |", ""]

    lines += ["## MCP (issue #42)", ""]
    st = status_line("mcp")
    if st:
        lines += [st, ""]
    else:
        g = s["mcp"]["summary"]
        lines += ["An MCP client (streamable HTTP, one kept-alive connection, a session) calling the tool "
                  "`test_component_add {a: 1, b: 2}` against a JSON-RPC client calling `test_component.add` with the "
                  "same arguments over TCP, on the same host's services, interleaved.", "",
                  "| measure | value |", "|---|---|",
                  f"| MCP tool call round trip p50 / p99 (µs) | {fmt(g['mcp_p50_us'])} / {fmt(g['mcp_p99_us'])} |",
                  f"| JSON-RPC (TCP) round trip p50 / p99 (µs) | {fmt(g['jsonrpc_p50_us'])} / {fmt(g['jsonrpc_p99_us'])} |",
                  f"| ratio p50 | {fmt(g['ratio_p50'], 2)} |", ""]

    lines += ["## Sections", "", "| section | status | seconds |", "|---|---|---|"]
    for name, sec in s.items():
        lines.append(f"| {name} | {sec['status']}{(': ' + sec.get('reason', '')) if sec['status'] != 'ok' else ''} "
                     f"| {sec.get('seconds', '')} |")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description="simgate benchmark harness (see docs/performance.md)")
    parser.add_argument("--build-dir", default=os.path.join(ROOT, "build"))
    parser.add_argument("--out", default=None, help="results directory (default: BUILD_DIR/bench-results)")
    parser.add_argument("--smoke", action="store_true", help="seconds-long run that only proves every part works")
    parser.add_argument("--repeats", type=int, default=0)
    parser.add_argument("--only", default="", help="comma-separated sections to run (default: all)")
    args = parser.parse_args()
    if args.out is None:
        args.out = os.path.join(args.build_dir, "bench-results-smoke" if args.smoke else "bench-results")
    code = Harness(args).run()
    print(os.path.join(os.path.abspath(args.out), "results.md"))
    return code


if __name__ == "__main__":
    sys.exit(main())
