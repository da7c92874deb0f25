"""The ros2 transport's topics and simulation_interfaces services as a ROS 2 client nobody on
the team wrote sees them: crates.io's ros2-client (Atostek's pure-Rust ROS 2 on RustDDS, a DDS
implementation other than Cyclone), with rmw_cyclonedds' service mapping
(ServiceMapping::Cyclone). tests/ros2/rust is the client (simgate_ros2_rust_probe); scripts/test
builds it (scripts/lib.sh ensure_rust_test_client) and ctest names it in SIMGATE_ROS2_RUST_PROBE.

RustDDS may discover by multicast and send on every interface, so simgate and the probe both
run in a network namespace of the test's own (unshare -n) that has only its loopback: this file
runs itself in there (`--inside`), starts `simgate run` (config/ros2.json's robot and scene,
simgate's Cyclone on loopback with multicast off, as shipped) and the probe, reads simgate's own
view through the socket transport between the probe's pause and its step, and writes what it
saw to a file, which the test checks. Every wait is bounded; every process is killed.
"""

import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import pytest  # noqa: E402

from conftest import START_TIMEOUT, Gateway, ros2_config  # noqa: E402

PROBE_ENV = "SIMGATE_ROS2_RUST_PROBE"
# the namespace has no other participant: any domain will do
DOMAIN = 0
STEPS = 50
TIMESTEP = 0.002  # config/ros2.json's scene
PROBE_TIMEOUT = 30  # s: the probe's wait for /clock and /tf, and for the go-ahead after its pause
CALL_TIMEOUT = 15  # s: the probe's wait for each service and its reply
# s: the whole run inside, longer than all its own bounded waits together
INSIDE_TIMEOUT = START_TIMEOUT + 2 * PROBE_TIMEOUT + 7 * CALL_TIMEOUT + 60
PAUSED_LINE = "simgate_ros2_rust_probe: paused"


def probe_binary():
    """The probe ctest names; skipped only when pytest runs by hand without it."""
    path = os.environ.get(PROBE_ENV)
    if not path:
        pytest.skip(f"{PROBE_ENV} is not set (ctest sets it): build tests/ros2/rust with "
                    "`source scripts/lib.sh && ensure_rust_test_client` and set it to what "
                    "`rust_test_client_path` prints")
    if not os.access(path, os.X_OK):
        pytest.fail(f"{PROBE_ENV}={path}: no such executable. scripts/test builds it "
                    "(scripts/lib.sh ensure_rust_test_client: needs cargo, rustup's, and "
                    "crates.io); its log says why it is not there")
    return path


def namespace_command():
    """unshare's command for a new network namespace: as root a plain one; otherwise inside a
    user namespace of the user's own (root there), where a network namespace is allowed."""
    unshare = shutil.which("unshare")
    if not unshare or not shutil.which("ip"):
        pytest.fail("unshare (util-linux) and ip (iproute2) are needed: the probe runs in a "
                    "network namespace of the test's own")
    return [unshare, "--net"] if os.geteuid() == 0 else [unshare, "--net", "--map-root-user"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One run in a namespace of its own: the probe's report and simgate's view around it."""
    probe = probe_binary()
    tmp = tmp_path_factory.mktemp("rust")
    command = namespace_command() + [
        "--", sys.executable, os.path.abspath(__file__), "--inside", str(tmp), probe]
    # a process group of its own: simgate and the probe are in it too, killed with it if the
    # run inside ever outlives its own bounded waits
    done = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        stdout, stderr = done.communicate(timeout=INSIDE_TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(done.pid, signal.SIGKILL)
        stdout, stderr = done.communicate(timeout=10)
        pytest.fail(f"the run in the network namespace took over {INSIDE_TIMEOUT} s:\n"
                    f"{stdout}\n{stderr}")
    if done.returncode != 0:
        pytest.fail(f"the run in the network namespace failed ({done.returncode}): "
                    f"{' '.join(command)}\n{stdout}\n{stderr}")
    outcome = json.loads((tmp / "outcome.json").read_text())
    if outcome["probe_status"] != 0 or not outcome["report"]:
        pytest.fail(f"simgate_ros2_rust_probe exited with {outcome['probe_status']}:\n"
                    f"{outcome['probe_stderr']}\nsimgate's log:\n{outcome['simgate_log']}")
    return outcome


def test_clock_and_tf_reach_the_rust_client(run):
    report = run["report"]
    assert report["clock"]["sec"] >= 0 and 0 <= report["clock"]["nanosec"] < 1_000_000_000
    assert "robot" in report["tf_frames"]
    assert report["tf_parents"]["robot"] == "world"
    assert report["tf_parents"]["robot_left_wheel"] == "robot"


def test_the_simulation_state_services_answer_the_rust_client(run):
    report = run["report"]
    before = report["get_simulation_state"]
    assert (before["result"], before["error_message"]) == (1, "")  # RESULT_OK
    assert before["state"] == 1  # STATE_PLAYING: config/ros2.json runs at once
    assert report["set_simulation_state"]["result"] == 1
    after = report["get_simulation_state_after"]
    assert (after["result"], after["state"]) == (1, 2)  # RESULT_OK, STATE_PAUSED


def test_step_simulation_steps_exactly_what_the_rust_client_asked(run):
    report = run["report"]
    assert report["step_simulation"]["result"] == 1, report["step_simulation"]
    # simgate's own view, paused, before and after the steps (the socket transport)
    before, after = run["before"], run["after"]
    assert before["state"] == after["state"] == "paused"
    assert after["timestep"] == before["timestep"] == TIMESTEP
    assert after["steps"] - before["steps"] == STEPS
    assert after["sim_time"] - before["sim_time"] == pytest.approx(STEPS * TIMESTEP, abs=1e-9)
    # and /clock, once the steps are done, within a step of it (test_clock_after_steps_is_exact)
    clock = report["clock_after_step"]
    assert clock is not None, "no /clock sample in the 1.5 s after the steps"
    assert clock["sec"] + clock["nanosec"] * 1e-9 == pytest.approx(
        after["sim_time"], abs=TIMESTEP + 1e-6)


def test_clock_after_steps_is_the_time_of_the_last_data(run):
    """/clock says the time of the data last published (docs/transports/ros2.md, /clock): the
    state the last step started from, one timestep before the simulation's own clock after it,
    so that /tf stamped then is never ahead of /clock (tf2 would refuse to extrapolate)."""
    clock = run["report"]["clock_after_step"]
    assert clock is not None
    assert clock["sec"] + clock["nanosec"] * 1e-9 == pytest.approx(
        run["after"]["sim_time"] - TIMESTEP, abs=1e-6)


def test_get_entities_lists_the_robot_to_the_rust_client(run):
    entities = run["report"]["get_entities"]
    assert (entities["result"], entities["error_message"]) == (1, "")
    assert "robot" in entities["entities"]


# ---- inside the network namespace (this file run as a program by the fixture `run`)


def only_loopback():
    """Up the namespace's loopback, and make sure it is the only interface there is."""
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True, timeout=10)
    with open("/proc/self/net/dev") as f:  # this namespace's (/sys/class/net is the host's)
        interfaces = sorted(line.split(":")[0].strip() for line in f.readlines()[2:])
    if interfaces != ["lo"]:
        sys.exit(f"not in a network namespace of the test's own: interfaces {interfaces}")


def inside(tmp, probe):
    only_loopback()
    outcome = {"probe_status": None, "report": None, "before": None, "after": None,
               "probe_stderr": "", "simgate_log": ""}
    gateway = Gateway(tmp, ros2_config("ros2.json", DOMAIN), "rust")
    process = None
    try:
        client = gateway.socket()
        stdout_path = tmp / "probe-stdout.json"
        with open(stdout_path, "w") as stdout:
            process = subprocess.Popen(
                [probe, "--domain", str(DOMAIN), "--steps", str(STEPS), "--gate",
                 "--timeout", str(PROBE_TIMEOUT), "--call-timeout", str(CALL_TIMEOUT)],
                stdin=subprocess.PIPE, stdout=stdout, stderr=subprocess.PIPE, text=True)
        lines = queue.Queue()
        stderr = []

        def read_stderr():
            for line in process.stderr:
                stderr.append(line)
                lines.put(line.rstrip("\n"))
            lines.put(None)  # end of file: the probe has exited

        threading.Thread(target=read_stderr, daemon=True).start()
        # the probe's pause, then simgate's view of the paused simulation before the steps
        deadline = time.monotonic() + PROBE_TIMEOUT + 3 * CALL_TIMEOUT + 10
        while True:
            try:
                line = lines.get(timeout=max(0.1, deadline - time.monotonic()))
            except queue.Empty:
                line = None
            if line == PAUSED_LINE or line is None or time.monotonic() > deadline:
                break
        if line == PAUSED_LINE:
            outcome["before"] = client.call("simulation", "get_simulation_state")
            process.stdin.write("go\n")
            process.stdin.flush()
        process.stdin.close()
        try:
            outcome["probe_status"] = process.wait(timeout=PROBE_TIMEOUT + 4 * CALL_TIMEOUT)
        except subprocess.TimeoutExpired:
            process.kill()
            outcome["probe_status"] = process.wait(timeout=10)
            stderr.append("(killed: it did not end in time)\n")
        if outcome["probe_status"] == 0:
            outcome["after"] = client.call("simulation", "get_simulation_state")
            outcome["report"] = json.loads(stdout_path.read_text())
        time.sleep(0.1)  # the stderr reader's last lines (it ends with the pipe)
        outcome["probe_stderr"] = "".join(stderr)
        client.close()
    finally:
        if process is not None and process.poll() is None:
            process.kill()
            process.wait(timeout=10)
        outcome["simgate_log"] = gateway.output()[-4000:]
        gateway.kill()
        (tmp / "outcome.json").write_text(json.dumps(outcome))


if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] != "--inside":
        sys.exit(f"usage: {sys.argv[0]} --inside TMPDIR PROBE (the test runs it in a network "
                 "namespace of its own)")
    inside(Path(sys.argv[2]), sys.argv[3])
