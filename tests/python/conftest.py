"""Fixtures of the Python client's tests: real `simgate run` processes on ephemeral ports.

The simgate executable is `SIMGATE_BIN` (ctest passes the build's; default: `simgate` on
PATH), its transport plugins are looked for in `SIMGATE_PLUGIN_DIR` too (`--plugin-path`), and
scenes are read from the source tree (`SIMGATE_SOURCE_DIR`, default: this checkout). Every
process listens on 127.0.0.1, port 0, reported by `--endpoints-file`; every wait is bounded;
every process is killed at the end of its fixture.
"""

import json
import os
import shutil
import subprocess
import time

import pytest

SOURCE_DIR = os.environ.get("SIMGATE_SOURCE_DIR") or os.path.abspath(
    os.path.join(os.path.dirname(__file__), "..", ".."))
START_TIMEOUT = 60
TOKEN = "python-client-test-token-0123456789"


def simgate_binary():
    binary = os.environ.get("SIMGATE_BIN") or shutil.which("simgate")
    if not binary:
        pytest.fail("no simgate executable: set SIMGATE_BIN (ctest does) or put simgate on PATH")
    return binary


class Gateway:
    """`simgate run CONFIG` on ports the kernel picks; `url(scheme)` gives the client's URL."""

    def __init__(self, tmp_path, config, name="gateway", env=None):
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(config))
        endpoints = tmp_path / f"{name}-endpoints.json"
        command = [simgate_binary(), "run", str(path), "--endpoints-file", str(endpoints),
                   "--realtime-factor", "max"]
        if os.environ.get("SIMGATE_PLUGIN_DIR"):
            command += ["--plugin-path", os.environ["SIMGATE_PLUGIN_DIR"]]
        self.log_path = tmp_path / f"{name}.log"
        self.log = open(self.log_path, "w")
        self.process = subprocess.Popen(command, stdout=self.log, stderr=subprocess.STDOUT,
                                        env={**os.environ, **(env or {})})
        try:
            deadline = time.monotonic() + START_TIMEOUT
            while not endpoints.exists():
                if self.process.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("simgate run did not start:\n" + self.output())
                time.sleep(0.02)  # polling for the file the child writes, bounded by the deadline
            self.endpoints = json.loads(endpoints.read_text())
        except BaseException:
            self.kill()
            raise

    def url(self, scheme):
        transport = {"jsonrpc": "jsonrpc", "ws": "websocket", "socket": "socket"}[scheme]
        address = self.endpoints[transport][0]  # tcp://127.0.0.1:P or ws://127.0.0.1:P/
        return scheme + "://" + address.split("://", 1)[1]

    def output(self):
        self.log.flush()
        return self.log_path.read_text()

    def kill(self):
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(timeout=START_TIMEOUT)
        self.log.close()


def rover_config(auth=False):
    """The rover room (cameras, pose, motion, waypoint) paused, on the three transports."""
    scenes = os.path.join(SOURCE_DIR, "config", "scenes")
    options = {"host": "127.0.0.1", "port": 0}
    if auth:
        options["auth"] = {"token_env": "SIMGATE_PY_TEST_TOKEN", "loopback": True}
    with open(os.path.join(SOURCE_DIR, "config", "rover.json")) as f:
        config = json.load(f)
    config["scene"]["mjcf"] = os.path.join(scenes, "rover_room.xml")
    config["scene"]["start_paused"] = True
    config["transports"] = {
        "socket": {"plugin": "socket", "options": {**options, "stream_port": 0}},
        "jsonrpc": {"plugin": "jsonrpc", "options": dict(options)},
        "websocket": {"plugin": "websocket", "options": {**options, "web": False}},
    }
    del config["services"]  # every transport serves every component
    everywhere = ["socket", "jsonrpc", "websocket"]
    config["streams"] = {"rover.pose": everywhere, "rover.motion": everywhere,
                         "rover.camera": ["jsonrpc", "websocket"]}
    config["log_level"] = "warning"
    return config


@pytest.fixture(scope="session")
def gateway(tmp_path_factory):
    """One rover simulation for the session, its transports requiring the token `TOKEN`."""
    gw = Gateway(tmp_path_factory.mktemp("gateway"), rover_config(auth=True),
                 env={"SIMGATE_PY_TEST_TOKEN": TOKEN})
    yield gw
    gw.kill()


@pytest.fixture
def fresh_gateway(tmp_path):
    """A simulation of the test's own (one the test may kill)."""
    gw = Gateway(tmp_path, rover_config(), name="fresh")
    yield gw
    gw.kill()


@pytest.fixture(params=["jsonrpc", "ws", "socket"])
def scheme(request):
    return request.param


@pytest.fixture
def sim(gateway, scheme):
    """A client of the session's simulation over `scheme`, the simulation paused."""
    import simgate
    client = simgate.connect(gateway.url(scheme), token=TOKEN, timeout=20)
    client.pause()
    yield client
    client.close()
