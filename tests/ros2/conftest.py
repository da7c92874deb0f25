"""Fixtures of the ros2 transport's tests: real `simgate run` processes, read and driven as a
ROS 2 node would, by PyPI's cyclonedds binding (its own Cyclone DDS, 11) with the hand-declared
types of ros2_types.py, and checked against simgate's own view through the MORSE socket
protocol.

Every process and participant keeps to loopback (CYCLONEDDS_URI: config/dds/loopback.xml,
which ctest sets for both sides), on a DDS domain of the test session's own (two simulations
on two domains), the socket transport on port 0 (`--endpoints-file`); every wait is bounded;
every process is killed at the end of its fixture.
"""

import json
import os
import shutil
import socket
import subprocess
import time

import pytest

SOURCE_DIR = os.environ.get("SIMGATE_SOURCE_DIR") or os.path.abspath(
    os.path.join(os.path.dirname(__file__), "..", ".."))
START_TIMEOUT = 60
# DOMAINS domains of this session's own (DOMAIN_BASE + 0 .. 6 within 1 .. 230: the rover, the
# arm, the pose rover, the services' and the action's simulations, the sensors' rover, the
# rover of two worlds), so that parallel runs do not see each other (two sessions share theirs
# only when their pids agree modulo 32)
DOMAINS = 7
DOMAIN_BASE = 1 + (os.getpid() % (230 // DOMAINS)) * DOMAINS


def simgate_binary():
    binary = os.environ.get("SIMGATE_BIN") or shutil.which("simgate")
    if not binary:
        pytest.fail("no simgate executable: set SIMGATE_BIN (ctest does) or put simgate on PATH")
    return binary


class Socket:
    """A MORSE socket protocol client (one request per line, `<id> <component> <service>
    [params]`, one reply per line, `<id> <status> [value]`), for simgate's own view."""

    def __init__(self, address):
        host, port = address.split("://", 1)[1].rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)), timeout=10)
        self.buffer = b""
        self.next_id = 0

    def call(self, component, service, *params):
        self.next_id += 1
        line = f"{self.next_id} {component} {service}"
        if params:
            line += " " + json.dumps(list(params))
        self.sock.sendall(line.encode() + b"\n")
        while b"\n" not in self.buffer:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise RuntimeError("the socket transport closed the connection")
            self.buffer += chunk
        reply, self.buffer = self.buffer.split(b"\n", 1)
        rid, status, *rest = reply.decode().split(" ", 2)
        assert rid == str(self.next_id), reply
        if status != "SUCCESS":
            raise RuntimeError(f"{component} {service}: {reply.decode()}")
        return json.loads(rest[0]) if rest else None

    def close(self):
        self.sock.close()


class Gateway:
    """`simgate run CONFIG`; `socket()` gives a socket protocol client of it."""

    def __init__(self, tmp_path, config, name):
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(config))
        endpoints = tmp_path / f"{name}-endpoints.json"
        command = [simgate_binary(), "run", str(path), "--endpoints-file", str(endpoints)]
        if os.environ.get("SIMGATE_PLUGIN_DIR"):
            command += ["--plugin-path", os.environ["SIMGATE_PLUGIN_DIR"]]
        self.log_path = tmp_path / f"{name}.log"
        self.log = open(self.log_path, "w")
        self.process = subprocess.Popen(command, stdout=self.log, stderr=subprocess.STDOUT)
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

    def socket(self):
        return Socket(self.endpoints["socket"][0])

    def output(self):
        self.log.flush()
        return self.log_path.read_text()

    def kill(self):
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(timeout=START_TIMEOUT)
        self.log.close()


def ros2_config(name, domain):
    """config/<name>.json's scene and robots, with the ros2 transport on `domain` and the
    socket transport on port 0 for simgate's own view."""
    with open(os.path.join(SOURCE_DIR, "config", name)) as f:
        config = json.load(f)
    config["scene"]["mjcf"] = os.path.join(SOURCE_DIR, "config", config["scene"]["mjcf"])
    options = config["transports"].get("ros2", {}).get("options", {})
    config["transports"] = {
        "socket": {"plugin": "socket",
                   "options": {"host": "127.0.0.1", "port": 0, "stream_port": 0}},
        "ros2": {"plugin": "ros2", "options": {**options, "domain": domain}},
    }
    config["log_level"] = "warning"
    return config


@pytest.fixture(scope="session")
def rover_domain():
    return DOMAIN_BASE


@pytest.fixture(scope="session")
def rover(tmp_path_factory, rover_domain):
    """config/ros2.json as it ships (the demo scene's robot: odometry, motion; /tf), its ROS 2
    topics on `rover_domain`."""
    config = ros2_config("ros2.json", rover_domain)
    gw = Gateway(tmp_path_factory.mktemp("rover"), config, "rover")
    yield gw
    gw.kill()


@pytest.fixture(scope="session")
def arm_domain():
    return DOMAIN_BASE + 1


@pytest.fixture(scope="session")
def arm(tmp_path_factory, arm_domain):
    """config/arm.json's arm on the table, its joints on /arm/joint_states, its armature's
    joint_positions from /arm/joint_command, on `arm_domain`."""
    config = ros2_config("arm.json", arm_domain)
    config["services"] = {"default": ["socket"], "simulation": ["socket", "ros2"]}
    config["streams"] = {"arm.armature_pose": {"transports": ["ros2"], "frequency": 50},
                         "arm.armature": ["ros2"],
                         "simulation": {"transports": ["ros2"], "frequency": 20}}
    gw = Gateway(tmp_path_factory.mktemp("arm"), config, "arm")
    yield gw
    gw.kill()


@pytest.fixture(scope="session")
def pose_domain():
    return DOMAIN_BASE + 2


@pytest.fixture(scope="session")
def pose_rover(tmp_path_factory, pose_domain):
    """The demo scene's robot with a pose sensor only (no odometry), its /odom from it, in the
    frame "map" (option world_frame); only the robot "robot" carried (option robots); the ROS
    graph as ROS 2 Humble reads it (option ros_distro)."""
    config = ros2_config("ros2.json", pose_domain)
    config["transports"]["ros2"]["options"].update(
        {"world_frame": "map", "robots": ["robot"], "clock_hz": 20, "ros_distro": "humble"})
    robot = config["robots"][0]
    robot["components"] = [c for c in robot["components"] if c["type"] != "odometry"]
    config["streams"] = {"robot.pose": ["ros2"], "robot.motion": ["ros2"]}
    gw = Gateway(tmp_path_factory.mktemp("pose"), config, "pose")
    yield gw
    gw.kill()


@pytest.fixture(scope="session")
def sensors_domain():
    return DOMAIN_BASE + 5


@pytest.fixture(scope="session")
def sensor_rover(tmp_path_factory, sensors_domain):
    """config/rover.json's rover in its room, its laser, camera and depth camera carried by the
    ros2 transport (small images, few a second: rendered only while a ROS reader reads them),
    with /tf_static for their frames, on `sensors_domain`; the depth camera's stream on the
    socket transport too, for its statistics (no socket client subscribes to it)."""
    config = ros2_config("rover.json", sensors_domain)
    robot = config["robots"][0]
    for component in robot["components"]:
        if component["name"] in ("camera", "depth"):
            component["frequency"] = 5
            component["options"].update({"cam_width": 160, "cam_height": 120})
    robot["components"] = [c for c in robot["components"] if c["name"] != "overhead"]
    # (simulation: its get_scene_geometry gives /tf_static its frames)
    config["services"] = {"default": ["socket"], "simulation": ["socket", "ros2"]}
    config["streams"] = {"rover.laser": {"transports": ["ros2"], "frequency": 10},
                         "rover.camera": ["ros2"], "rover.depth": ["ros2", "socket"],
                         "simulation": {"transports": ["ros2"], "frequency": 10}}
    gw = Gateway(tmp_path_factory.mktemp("sensors"), config, "sensors")
    yield gw
    gw.kill()


@pytest.fixture(scope="session")
def worlds_domain():
    return DOMAIN_BASE + 6


@pytest.fixture(scope="session")
def worlds_rover(tmp_path_factory, worlds_domain):
    """config/ros2.json in two worlds (docs/worlds.md): world 0's topics as ever, world 1's in
    the namespace /w1, on `worlds_domain`."""
    config = ros2_config("ros2.json", worlds_domain)
    config["worlds"] = 2
    gw = Gateway(tmp_path_factory.mktemp("worlds"), config, "worlds")
    yield gw
    gw.kill()


def check_config(tmp_path, ros2_options):
    """`simgate check` of config/ros2.json with these ros2 options: (exit code, output)."""
    config = ros2_config("ros2.json", 0)
    config["transports"]["ros2"]["options"] = ros2_options
    path = tmp_path / "check.json"
    path.write_text(json.dumps(config))
    command = [simgate_binary(), "check", str(path)]
    if os.environ.get("SIMGATE_PLUGIN_DIR"):
        command += ["--plugin-path", os.environ["SIMGATE_PLUGIN_DIR"]]
    done = subprocess.run(command, capture_output=True, text=True, timeout=START_TIMEOUT)
    return done.returncode, done.stdout + done.stderr


@pytest.fixture(scope="module")
def own(sim):
    """A socket protocol client of the module's own simulation (its fixture `sim`): simgate's
    own view, the reference the ROS 2 side is checked against."""
    client = sim.socket()
    yield client
    client.close()
