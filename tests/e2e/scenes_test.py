#!/usr/bin/python3
"""E2E: the shipped scenes (issue #18, "Scenes"): config/arm.json and config/rover.json.

Both configs pass `simgate check` as shipped. Each is then run (a copy: the scene's absolute
path, every transport on port 0, the bound ports read from --endpoints-file) and used the
way its README section shows, with MORSE's socket protocol on a raw socket, Debian's pymorse
(python3-morse-simulator, run with /usr/bin/python3) and once JSON-RPC:

- the arm on its table: at rest nothing drifts over 10 simulated seconds and the wrist
  force/torque sensor reads the hand's weight; rotate_joints of two joints reaches both
  targets (armature_pose and the jointpos sensors agree); the arm reaches down to the box,
  the gripper closes on it (both touch sensors press, the fingers stop at the box's sides,
  short of closed) and lifts it off the table; a finger target beyond its ctrlrange is
  refused;
- the rover in its room: the laser's 271 rays see the walls where the room puts them (and
  nothing through the door), also after a teleport; the IMU reads gravity at rest; a goto
  arrives; the integrated odometry matches the pose; proximity finds the crates; the depth
  camera sees the east wall where the laser does, and the camera's capture returns PNGs;
  `simulation get_snapshot` pictures the room.

The physics is predicted from the scenes' geometry (positions, masses), not recorded. Every
wait is bounded; no assertion is on wall-clock time.
"""
import argparse
import base64
import json
import logging
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
import unittest
import urllib.parse
import zlib
import warnings

warnings.simplefilter("ignore", DeprecationWarning)  # asyncore/asynchat on Python 3.11
import pymorse  # noqa: E402
from pymorse import MorseServiceFailed  # noqa: E402

ARGS = None
TIMEOUT = 60  # seconds, for any single wait
GRAVITY = 9.81

# config/scenes/arm_table.xml: the hand and its fingers (palm 0.25 kg, fingers 0.05 kg each)
HAND_MASS = 0.35
# the box: a 0.05 m cube on the table top (z = 0.75), centred at (0.1, 0, 0.775)
BOX_X, BOX_HALF, TABLE_TOP = 0.1, 0.025, 0.75
# a finger's inner face is 0.042 m from the hand's centre line when open (joint at 0)
FINGER_OPEN_GAP_HALF = 0.042
FINGER_CLOSED = 0.04  # the finger joints' upper limit and servo ctrlrange


def arm_pitch_joints(x, z):
    """shoulder_lift, elbow and wrist_pitch (rad) that put the arm's `grasp` site at (x, 0, z)
    with the hand pointing straight down (the scene's geometry: the shoulder_lift axis at
    (-0.35, 0, 0.9), a 0.3 m upper arm, 0.29 m from the elbow to the wrist_pitch axis, and
    the grasp site 0.145 m beyond it). Elbow up; all three lean towards +x."""
    upper, fore, hand = 0.3, 0.29, 0.145
    dx, dz = x + 0.35, z + hand - 0.9
    elbow = math.acos((dx * dx + dz * dz - upper * upper - fore * fore) / (2 * upper * fore))
    shoulder = math.atan2(dx, dz) - math.atan2(fore * math.sin(elbow), upper + fore * math.cos(elbow))
    return {"shoulder_lift": shoulder, "elbow": elbow, "wrist_pitch": math.pi - shoulder - elbow}


class Gateway:
    """A `simgate run` child process on a copy of a shipped config, every transport on an
    ephemeral port."""

    def __init__(self, config_name, workdir):
        with open(os.path.join(ARGS.source_dir, "config", config_name)) as f:
            config = json.load(f)
        config["scene"]["mjcf"] = os.path.join(ARGS.source_dir, "config", config["scene"]["mjcf"])
        config["scene"]["realtime_factor"] = 4.0  # bounded CPU, shorter waits
        for transport in config["transports"].values():
            transport["options"]["port"] = 0
        config["log_level"] = "warning"
        self.config_path = os.path.join(workdir, config_name)
        with open(self.config_path, "w") as f:
            json.dump(config, f)
        self.endpoints_path = os.path.join(workdir, "endpoints.json")
        self.log = open(os.path.join(workdir, "gateway.log"), "w+")
        self.process = subprocess.Popen(
            [ARGS.simgate, "run", self.config_path, "--endpoints-file", self.endpoints_path],
            stdout=self.log, stderr=subprocess.STDOUT)
        try:
            deadline = time.monotonic() + TIMEOUT
            while not os.path.exists(self.endpoints_path):
                if self.process.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("gateway did not start:\n" + self.output())
                time.sleep(0.01)  # polling for a file the child writes; bounded by the deadline
            with open(self.endpoints_path) as f:
                endpoints = json.load(f)  # {"socket": ["tcp://127.0.0.1:PORT"], ...}
            # "tcp://127.0.0.1:4000", "ws://127.0.0.1:8765/"
            self.ports = {name: urllib.parse.urlsplit(e[0]).port for name, e in endpoints.items()}
        except BaseException:
            # a start that fails half way must not leave the child running (it did: an
            # endpoint this code could not read left two gateways stepping for an hour)
            self.stop()
            raise

    def output(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            code = self.process.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait()
        self.log.close()
        return code


class Wire:
    """MORSE's socket protocol on a raw socket: one request at a time, its reply awaited."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT)
        self.reader = self.sock.makefile("rb")
        self.next_id = 1

    def close(self):
        self.reader.close()
        self.sock.close()

    def request(self, component, service, params=None):
        """(status, value): the reply to `<id> component service [params]`, value decoded
        from JSON (None when the reply has none)."""
        request_id = str(self.next_id)
        self.next_id += 1
        line = "%s %s %s" % (request_id, component, service)
        if params is not None:
            line += " " + json.dumps(params)
        self.sock.sendall(line.encode() + b"\n")
        while True:  # bounded: each readline waits at most TIMEOUT (the socket's timeout)
            reply = self.reader.readline().decode()
            if not reply:
                raise RuntimeError("connection closed waiting for " + line)
            parts = reply.rstrip("\n").split(" ", 2)
            if parts[0] == request_id:
                return parts[1], json.loads(parts[2]) if len(parts) > 2 else None

    def call(self, component, service, params=None):
        """The value of a request that must succeed."""
        status, value = self.request(component, service, params)
        if status != "SUCCESS":
            raise AssertionError("%s %s %s: %s %r" % (component, service, params, status, value))
        return value


def jsonrpc_call(port, method, params=None):
    """One JSON-RPC 2.0 request on its own connection; the response object."""
    with socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT) as sock:
        message = {"jsonrpc": "2.0", "id": 1, "method": method}
        if params is not None:
            message["params"] = params
        sock.sendall(json.dumps(message).encode() + b"\n")
        return json.loads(sock.makefile("rb").readline())


def object_position(wire, name):
    """[x, y, z] of a top-level body, from `simulation get_scene_objects`
    ({name: [children, position, orientation]})."""
    return wire.call("simulation", "get_scene_objects")[name][1]


def decode_png(text):
    """(width, height, bit depth, colour type, rows): a camera's base64 PNG, every chunk's
    CRC checked, IDAT inflated; rows without their filter byte (the cameras write None)."""
    data = base64.b64decode(text)
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "no PNG signature"
    at, packed, header = 8, b"", None
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + length]
        (crc,) = struct.unpack(">I", data[at + 8 + length:at + 12 + length])
        assert zlib.crc32(kind + body) == crc, "bad CRC in %s" % kind
        if kind == b"IHDR":
            header = struct.unpack(">IIBB", body[:10])
        elif kind == b"IDAT":
            packed += body
        at += 12 + length
    width, height, depth, colour = header
    row = width * (3 if colour == 2 else 1) * depth // 8
    raw = zlib.decompress(packed)
    assert len(raw) == (row + 1) * height
    rows = [raw[y * (row + 1) + 1:(y + 1) * (row + 1)] for y in range(height)]
    assert all(raw[y * (row + 1)] == 0 for y in range(height))
    return width, height, depth, colour, rows


class ShippedConfigsTest(unittest.TestCase):
    def test_both_configs_pass_check_as_shipped(self):
        for name in ("arm.json", "rover.json"):
            path = os.path.join(ARGS.source_dir, "config", name)
            check = subprocess.run([ARGS.simgate, "check", path], capture_output=True, text=True,
                                   timeout=TIMEOUT)
            self.assertEqual(check.returncode, 0, check.stdout + check.stderr)
            self.assertIn("OK", check.stdout)
            with open(path) as f:
                scene = json.load(f)["scene"]["mjcf"]
            # relative to the config: the installed share/simgate/config works as the source tree
            self.assertFalse(os.path.isabs(scene), scene)


class ArmSceneTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.TemporaryDirectory(prefix="simgate-e2e-arm-")
        cls.gateway = Gateway("arm.json", cls.workdir.name)
        cls.wire = Wire(cls.gateway.ports["socket"])
        cls.simu = pymorse.Morse(host="127.0.0.1", port=cls.gateway.ports["socket"])

    @classmethod
    def tearDownClass(cls):
        # not `with pymorse.Morse()`: its close() with wait_publishers=True raises a
        # TypeError in Debian's pymorse (its proxies' __getattribute__)
        cls.simu.close(wait_publishers=False)
        cls.wire.close()
        code = cls.gateway.stop()
        cls.workdir.cleanup()
        if code != 0:
            raise RuntimeError("gateway exited with %d" % code)

    def setUp(self):
        self.assertEqual(self.wire.call("simulation", "reset_objects"), "Objects restored to initial position")

    def state(self):
        return self.wire.call("arm.armature_pose", "get_state")

    def test_at_rest_nothing_drifts_and_the_wrist_carries_the_hand(self):
        self.wire.call("time", "sleep", [0.5])  # the objects settle on the table (< 1 mm)
        objects = ("box", "cylinder", "block")
        before = {name: object_position(self.wire, name) for name in objects}
        self.wire.call("time", "sleep", [10.0])
        for name in objects:
            after = object_position(self.wire, name)
            self.assertLess(math.dist(before[name], after), 1e-4, name)
            self.assertGreater(after[2], TABLE_TOP, name)  # still on the table
        for joint, state in self.state().items():
            self.assertLess(abs(state["position"]), 1e-3, joint)
            self.assertLess(abs(state["velocity"]), 1e-3, joint)
        sensors = self.wire.call("arm.sensors", "get_local_data")
        # the arm points straight up: the wrist holds the hand's weight along its z axis
        force = sensors["wrist_force"]
        self.assertAlmostEqual(force[2], HAND_MASS * GRAVITY, delta=0.01)
        self.assertLess(math.hypot(force[0], force[1]), 0.01)
        self.assertEqual(sensors["left_touch"], 0.0)
        self.assertEqual(sensors["right_touch"], 0.0)

    def test_rotate_joints_of_two_joints_reaches_both_targets(self):
        targets = {"shoulder_pan": 0.5, "elbow": -0.6}
        self.assertEqual(self.wire.request("arm.armature", "rotate_joints", [targets]), ("SUCCESS", None))
        # arrived means within angle_tolerance (0.01 rad); the servos then settle closer
        self.wire.call("time", "sleep", [0.5])
        state = self.state()
        sensors = self.wire.call("arm.sensors", "get_local_data")
        for joint, target in targets.items():
            self.assertAlmostEqual(state[joint]["position"], target, delta=0.01, msg=joint)
            self.assertLess(abs(state[joint]["velocity"]), 0.01, joint)
            self.assertAlmostEqual(sensors[joint + "_pos"], state[joint]["position"], delta=1e-3, msg=joint)
        for joint in ("shoulder_lift", "forearm_roll", "wrist_pitch", "wrist_roll"):
            self.assertLess(abs(state[joint]["position"]), 0.01, joint)
        # the same positions through JSON-RPC
        reply = jsonrpc_call(self.gateway.ports["jsonrpc"], "arm.armature_pose.get_joint", ["elbow"])
        self.assertAlmostEqual(reply["result"], -0.6, delta=0.01)

    def test_the_gripper_closes_on_the_box_and_lifts_it(self):
        armature, gripper = self.simu.arm.armature, self.simu.arm.gripper
        grasp_z = TABLE_TOP + 0.04  # the fingertips 1.5 mm above the table
        armature.rotate_joints(arm_pitch_joints(BOX_X, grasp_z + 0.1)).result(timeout=TIMEOUT)
        armature.rotate_joints(arm_pitch_joints(BOX_X, grasp_z), 0.3).result(timeout=TIMEOUT)
        gripper.set_controls({"left_finger_servo": FINGER_CLOSED, "right_finger_servo": FINGER_CLOSED}).result(
            timeout=TIMEOUT)
        self.simu.sleep(1.0)
        sensors = self.simu.arm.sensors.get_local_data().result(timeout=TIMEOUT)
        self.assertGreater(sensors["left_touch"], 1.0)
        self.assertGreater(sensors["right_touch"], 1.0)
        state = self.simu.arm.armature_pose.get_state().result(timeout=TIMEOUT)
        for finger in ("left_finger", "right_finger"):
            # stopped at the box's side, short of closed
            self.assertAlmostEqual(state[finger]["position"], FINGER_OPEN_GAP_HALF - BOX_HALF, delta=0.003,
                                   msg=finger)
        box_before = object_position(self.wire, "box")
        armature.rotate_joints(arm_pitch_joints(BOX_X, grasp_z + 0.15), 0.3).result(timeout=TIMEOUT)
        box_after = object_position(self.wire, "box")
        self.assertGreater(box_after[2] - box_before[2], 0.12)
        self.assertLess(math.hypot(box_after[0] - BOX_X, box_after[1]), 0.02)
        sensors = self.simu.arm.sensors.get_local_data().result(timeout=TIMEOUT)
        self.assertGreater(sensors["left_touch"], 1.0)

    def test_a_finger_target_beyond_its_range_is_refused(self):
        status, message = self.wire.request("arm.gripper", "set_controls", [{"left_finger_servo": 0.05}])
        self.assertEqual(status, "FAILED")
        self.assertIn("left_finger_servo", message)
        self.assertIn("ctrlrange", message)
        self.assertEqual(self.wire.call("arm.gripper", "get_controls"),
                         {"left_finger_servo": 0.0, "right_finger_servo": 0.0})
        with self.assertRaises(MorseServiceFailed):
            self.simu.arm.armature.rotate_joints({"elbow": float("nan")}).result(timeout=TIMEOUT)
        self.wire.call("time", "sleep", [0.1])
        for joint, state in self.state().items():
            self.assertTrue(math.isfinite(state["position"]), joint)


# config/scenes/rover_room.xml: the rover's laser site is 0.1 m ahead of its body origin;
# the walls' inner faces are at x = ±3, y = ±2.5; the north wall has a door from x = 1 to 2
LASER_AHEAD = 0.1
EAST_WALL, SIDE_WALL = 3.0, 2.5
RAYS = 271  # 270° every 1°, both ends included


class RoverSceneTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.TemporaryDirectory(prefix="simgate-e2e-rover-")
        cls.gateway = Gateway("rover.json", cls.workdir.name)
        cls.wire = Wire(cls.gateway.ports["socket"])
        cls.simu = pymorse.Morse(host="127.0.0.1", port=cls.gateway.ports["socket"])

    @classmethod
    def tearDownClass(cls):
        cls.simu.close(wait_publishers=False)
        cls.wire.close()
        code = cls.gateway.stop()
        cls.workdir.cleanup()
        if code != 0:
            raise RuntimeError("gateway exited with %d" % code)

    def setUp(self):
        self.assertEqual(self.wire.call("simulation", "reset_objects"), "Objects restored to initial position")
        self.wire.call("time", "sleep", [0.2])

    def scan(self):
        return self.wire.call("rover.laser", "get_local_data")

    def test_the_laser_sees_the_walls_where_they_are(self):
        properties = self.wire.call("rover.laser", "get_properties")["properties"]
        self.assertEqual(properties["ray_count"], RAYS)
        scan = self.scan()
        ranges, points = scan["range_list"], scan["point_list"]
        self.assertEqual(len(ranges), RAYS)
        self.assertEqual(len(points), RAYS)
        ahead, right, left = RAYS // 2, RAYS // 2 - 90, RAYS // 2 + 90  # 0°, -90°, +90°
        self.assertAlmostEqual(ranges[ahead], EAST_WALL - LASER_AHEAD, delta=0.01)
        self.assertAlmostEqual(points[ahead][0], EAST_WALL - LASER_AHEAD, delta=0.01)
        self.assertAlmostEqual(ranges[right], SIDE_WALL, delta=0.01)
        self.assertAlmostEqual(ranges[left], SIDE_WALL, delta=0.01)
        # +60°: from (0.1, 0), the ray crosses y = 2.5 at x = 1.54, in the door: nothing within 10 m
        self.assertEqual(ranges[ahead + 60], 10.0)
        self.assertEqual(points[ahead + 60], [0.0, 0.0, 0.0])
        # teleported 1 m forward, the east wall is 1 m nearer
        self.wire.call("rover.teleport", "translate", [1.0, 0.0, 0.0])
        self.wire.call("time", "sleep", [0.2])
        self.assertAlmostEqual(self.scan()["range_list"][ahead], EAST_WALL - LASER_AHEAD - 1.0, delta=0.01)

    def test_the_depth_camera_sees_the_east_wall_where_the_laser_does(self):
        record = self.wire.call("rover.depth", "get_image")
        self.assertEqual(record["depth_unit"], "mm")
        width, height, depth, colour, rows = decode_png(record["image"])
        self.assertEqual((width, height, depth, colour), (160, 120, 16, 0))
        # the centre pixel looks along the laser's 0° ray, at the laser's height
        centre = rows[height // 2]
        millimetres = (centre[width] << 8) | centre[width + 1]
        self.assertAlmostEqual(millimetres / 1000.0, EAST_WALL - LASER_AHEAD, delta=0.01)
        self.assertAlmostEqual(millimetres / 1000.0, self.scan()["range_list"][RAYS // 2], delta=0.01)

    def test_a_capture_returns_its_images_as_pngs(self):
        images = self.wire.call("rover.camera", "capture", [2])
        self.assertEqual(len(images), 2)
        # 10 images per simulated second
        self.assertAlmostEqual(images[1]["timestamp"] - images[0]["timestamp"], 0.1, delta=0.003)
        for image in images:
            width, height, depth, colour, rows = decode_png(image["image"])
            self.assertEqual((width, height, depth, colour), (320, 240, 8, 2))
            self.assertEqual(image["intrinsic_matrix"][0][2], 160.0)

    def test_the_overhead_camera_sees_the_room_from_above(self):
        # rover.overhead: a video_camera on the scene's MJCF camera "overhead", 6 m above the
        # room's centre looking down, east right, north up (f = 257 px): crate_2 (0.6 0.4 0.1,
        # at (-1.6, 1.4), which the other tests do not push) orange up left
        record = self.wire.call("rover.overhead", "get_image")
        width, height, depth, colour, rows = decode_png(record["image"])
        self.assertEqual((width, height, depth, colour), (320, 240, 8, 2))
        r, g, b = rows[56][3 * 86:3 * 86 + 3]
        self.assertTrue(r > 120 and r > g + 30 and g > b + 50, (r, g, b))
        # the floor at (-0.9, 0.7): grey-green, its blue about its red
        r, g, b = rows[90][3 * 120:3 * 120 + 3]
        self.assertLess(abs(r - b), 40, (r, g, b))
        properties = self.wire.call("rover.overhead", "get_properties")["properties"]
        self.assertEqual(properties["cam_fovy"], 50.0)

    def test_a_snapshot_pictures_the_room_as_the_readme_shows_it(self):
        # simulation get_snapshot (docs/world/snapshot.md): the free view, the asked size
        record = self.wire.call("simulation", "get_snapshot", {"width": 320, "height": 240})
        self.assertEqual(record["camera"], "free")
        width, height, depth, colour, rows = decode_png(record["image"])
        self.assertEqual((width, height, depth, colour), (320, 240, 8, 2))
        # the room's walls, floor, crates and rover: many colours, not one
        pixels = {bytes(row[x:x + 3]) for row in rows[::8] for x in range(0, 3 * width, 24)}
        self.assertGreater(len(pixels), 10)
        # an unknown camera is refused, listing the scene's cameras
        status, message = self.wire.request("simulation", "get_snapshot", {"camera": "nope"})
        self.assertEqual(status, "FAILED")
        self.assertIn("camera 'nope' is not an MJCF camera", message)

    def test_the_imu_reads_gravity_at_rest(self):
        imu = self.wire.call("rover.imu", "get_local_data")
        acceleration = imu["linear_acceleration"]
        self.assertAlmostEqual(acceleration[2], GRAVITY, delta=0.02)
        self.assertLess(math.hypot(acceleration[0], acceleration[1]), 0.02)
        self.assertLess(max(abs(w) for w in imu["angular_velocity"]), 1e-3)

    def test_a_goto_arrives_and_the_odometry_matches_the_pose(self):
        arrival = self.simu.rover.waypoint.goto(2.0, -0.5, 0.0, 0.2, 0.5)
        self.assertEqual(arrival.result(timeout=TIMEOUT), "Arrived")
        self.simu.sleep(1.0)  # the rover stops
        pose = self.simu.rover.pose.get_local_data().result(timeout=TIMEOUT)
        odometry = self.simu.rover.odometry.get_local_data().result(timeout=TIMEOUT)
        self.assertLess(math.hypot(pose["x"] - 2.0, pose["y"] + 0.5), 0.25)
        # the rover starts at the origin, facing +x: its start frame is the world's
        for key in ("x", "y", "yaw"):
            self.assertAlmostEqual(odometry[key], pose[key], delta=1e-3, msg=key)
        self.assertLess(abs(odometry["vx"]), 0.01)

    def test_driving_then_stopping_the_odometry_integrates_the_path(self):
        self.wire.call("rover.motion", "set_speed", [0.4, 0.3])
        self.wire.call("time", "sleep", [2.0])
        self.wire.call("rover.motion", "stop")
        self.wire.call("time", "sleep", [1.0])
        pose = self.wire.call("rover.pose", "get_local_data")
        odometry = self.wire.call("rover.odometry", "get_local_data")
        self.assertGreater(pose["x"], 0.4)
        self.assertGreater(pose["yaw"], 0.3)
        for key in ("x", "y", "yaw"):
            self.assertAlmostEqual(odometry[key], pose[key], delta=1e-3, msg=key)

    def test_proximity_finds_the_crates(self):
        near = self.wire.call("rover.proximity", "get_local_data")["near_objects"]
        self.assertEqual(set(near), {"crate_1", "crate_2"})
        # from the rover's origin (0, 0, 0.1) to crate_1's centre (1.5, -1.3, 0.2)
        self.assertAlmostEqual(near["crate_1"], math.sqrt(1.5 ** 2 + 1.3 ** 2 + 0.1 ** 2), delta=0.01)


def main():
    global ARGS
    parser = argparse.ArgumentParser()
    parser.add_argument("--simgate", required=True)
    parser.add_argument("--source-dir", required=True)
    ARGS, rest = parser.parse_known_args()
    ARGS.source_dir = os.path.abspath(ARGS.source_dir)
    logging.basicConfig(level=logging.WARNING)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
