#!/usr/bin/python3
"""BenchSmoke: runs bench/harness.py --smoke and checks that its results are well formed.

Checks, never timing thresholds:
  * the harness exits 0 and writes results.json and results.md;
  * every section (socket, jsonrpc, dds, peers, sim, memory, byor, world, progress, streams, cameras, web) is present and "ok", or
    "skipped" with a reason (a part this build does not have, e.g. DDS switched off);
  * every figure an ok section reports is a finite, positive number (a silently empty
    measurement, such as zero replies, fails here), except those that may be 0 on a good
    run: overruns, jitter, a minimum, and the memory a few smoke connections add (the
    allocator may reuse pages it already had);
  * every target of the issue has a value, a threshold and a verdict;
  * the socket and JSON-RPC sections report simgate against both echoes: the echo limit
    (polling, ratio_p50 / ratio) and the plain Asio server (sleeping, plain_ratio_p50 /
    plain_ratio), and results.md shows both; the echo server runs with --spin-us;
  * results.md has the targets table and a table per section;
  * the load generator counts a wrong reply as an error, never as a measurement;
  * a server slower than the measurement still gets a rate (never 0 req/s).
Prints one line per check and "N passed, N failed" at the end.
"""
import argparse
import json
import math
import os
import socket
import subprocess
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SECTIONS = ("socket", "jsonrpc", "dds", "peers", "sim", "memory", "byor", "world", "progress", "streams", "cameras", "web",
            "recording", "gym", "ros2", "mcp", "farm")

passed, failed = 0, 0


def check(ok, what):
    global passed, failed
    if ok:
        passed += 1
        print(f"[ OK ] {what}")
    else:
        failed += 1
        print(f"[FAIL] {what}")
    return ok


def numbers(value, path=""):
    """Every number inside a summary, with its JSON path."""
    if isinstance(value, bool):
        return
    if isinstance(value, (int, float)):
        yield path, value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from numbers(v, f"{path}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from numbers(v, f"{path}[{i}]")


def check_wrong_replies_counted(build_dir):
    """The load generator must not count a wrong reply as a measurement: the echo server
    answers a socket request with the request itself, not "<id> SUCCESS ...", so every reply
    of a socket-protocol run against it is an error (and the harness refuses such runs)."""
    bin_dir = os.path.join(os.path.abspath(build_dir), "bin")
    echo = subprocess.Popen([os.path.join(bin_dir, "simgate_bench_echo"), "--spin-us", "50", "--max-seconds", "120"],
                            stdout=subprocess.PIPE, text=True)
    try:
        port = json.loads(echo.stdout.readline())["port"]
        done = subprocess.run([os.path.join(bin_dir, "simgate_bench_loadgen"), "--port", str(port), "--proto",
                               "socket", "--count", "5", "--warmup", "0"], capture_output=True, text=True,
                              timeout=120)
        result = json.loads(done.stdout.strip().splitlines()[-1]) if done.returncode == 0 else {}
        check(result.get("errors") == 5, f"loadgen counts non-SUCCESS replies as errors ({result.get('errors')} of 5)")
        done = subprocess.run([os.path.join(bin_dir, "simgate_bench_loadgen"), "--port", str(port), "--proto",
                               "socket", "--echo", "--count", "5", "--warmup", "0"], capture_output=True, text=True,
                              timeout=120)
        result = json.loads(done.stdout.strip().splitlines()[-1]) if done.returncode == 0 else {}
        check(result.get("errors") == 0 and result.get("n") == 5, "loadgen --echo accepts echoed requests")
    finally:
        echo.terminate()
        check(echo.wait(timeout=30) == 0, "echo server (polling, --spin-us 50) exits cleanly on SIGTERM")
        echo.stdout.close()


def check_slow_server_still_measured(build_dir):
    """A server slower than --duration (MORSE's Python loop on a busy host) must still get a
    rate from at least one full window of replies, never 0 req/s: the loadgen measures on
    until the window came back (up to 10 s more)."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    listener.settimeout(30)

    def serve():
        try:
            conn, _ = listener.accept()
        except OSError:
            return
        with conn:
            conn.settimeout(30)
            try:
                while True:
                    data = conn.recv(65536)
                    if not data:
                        return
                    time.sleep(0.3)  # slower than the whole measurement below
                    conn.sendall(data)
            except OSError:
                return

    server = threading.Thread(target=serve, daemon=True)
    server.start()
    try:
        bin_dir = os.path.join(os.path.abspath(build_dir), "bin")
        done = subprocess.run([os.path.join(bin_dir, "simgate_bench_loadgen"), "--port", str(listener.getsockname()[1]),
                               "--proto", "socket", "--echo", "--mode", "throughput", "--window", "4",
                               "--duration", "0.05", "--warmup-seconds", "0.01"],
                              capture_output=True, text=True, timeout=60)
        result = json.loads(done.stdout.strip().splitlines()[-1]) if done.returncode == 0 else {}
        check(result.get("replies", 0) >= 4 and result.get("rps", 0) > 0,
              f"a server slower than --duration still gets a rate ({result.get('replies')} replies, "
              f"{result.get('rps')} req/s)")
    finally:
        listener.close()
        server.join(timeout=30)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--build-dir", required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    harness = os.path.join(ROOT, "bench", "harness.py")
    done = subprocess.run([sys.executable, harness, "--smoke", "--build-dir", args.build_dir, "--out", args.out],
                          capture_output=True, text=True, timeout=840)
    sys.stdout.write(done.stderr)
    check(done.returncode == 0, f"harness exit code {done.returncode} (0 expected)")

    results_path = os.path.join(args.out, "results.json")
    if not check(os.path.exists(results_path), "results.json written"):
        return 1
    with open(results_path) as f:
        results = json.load(f)
    check(results.get("mode") == "smoke", "results.json says mode smoke")
    for key in ("date", "machine", "sections", "targets"):
        check(key in results, f"results.json has '{key}'")
    check(bool(results["machine"].get("pinning")), "the pinning policy is stated")

    for name in SECTIONS:
        section = results["sections"].get(name)
        if not check(section is not None, f"section {name} ran"):
            continue
        status = section.get("status")
        if status == "skipped":
            check(bool(section.get("reason")), f"section {name} skipped with a reason: {section.get('reason')}")
            continue
        check(status == "ok", f"section {name} ok (status {status}: {section.get('reason', '')})")
        summaries = [section.get("summary")] if "summary" in section else \
            [v.get("summary") for v in section.values() if isinstance(v, dict) and v.get("status") == "ok"]
        for summary in summaries:
            bad = [(p, v) for p, v in numbers(summary)
                   if not math.isfinite(v) or (v <= 0 and not p.endswith("overruns") and "jitter" not in p
                                               and not p.endswith(".min") and not p.endswith("added_mib")
                                               and not p.endswith("per_connection_kib"))]
            check(summary is not None and not bad, f"section {name}: figures finite and positive {bad[:3]}")

    for name in ("socket", "jsonrpc"):
        section = results["sections"].get(name) or {}
        if section.get("status") != "ok":
            continue
        sm = section.get("summary", {})
        lat, w64 = sm.get("latency", {}), sm.get("throughput", {}).get("w64_c1", {})
        for what, value in (("sync p50 / echo limit", lat.get("ratio_p50")),
                            ("sync p50 / plain Asio server", lat.get("plain_ratio_p50")),
                            ("plain Asio server p50", lat.get("plain_p50_us")),
                            ("window-64 throughput / echo limit", w64.get("ratio")),
                            ("window-64 throughput / plain Asio server", w64.get("plain_ratio")),
                            ("plain Asio server window-64 rps", w64.get("plain_rps"))):
            median = value.get("median") if isinstance(value, dict) else None
            check(isinstance(median, (int, float)) and median > 0, f"section {name}: {what} reported ({median})")
        check(sm.get("echo_spin_us", 0) > 0, f"section {name}: the echo limit polls (echo_spin_us "
                                             f"{sm.get('echo_spin_us')})")

    for t in results["targets"]:
        ok = t.get("threshold") is not None and t.get("op") in ("<=", ">=") and t.get("met") in (True, False)
        check(ok, f"target '{t.get('target')}' has a value and a verdict")
    check(len(results["targets"]) >= 1, "targets recorded")

    md_path = os.path.join(args.out, "results.md")
    if check(os.path.exists(md_path), "results.md written"):
        with open(md_path) as f:
            md = f.read()
        for heading in ("## Targets", "## Socket transport", "## JSON-RPC transport", "## DDS transport",
                        "## Peers", "## Simulation", "## Memory", "## Bring your own robot",
                        "## Controlling the world", "## Progress reports", "## Data streams", "## Cameras",
                        "## Browsers", "## ROS 2", "## MCP", "## Many worlds"):
            check(heading in md, f"results.md has '{heading}'")
        if any((results["sections"].get(n) or {}).get("status") == "ok" for n in ("socket", "jsonrpc")):
            for text in ("/ echo limit (polling)", "/ plain Asio server (sleeping)", "simgate / plain"):
                check(text in md, f"results.md shows '{text}'")

    check_wrong_replies_counted(args.build_dir)
    check_slow_server_still_measured(args.build_dir)
    print(f"{passed} passed, {failed} failed")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
