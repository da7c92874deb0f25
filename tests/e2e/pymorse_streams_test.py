#!/usr/bin/python3
"""E2E: MORSE's socket datastreams (issue #21) with MORSE's own client, Debian's pymorse.

Starts `simgate run` on the demo deployment (whose robot.pose and robot.motion stream on
the socket transport; every port ephemeral here, pymorse asks `simulation get_stream_port`
for them as it does of MORSE) and uses pymorse's stream API as MORSE users do:
`simu.streams()`, `simu.robot.pose.get()`, `last()`, `subscribe(cb)` / `unsubscribe(cb)`,
and `simu.robot.motion.publish({"v": 1, "w": 0})` driving the robot. Every wait is bounded.
"""
import argparse
import logging
import sys
import tempfile
import threading
import unittest
import warnings

warnings.simplefilter("ignore", DeprecationWarning)  # asyncore/asynchat on Python 3.11
import pymorse  # noqa: E402

from pymorse_test import TIMEOUT, Gateway  # noqa: E402  (the gateway child process, beside this file)

ARGS = None


class PymorseStreamsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.TemporaryDirectory(prefix="simgate-e2e-streams-")
        cls.gateway = Gateway(ARGS.simgate, ARGS.source_dir, cls.workdir.name)
        cls.simu = pymorse.Morse(host="127.0.0.1", port=cls.gateway.port)  # asks every stream's port

    @classmethod
    def tearDownClass(cls):
        # pymorse's close() with wait_publishers=True trips over its own proxies (known bug)
        cls.simu.close(wait_publishers=False)
        code = cls.gateway.stop()
        cls.workdir.cleanup()
        if code != 0:
            raise RuntimeError("gateway exited with %d" % code)

    def setUp(self):
        self.simu.robot.motion.publish({"v": 0, "w": 0})
        self.assertEqual(self.simu.reset(), "Objects restored to initial position")

    def pose(self):
        sample = self.simu.robot.pose.get(timeout=TIMEOUT)
        self.assertIsNotNone(sample, "no pose sample within %d s" % TIMEOUT)
        return sample

    def test_streams_lists_the_streamed_components(self):
        self.assertEqual(sorted(self.simu.streams()), ["robot.motion", "robot.pose"])
        ports = self.simu.rpc("simulation", "get_all_stream_ports")
        self.assertEqual(self.simu.get_stream_port("robot.pose"), ports["robot.pose"])
        with self.assertRaises(pymorse.MorseServiceFailed) as unavailable:
            self.simu.get_stream_port("robot.waypoint")
        self.assertEqual(str(unavailable.exception), "Stream unavailable for component robot.waypoint")

    def test_get_and_last_give_pose_samples(self):
        first = self.pose()
        for key in ("x", "y", "z", "roll", "pitch", "yaw", "timestamp"):
            self.assertIn(key, first)
        second = self.pose()
        self.assertGreater(second["timestamp"], first["timestamp"])
        # the last sample received (pymorse's last(n) gives the last one whatever n)
        for last in (self.simu.robot.pose.last(), self.simu.robot.pose.last(3)):
            self.assertIsInstance(last, dict)
            self.assertGreaterEqual(last["timestamp"], second["timestamp"])

    def test_subscribe_receives_samples_until_unsubscribed(self):
        received = []
        enough = threading.Event()

        def on_pose(sample):  # pymorse's poll thread
            received.append(sample)
            if len(received) >= 5:
                enough.set()

        self.simu.robot.pose.subscribe(on_pose)
        try:
            self.assertTrue(enough.wait(TIMEOUT), "%d samples within %d s" % (len(received), TIMEOUT))
        finally:
            self.simu.robot.pose.unsubscribe(on_pose)
        stamps = [s["timestamp"] for s in received]
        self.assertEqual(stamps, sorted(stamps))
        self.assertEqual(len(set(stamps)), len(stamps))
        # unsubscribed: later samples reach get(), not the callback
        count = len(received)
        self.pose()
        self.pose()
        self.assertEqual(len(received), count)

    def test_publish_drives_the_robot(self):
        x0 = self.pose()["x"]
        self.simu.robot.motion.publish({"v": 1, "w": 0})
        x = x0
        for _ in range(1000):  # 60 samples per simulated second: a few seconds at most
            x = self.pose()["x"]
            if x > x0 + 0.3:
                break
        self.assertGreater(x, x0 + 0.3)
        self.simu.robot.motion.publish({"v": 0, "w": 0})
        # the stream and the service see the same robot
        self.assertGreater(self.simu.robot.pose.get_local_data().result(timeout=TIMEOUT)["x"], x0 + 0.3)
        statistics = {s["component"]: s for s in self.simu.rpc("simulation", "get_stream_statistics")}
        self.assertGreaterEqual(statistics["robot.motion"]["commands"], 1)
        self.assertEqual(statistics["robot.motion"]["refused"], 0)


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
