#!/usr/bin/python3
"""E2E: pymorse (Debian's python3-morse-simulator) against a running simgate gateway.

Starts `simgate run` on a test config (the demo scene, socket transport and its datastreams
on ephemeral ports), reads the bound port from --endpoints-file, and drives the robot the
way MORSE users do:
connect (`simulation details`), sync calls, `goto` futures that complete when the robot
really arrives (pose checked), cancel -> preempted and the robot stops, a second goto
preempts the first, wrong arity -> TypeError, `time.sleep` (two scripts sleeping together, a
sleep left by a closed connection). A second gateway splits the components between two
socket transports: pymorse sees and acts on only those its transport serves (issue #17,
item 6). A third denies services on its socket transport (issue #17, access control):
pymorse connects, has no method for them, and calling them fails as for an unknown service.
Every wait is bounded.
"""
import argparse
import json
import logging
import math
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
import unittest
import warnings

warnings.simplefilter("ignore", DeprecationWarning)  # asyncore/asynchat on Python 3.11
import pymorse  # noqa: E402
from pymorse import MorseServiceFailed, MorseServicePreempted  # noqa: E402

ARGS = None
TIMEOUT = 60  # seconds, for any single wait


class Gateway:
    """A `simgate run` child process on ephemeral ports."""

    def __init__(self, simgate, source_dir, workdir, adapt=None):
        with open(os.path.join(source_dir, "config", "demo.json")) as f:
            config = json.load(f)
        config["scene"]["mjcf"] = os.path.join(source_dir, "config", "scenes", "demo.xml")
        config["scene"]["realtime_factor"] = 2.0
        config["transports"]["socket"]["options"]["port"] = 0
        config["transports"]["socket"]["options"]["stream_port"] = 0  # its datastreams too
        config["transports"]["websocket"]["options"]["port"] = 0  # the web app's
        config["transports"]["foxglove"]["options"]["port"] = 0
        config["transports"]["mcp"]["options"]["port"] = 0
        config["log_level"] = "warning"
        if adapt:
            adapt(config)
        self.config_path = os.path.join(workdir, "e2e.json")
        with open(self.config_path, "w") as f:
            json.dump(config, f)
        self.endpoints_path = os.path.join(workdir, "endpoints.json")
        self.log = open(os.path.join(workdir, "gateway.log"), "w+")
        self.process = subprocess.Popen(
            [simgate, "run", self.config_path, "--endpoints-file", self.endpoints_path],
            stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + TIMEOUT
        while not os.path.exists(self.endpoints_path):
            if self.process.poll() is not None or time.monotonic() > deadline:
                output = self.output()
                self.stop()  # (one that hangs is not left running)
                raise RuntimeError("gateway did not start:\n" + output)
            time.sleep(0.01)  # polling for a file the child writes; bounded by the deadline
        with open(self.endpoints_path) as f:
            endpoints = json.load(f)  # {"socket": ["tcp://127.0.0.1:PORT"], ...}
        # tcp://HOST:PORT, ws://HOST:PORT/, http://HOST:PORT/mcp
        self.ports = {name: int(re.match(r"\w+://[^/]*:(\d+)", e[0]).group(1)) for name, e in endpoints.items()}
        self.port = self.ports["socket"]

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


def read_line(sock):
    """One reply line from a raw socket (without its newline), however the bytes arrive."""
    data = b""
    while not data.endswith(b"\n"):
        chunk = sock.recv(1)
        if not chunk:
            break
        data += chunk
    return data.rstrip(b"\n")


class GatewayTestCase(unittest.TestCase):
    """A gateway of config/demo.json (changed by `adapt`) and pymorse connected to it, for
    the class's tests. Both are ended by class cleanups, which run even when setUpClass fails
    half-way (tearDownClass would not): a failed run leaves no gateway behind."""

    adapt = None  # staticmethod(config -> None) in a subclass

    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.TemporaryDirectory(prefix="simgate-e2e-")
        cls.addClassCleanup(cls.workdir.cleanup)
        cls.gateway = Gateway(ARGS.simgate, ARGS.source_dir, cls.workdir.name, cls.adapt)
        cls.addClassCleanup(cls.stop_gateway)
        cls.simu = pymorse.Morse(host="127.0.0.1", port=cls.gateway.port)  # sends `simulation details`
        # pymorse's close() with wait_publishers=True trips over its own proxies (known bug)
        cls.addClassCleanup(cls.simu.close, wait_publishers=False)  # (cleanups run last first)

    @classmethod
    def stop_gateway(cls):
        code = cls.gateway.stop()
        if code != 0:
            raise RuntimeError("gateway exited with %d" % code)


class PymorseTest(GatewayTestCase):

    def setUp(self):
        self.assertEqual(self.simu.reset(), "Objects restored to initial position")

    def pose(self):
        return self.simu.robot.pose.get_local_data().result(timeout=TIMEOUT)

    def wait_for_status(self, status):
        for _ in range(200):  # bounded: each call is one round trip
            if self.simu.robot.waypoint.get_status().result(timeout=TIMEOUT) == status:
                return
        self.fail("waypoint never reported " + status)

    # ---- connect and sync calls ----

    def test_connect_builds_proxies_from_details(self):
        self.assertTrue(hasattr(self.simu, "robot"))
        self.assertTrue(hasattr(self.simu.robot, "waypoint"))
        self.assertTrue(hasattr(self.simu.robot.waypoint, "goto"))
        self.assertTrue(hasattr(self.simu.human, "move"))

    def test_sync_rpc(self):
        self.assertEqual(self.simu.rpc("simulation", "list_robots"), ["robot", "human"])
        pose = self.pose()
        for key in ("x", "y", "z", "roll", "pitch", "yaw"):
            self.assertIn(key, pose)

    def test_set_speed_moves_the_robot(self):
        self.simu.robot.motion.set_speed(0.5, 0.0).result(timeout=TIMEOUT)
        self.simu.sleep(1.0)
        self.assertGreater(self.pose()["x"], 0.2)
        self.simu.robot.motion.stop().result(timeout=TIMEOUT)

    def test_human_refuses_negative_speed(self):
        error = self.simu.human.move(-1.0, 0.0).exception(timeout=TIMEOUT)
        self.assertIsInstance(error, MorseServiceFailed)
        self.assertIn("Our human cannot walk at negative speed!", str(error))

    # ---- async: goto ----

    def test_goto_completes_when_the_robot_arrives(self):
        future = self.simu.robot.waypoint.goto(1.5, 0.5, 0.0, 0.2, 1.0)
        self.assertFalse(future.done())
        self.assertEqual(future.result(timeout=TIMEOUT), "Arrived")
        pose = self.pose()
        self.assertLess(math.hypot(pose["x"] - 1.5, pose["y"] - 0.5), 0.3)
        self.assertEqual(self.simu.robot.waypoint.get_status().result(timeout=TIMEOUT), "Arrived")

    def test_cancel_preempts_and_the_robot_stops(self):
        future = self.simu.robot.waypoint.goto(20.0, 0.0, 0.0)
        self.wait_for_status("Transit")
        self.simu.sleep(0.5)
        self.assertTrue(future.running())
        future.cancel()
        self.assertIsInstance(future.exception(timeout=TIMEOUT), MorseServicePreempted)
        self.assertTrue(future.done())
        future.cancel()  # a second cancel of a finished request does nothing
        self.simu.sleep(1.0)  # braking
        x1 = self.pose()["x"]
        self.simu.sleep(1.0)
        self.assertAlmostEqual(self.pose()["x"], x1, delta=0.01)
        self.assertLess(x1, 5.0)

    def test_second_goto_preempts_the_first(self):
        first = self.simu.robot.waypoint.goto(20.0, 0.0, 0.0)
        self.wait_for_status("Transit")
        second = self.simu.robot.waypoint.goto(1.0, 0.0, 0.0, 0.3)
        self.assertIsInstance(first.exception(timeout=TIMEOUT), MorseServicePreempted)
        self.assertEqual(second.result(timeout=TIMEOUT), "Arrived")

    def test_stop_keeps_goto_pending_and_resume_finishes_it(self):
        future = self.simu.robot.waypoint.goto(1.5, 0.0, 0.0, 0.2)
        self.wait_for_status("Transit")
        self.assertEqual(self.simu.robot.waypoint.stop().result(timeout=TIMEOUT), "Stop")
        self.simu.sleep(0.5)
        self.assertTrue(future.running())
        self.assertEqual(self.simu.robot.waypoint.get_status().result(timeout=TIMEOUT), "Stop")
        self.assertEqual(self.simu.robot.waypoint.resume().result(timeout=TIMEOUT), "Transit")
        self.assertEqual(future.result(timeout=TIMEOUT), "Arrived")

    def test_object_services_through_pymorse(self):
        # MORSE's get_properties / set_property / get_configurations on every component
        waypoint = self.simu.robot.waypoint
        self.assertEqual(waypoint.get_properties().result(timeout=TIMEOUT)["properties"]["heading_gain"], 2.0)
        waypoint.set_property("heading_gain", 2.5).result(timeout=TIMEOUT)
        self.assertEqual(waypoint.get_properties().result(timeout=TIMEOUT)["properties"]["heading_gain"], 2.5)
        waypoint.set_property("heading_gain", 2.0).result(timeout=TIMEOUT)
        with self.assertRaises(MorseServiceFailed) as unknown:
            waypoint.set_property("no_such", 1.0).result(timeout=TIMEOUT)
        self.assertIn("no property 'no_such' in robot.waypoint", str(unknown.exception))
        configurations = self.simu.robot.pose.get_configurations().result(timeout=TIMEOUT)["configurations"]
        self.assertEqual(configurations["type"], "pose")
        for got, expected in zip(configurations["object_to_robot"]["rotation"], [1.0, 0.0, 0.0, 0.0]):
            self.assertAlmostEqual(got, expected, places=9)

    def test_entity_and_communication_services_through_pymorse(self):
        # MORSE's set_object_position returns None; the pose reads back as get_scene_objects'
        self.assertIsNone(self.simu.rpc("simulation", "set_object_position", "crate1", [-1.0, 1.0, 0.2]))
        position, orientation = self.simu.rpc("simulation", "get_object_pose", "crate1")
        self.assertAlmostEqual(position[0], -1.0, places=2)
        self.assertEqual(len(orientation), 4)
        # MORSE's communication service: the crate stands between the robot and the human
        distance, visible = self.simu.rpc("communication", "distance_and_view", "robot", "human")
        self.assertAlmostEqual(distance, 8 ** 0.5, places=1)
        self.assertFalse(visible)
        with self.assertRaises(MorseServiceFailed) as unknown:
            self.simu.rpc("communication", "distance_and_view", "robot", "nobody")
        self.assertEqual(str(unknown.exception), "nobody does not exist in the simulation ")
        # MORSE's communication_service_testing.py: no arguments -> MorseServiceFailed (MORSE
        # says "parameters expected", not "wrong # of parameters", which pymorse makes TypeError)
        with self.assertRaises(MorseServiceFailed):
            self.simu.rpc("communication", "distance_and_view")
        self.assertFalse(self.simu.rpc("simulation", "set_object_dynamics", "crate1", False))
        self.assertTrue(self.simu.rpc("simulation", "set_object_dynamics", "crate1", True))

    def test_wrong_arity_is_a_type_error(self):
        too_few = self.simu.robot.waypoint.goto(1.0)
        self.assertIsInstance(too_few.exception(timeout=TIMEOUT), TypeError)
        too_many = self.simu.robot.waypoint.goto(1.0, 2.0, 3.0, 0.5, 1.0, 7.0)
        self.assertIsInstance(too_many.exception(timeout=TIMEOUT), TypeError)
        with self.assertRaises(TypeError):
            self.simu.rpc("robot.motion", "set_speed", 1.0)

    # ---- the world (issue #19, docs/world/spawn.md) ----

    def test_spawn_and_delete_an_entity(self):
        ball = "<body><freejoint/><geom type='sphere' size='0.1' mass='1'/></body>"
        spawned = self.simu.rpc("simulation", "spawn_entity", "pyball", ball, [1.0, -1.0, 0.5])
        self.assertEqual(spawned["name"], "pyball")
        self.assertIn("pyball", self.simu.rpc("simulation", "get_scene_objects"))
        with self.assertRaises(MorseServiceFailed):
            self.simu.rpc("simulation", "spawn_entity", "pyball", ball, [1.0, -1.0, 0.5])
        self.simu.rpc("simulation", "delete_entity", "pyball")
        self.assertNotIn("pyball", self.simu.rpc("simulation", "get_scene_objects"))
        # the proxies pymorse built at connect still work
        self.assertIn("x", self.pose())

    # ---- time ----

    def test_sleep_waits_for_simulated_time(self):
        t0 = self.simu.time()
        self.simu.sleep(0.5)
        t1 = self.simu.time()
        self.assertGreaterEqual(t1 - t0, 0.5 - 1e-6)
        self.assertLess(t1 - t0, 5.0)

    def test_two_scripts_sleep_together(self):
        # each caller of `time sleep` gets its own sleep (it was one for the whole
        # simulation: the second caller FAILED "already running"). The other script speaks
        # the wire itself: closing a second pymorse.Morse stops the poll thread all of them
        # share (pymorse's close()).
        with socket.create_connection(("127.0.0.1", self.gateway.port), timeout=TIMEOUT) as other:
            other.sendall(b"s1 time sleep [0.5]\n")
            self.simu.sleep(0.5)
            self.assertEqual(read_line(other), b"s1 SUCCESS")

    def test_a_sleep_left_by_a_closed_connection_blocks_nobody(self):
        with socket.create_connection(("127.0.0.1", self.gateway.port), timeout=TIMEOUT) as gone:
            gone.sendall(b"1 time sleep [1000]\n")
            gone.sendall(b"2 time now\n")
            reply = read_line(gone)
            self.assertTrue(reply.startswith(b"2 SUCCESS"), reply)  # the sleep has started
        self.simu.sleep(0.2)


def split_services(config):
    """The demo with a second socket transport, `private`, that alone serves robot.waypoint
    and robot.teleport: pymorse connects to `socket`, which serves the rest."""
    config["transports"]["private"] = {"plugin": "socket", "options": {"port": 0}}
    config["services"] = {"default": ["socket"], "robot.waypoint": ["private"],
                          "robot.teleport": ["private"], "simulation": ["socket", "private"]}


class PymorseMappingBoundaryTest(GatewayTestCase):
    """Issue #17, item 6: the mapping is a boundary. pymorse still connects, sees only what
    its transport serves, and cannot act on the rest, which the other transport's clients
    still can."""

    adapt = staticmethod(split_services)

    def test_connect_builds_proxies_of_served_components_only(self):
        # a pymorse Robot is a dict of its components and attributes (its __getattr__ raises
        # KeyError, not AttributeError)
        self.assertIn("motion", self.simu.robot)
        self.assertIn("pose", self.simu.robot)
        self.assertNotIn("waypoint", self.simu.robot)
        self.assertNotIn("teleport", self.simu.robot)
        self.assertTrue(hasattr(self.simu.human, "move"))
        self.simu.robot.motion.set_speed(0.0, 0.0).result(timeout=TIMEOUT)

    def test_an_unserved_component_cannot_be_deactivated_and_looks_missing(self):
        with self.assertRaises(MorseServiceFailed) as unserved:
            self.simu.rpc("simulation", "deactivate", "robot.waypoint")
        self.assertIn("Component 'robot.waypoint' not found. Can't deactivate", str(unserved.exception))
        with self.assertRaises(MorseServiceFailed) as missing:
            self.simu.rpc("simulation", "deactivate", "robot.nowhere")
        self.assertEqual(str(unserved.exception).replace("robot.waypoint", "X"),
                         str(missing.exception).replace("robot.nowhere", "X"))
        # the transport that serves it still can
        with socket.create_connection(("127.0.0.1", self.gateway.ports["private"]), timeout=TIMEOUT) as private:
            private.sendall(b'1 simulation deactivate ["robot.waypoint"]\n')
            self.assertEqual(read_line(private), b"1 SUCCESS")
            private.sendall(b'2 simulation activate ["robot.waypoint"]\n')
            self.assertEqual(read_line(private), b"2 SUCCESS")

    def test_list_services_shows_served_components_only(self):
        components = {s["component"] for s in self.simu.rpc("simulation", "list_services")}
        # the robot itself is served too: its object services (get_properties, ...)
        # communication goes with simulation
        self.assertEqual(components,
                         {"robot", "robot.motion", "robot.pose", "human", "simulation", "time", "communication"})


def has_method(proxy, name):
    """Whether a pymorse proxy has a method `name` (a Robot's __getattr__ raises KeyError)."""
    try:
        return callable(getattr(proxy, name))
    except (AttributeError, KeyError):
        return False


def deny_on_socket(config):
    """The demo whose socket transport denies the teleport, the human's move and
    `simulation quit` (issue #17, access control: allow/deny lists)."""
    config["transports"]["socket"]["deny"] = ["robot.teleport.*", "human.move", "simulation.quit"]


class PymorseAccessListsTest(GatewayTestCase):
    """Issue #17, access control: a socket transport's deny list. pymorse still connects,
    gets no proxy method for a denied service, and a denied call fails as an unknown service
    would, without running."""

    adapt = staticmethod(deny_on_socket)

    def test_connect_builds_no_method_for_a_denied_service(self):
        self.assertIn("teleport", self.simu.robot)  # served, with nothing to call
        self.assertFalse(has_method(self.simu.robot.teleport, "translate"))
        self.assertFalse(has_method(self.simu.human, "move"))
        self.assertTrue(has_method(self.simu.robot.motion, "set_speed"))
        self.simu.robot.motion.set_speed(0.0, 0.0).result(timeout=TIMEOUT)

    def test_a_denied_call_fails_as_an_unknown_service_and_does_not_run(self):
        with self.assertRaises(MorseServiceFailed) as denied:
            self.simu.rpc("simulation", "quit")
        self.assertIn("has not been registered", str(denied.exception))
        with self.assertRaises(MorseServiceFailed) as missing:
            self.simu.rpc("simulation", "quiz")
        self.assertEqual(str(denied.exception).replace("quit", "X"), str(missing.exception).replace("quiz", "X"))
        x = self.simu.robot.pose.get_local_data().result(timeout=TIMEOUT)["x"]
        with self.assertRaises(MorseServiceFailed):
            self.simu.rpc("robot.teleport", "translate", 5.0)
        self.assertLess(abs(self.simu.robot.pose.get_local_data().result(timeout=TIMEOUT)["x"] - x), 0.5)
        # the simulation did not quit
        self.assertGreater(self.simu.time(), 0)

    def test_list_services_shows_only_what_may_be_called(self):
        names = {s["component"] + "." + s["name"] for s in self.simu.rpc("simulation", "list_services")}
        self.assertIn("simulation.details", names)
        self.assertIn("robot.motion.set_speed", names)
        for denied in ("simulation.quit", "human.move", "robot.teleport.translate", "robot.teleport.rotate"):
            self.assertNotIn(denied, names)


def main():
    global ARGS
    parser = argparse.ArgumentParser()
    parser.add_argument("--simgate", required=True)
    parser.add_argument("--source-dir", required=True)
    ARGS, rest = parser.parse_known_args()
    logging.basicConfig(level=logging.WARNING)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
