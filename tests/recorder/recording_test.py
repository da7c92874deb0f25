#!/usr/bin/python3
"""E2E: the flight recorder (issue #39) through the real transports and the real command line.

`simgate run --record FILE` serves the demo (paused) on the socket, JSON-RPC and WebSocket
transports; a scripted 10 000-step session drives it: `simulation step 250` through the MORSE
socket protocol, set_speed and stream commands (rpc.publish) through JSON-RPC, teleport
rotations through WebSocket (`simgate call --transport websocket`). `simgate replay FILE
--verify` then re-runs it with every step's state equal to the recorded one (exit 0). A
recording killed with SIGKILL in the middle is still read and replayed up to its last whole
chunk. With --record-dir, a client records over the wire (start_recording /
stop_recording); without it, or with a name that is a path, it is refused. A file that is no
recording is exit 2 naming what is wrong. Every wait is bounded.
"""
import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import unittest

ARGS = None
TIMEOUT = 60


class Gateway:
    """`simgate run CONFIG [extra]` on ephemeral ports, its endpoints read from --endpoints-file."""

    def __init__(self, workdir, name, extra):
        with open(os.path.join(ARGS.source_dir, "config/all-transports.json")) as f:
            config = json.load(f)
        config["scene"]["mjcf"] = os.path.join(ARGS.source_dir, "config/scenes/demo.xml")
        config["scene"]["start_paused"] = True
        del config["transports"]["dds"]
        config["transports"]["socket"]["options"]["port"] = 0
        config["transports"]["jsonrpc"]["options"]["port"] = 0
        config["transports"]["websocket"] = {"plugin": "websocket",
                                             "options": {"host": "127.0.0.1", "port": 0}}
        config["streams"] = {"robot.pose": ["socket", "jsonrpc"], "robot.motion": ["jsonrpc"]}
        del config["services"]  # every transport serves every component
        config["log_level"] = "warning"
        path = os.path.join(workdir, name + ".json")
        with open(path, "w") as f:
            json.dump(config, f)
        endpoints = os.path.join(workdir, name + "-endpoints.json")
        self.log = open(os.path.join(workdir, name + ".log"), "w+")
        self.process = subprocess.Popen([ARGS.simgate, "run", path, "--endpoints-file", endpoints] + extra,
                                        stdout=self.log, stderr=subprocess.STDOUT)
        try:
            deadline = time.monotonic() + TIMEOUT
            while not os.path.exists(endpoints):
                if self.process.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("simgate run did not start:\n" + self.output())
                time.sleep(0.01)  # polling for a file the child writes; bounded by the deadline
            with open(endpoints) as f:
                ports = json.load(f)
            # "tcp://127.0.0.1:4000", "ws://127.0.0.1:8090/"
            self.ports = {name: int(urls[0].rstrip("/").rsplit(":", 1)[1]) for name, urls in ports.items()}
        except BaseException:
            # a gateway that started half way is not left running
            self.process.kill()
            self.process.wait()
            self.log.close()
            raise

    def kill_if_running(self):
        """A test that failed before it stopped the gateway does not leave it running."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()

    def output(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self, sig=signal.SIGTERM):
        self.process.send_signal(sig)
        try:
            code = self.process.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait()
        self.final_output = self.output()
        self.log.close()
        return code


class Lines:
    """One TCP connection speaking lines, every read with a deadline."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT)
        self.reader = self.sock.makefile("rb")
        self.next_id = 0

    def ask(self, line):
        self.sock.sendall((line + "\n").encode())
        return self.reader.readline().decode().rstrip("\n")

    def morse(self, component, service, params=None):
        """A MORSE socket request; returns (status, value)."""
        self.next_id += 1
        rid = "r%d" % self.next_id
        line = "%s %s %s" % (rid, component, service)
        if params is not None:
            line += " " + json.dumps(params)
        reply = self.ask(line)
        got_id, status, *rest = reply.split(" ", 2)
        assert got_id == rid, reply
        return status, json.loads(rest[0]) if rest else None

    def rpc(self, method, params=None):
        """A JSON-RPC request; returns the response object."""
        self.next_id += 1
        request = {"jsonrpc": "2.0", "method": method, "id": self.next_id}
        if params is not None:
            request["params"] = params
        return json.loads(self.ask(json.dumps(request)))

    def close(self):
        self.reader.close()
        self.sock.close()


def websocket_call(port, component, service, *args):
    """`simgate call --transport websocket`: the WebSocket transport's JSON-RPC."""
    done = subprocess.run([ARGS.simgate, "call", "--transport", "websocket", "--port", str(port),
                           "--timeout", "30", component, service] + [str(a) for a in args],
                          capture_output=True, text=True, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr
    return done.stdout


def read_with_npm(path):
    """@mcap/core's indexed reader (read_recording.js); None when npm's packages are missing."""
    done = subprocess.run(["node", os.path.join(os.path.dirname(__file__), "read_recording.js"), path],
                          capture_output=True, text=True, timeout=TIMEOUT)
    if done.returncode == 77:
        return None
    assert done.returncode == 0, done.stderr + done.stdout
    return json.loads(done.stdout)


def read_with_pypi(path):
    """PyPI's mcap reader, CRCs checked: {topic: messages}; None when it is not installed."""
    if not ARGS.mcap_pythonpath or not os.path.isdir(ARGS.mcap_pythonpath):
        return None
    if ARGS.mcap_pythonpath not in sys.path:
        sys.path.insert(0, ARGS.mcap_pythonpath)
    from mcap.reader import make_reader  # noqa: E402 (where the test's scripts installed it)
    topics = {}
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[])
        for _schema, channel, _message in reader.iter_messages():
            topics[channel.topic] = topics.get(channel.topic, 0) + 1
    return topics


def replay(path, *extra):
    done = subprocess.run([ARGS.simgate, "replay", path, "--json"] + list(extra),
                          capture_output=True, text=True, timeout=300)
    report = json.loads(done.stdout) if done.returncode in (0, 1) and done.stdout.strip() else None
    return done.returncode, report, done.stderr


class RecordingTest(unittest.TestCase):
    def setUp(self):
        self.workdir = tempfile.TemporaryDirectory()

    def tearDown(self):
        self.workdir.cleanup()

    def test_a_session_from_three_transports_replays_bit_for_bit(self):
        path = os.path.join(self.workdir.name, "session.mcap")
        gateway = Gateway(self.workdir.name, "session", ["--record", path])
        self.addCleanup(gateway.kill_if_running)
        sock, rpc = Lines(gateway.ports["socket"]), Lines(gateway.ports["jsonrpc"])
        try:
            steps, round_ = 0, 0
            while steps < 10000:
                status, value = sock.morse("simulation", "step", [250])
                self.assertEqual(status, "SUCCESS", value)
                steps += 250
                reply = rpc.rpc("robot.motion.set_speed", {"v": 0.2 + 0.01 * round_, "w": 0.3 - 0.02 * round_})
                self.assertIn("result", reply, reply)
                if round_ % 3 == 1:
                    reply = rpc.rpc("rpc.publish", {"component": "robot.motion",
                                                    "data": {"v": -0.2, "w": 0.05 * round_}})
                    self.assertIn("result", reply, reply)
                if round_ % 5 == 2:
                    websocket_call(gateway.ports["websocket"], "robot.teleport", "rotate", 0, 0, 0.1 * round_)
                round_ += 1
            # a client without --record-dir is not let record
            status, value = sock.morse("simulation", "start_recording", ["elsewhere"])
            self.assertEqual(status, "FAILED")
            self.assertIn("--record-dir", value)
        finally:
            sock.close()
            rpc.close()
            self.assertEqual(gateway.stop(), 0, gateway.final_output)
        code, report, err = replay(path, "--verify")
        self.assertEqual(code, 0, (report, err))
        self.assertIsNone(report["mismatch"])
        self.assertTrue(report["complete"])
        self.assertEqual(report["steps"], 10000)
        self.assertEqual(report["steps_compared"], 10000)
        self.assertEqual(report["outcomes_differing"], 0)
        # the 40 `simulation step`s and the refused start_recording: they act on the loop
        self.assertEqual(report["inputs_skipped"], 41)
        self.assertGreaterEqual(report["inputs_applied"], 40 + 13 + 8)
        # two readers nobody on the team wrote read it, CRCs checked
        for name, topics in (("npm @mcap/core", (read_with_npm(path) or {}).get("topics")),
                             ("PyPI mcap", read_with_pypi(path))):
            if topics is None:
                print("SKIP: %s is not installed" % name)
                continue
            self.assertEqual(topics["/simgate/initial_state"], 1, name)
            self.assertEqual(topics["/simgate/state_hashes"], 100, name)  # 10 000 steps, 100 a block
            self.assertGreaterEqual(topics["/simgate/inputs"], 40 + 40 + 13 + 8 + 1, name)
            self.assertGreater(topics["/robot/pose"], 100, name)

    def test_a_recording_killed_with_sigkill_is_read_up_to_its_last_whole_chunk(self):
        path = os.path.join(self.workdir.name, "killed.mcap")
        gateway = Gateway(self.workdir.name, "killed", ["--record", path])
        self.addCleanup(gateway.kill_if_running)
        sock = Lines(gateway.ports["socket"])
        try:
            for i in range(8):
                self.assertEqual(sock.morse("robot.motion", "set_speed", [0.3, 0.1 * i])[0], "SUCCESS")
                self.assertEqual(sock.morse("simulation", "step", [100])[0], "SUCCESS")
            time.sleep(1.5)  # the writer hands what it has to the file every second
        finally:
            sock.close()
            gateway.stop(signal.SIGKILL)
        code, report, err = replay(path, "--verify")
        self.assertEqual(code, 0, (report, err))
        self.assertFalse(report["complete"])
        self.assertIsNone(report["mismatch"])
        self.assertEqual(report["steps"], 800)

    def test_a_client_records_over_the_wire_into_the_record_dir(self):
        record_dir = os.path.join(self.workdir.name, "recordings")
        os.mkdir(record_dir)
        gateway = Gateway(self.workdir.name, "wire", ["--record-dir", record_dir])
        self.addCleanup(gateway.kill_if_running)
        rpc = Lines(gateway.ports["jsonrpc"])
        try:
            bad = rpc.rpc("simulation.start_recording", {"name": "../outside"})
            self.assertIn("error", bad)
            self.assertIn("not a file name", bad["error"]["message"])
            started = rpc.rpc("simulation.start_recording", {"name": "wire"})
            self.assertTrue(started["result"]["recording"], started)
            again = rpc.rpc("simulation.start_recording", {"name": "again"})
            self.assertIn("already recording", again["error"]["message"])
            self.assertIn("result", rpc.rpc("robot.motion.set_speed", [0.4, 0.2]))
            self.assertIn("result", rpc.rpc("simulation.step", [300]))
            stopped = rpc.rpc("simulation.stop_recording")
            self.assertEqual(stopped["result"]["steps"], 300, stopped)
            self.assertIsNone(stopped["result"]["error"])
            self.assertFalse(rpc.rpc("simulation.get_recording_status")["result"]["recording"])
            for name in ("again1", "again2", "again3"):  # one after another, each closed whole
                self.assertTrue(rpc.rpc("simulation.start_recording", {"name": name})["result"]["recording"])
                self.assertIn("result", rpc.rpc("simulation.step", [10]))
                self.assertEqual(rpc.rpc("simulation.stop_recording")["result"]["steps"], 10)
        finally:
            rpc.close()
            self.assertEqual(gateway.stop(), 0, gateway.final_output)
        self.assertEqual(sorted(os.listdir(record_dir)), ["again1.mcap", "again2.mcap", "again3.mcap", "wire.mcap"])
        code, report, err = replay(os.path.join(record_dir, "wire.mcap"), "--verify")
        self.assertEqual(code, 0, (report, err))
        self.assertEqual(report["steps"], 300)
        self.served(os.path.join(record_dir, "wire.mcap"))

    def serve(self, path):
        """`simgate replay --serve` (as fast as it can) on ephemeral ports: (process, JSON-RPC
        Lines, log); stop() ends it."""
        endpoints = os.path.join(self.workdir.name, "served-endpoints.json")
        log = open(os.path.join(self.workdir.name, "served.log"), "w+")
        process = subprocess.Popen([ARGS.simgate, "replay", path, "--serve", "--realtime-factor", "max",
                                    "--endpoints-file", endpoints], stdout=log, stderr=subprocess.STDOUT)

        def stop():
            """SIGTERM: exit 0, the endpoints file removed; returns the log."""
            try:
                process.send_signal(signal.SIGTERM)
                self.assertEqual(process.wait(timeout=TIMEOUT), 0)
            finally:
                if process.poll() is None:
                    process.kill()
                    process.wait()
                log.seek(0)
                output = log.read()
                log.close()
            self.assertFalse(os.path.exists(endpoints))
            return output

        try:
            deadline = time.monotonic() + TIMEOUT
            while not os.path.exists(endpoints):
                self.assertIsNone(process.poll(), "simgate replay --serve ended early")
                self.assertLess(time.monotonic(), deadline, "simgate replay --serve did not start")
                time.sleep(0.01)  # polling for a file the child writes; bounded by the deadline
            with open(endpoints) as f:
                url = json.load(f)["jsonrpc"][0]
            return Lines(int(url.rsplit(":", 1)[1])), stop
        except BaseException:
            stop()
            raise

    def at_the_end(self, rpc, steps):
        """Waits (bounded) for the served replay to reach the end of its `steps` steps, paused."""
        deadline = time.monotonic() + TIMEOUT
        while True:
            state = rpc.rpc("simulation.get_simulation_state")["result"]
            if state["state"] == "paused" and rpc.rpc("simulation.get_replay_status")["result"]["step"] >= steps:
                return state
            self.assertLess(time.monotonic(), deadline, state)
            time.sleep(0.01)  # polling the served run; bounded by the deadline

    def served(self, path):
        """`simgate replay --serve`: the recording through its deployment's transports, a client
        watching; at its end the last state is served, paused, until SIGTERM."""
        rpc, stop = self.serve(path)
        try:
            self.assertEqual(self.at_the_end(rpc, 300)["steps"], 300)
            pose = rpc.rpc("robot.pose.get_local_data")["result"]
            self.assertGreater(pose["x"], 0.1)  # the recorded set_speed drove it
            stepped = rpc.rpc("simulation.step", [5])["result"]  # a client may go on
            self.assertEqual(stepped["steps_done"], 5)
        finally:
            rpc.close()
            output = stop()
        self.assertIn("replayed 300 steps", output)

    def test_a_served_replay_seeks_back_and_forth_with_the_states_it_saved(self):
        """`simulation seek` in a served replay: back to the recording's start and forward again,
        the recorded run's own states each time, the states the recording saved and restored
        told apart from those saved before the seek back."""
        path = os.path.join(self.workdir.name, "seek.mcap")
        gateway = Gateway(self.workdir.name, "seek", ["--record", path])
        self.addCleanup(gateway.kill_if_running)
        rpc = Lines(gateway.ports["jsonrpc"])
        try:
            def ok(method, params=None):
                reply = rpc.rpc(method, params)
                self.assertIn("result", reply, (method, reply))
                return reply["result"]
            ok("robot.motion.set_speed", [0.5, 0.3])
            ok("simulation.step", [100])
            saved = ok("simulation.save_state")
            ok("simulation.step", [100])
            ok("robot.motion.set_speed", [0.2, -0.4])
            ok("simulation.step", [100])
            ok("simulation.restore_state", [saved])  # the robot back at step 100's pose
            ok("robot.motion.set_speed", [0.4, 0.6])
            ok("simulation.step", [100])
            ok("simulation.drop_state", [saved])
            ok("simulation.save_state")
            ok("simulation.step", [100])
        finally:
            rpc.close()
            self.assertEqual(gateway.stop(), 0, gateway.final_output)

        rpc, stop = self.serve(path)
        try:
            self.at_the_end(rpc, 500)
            end_pose = rpc.rpc("robot.pose.get_local_data")["result"]
            for step in (150, 350, 50):
                reply = rpc.rpc("simulation.seek", {"step": step})
                self.assertEqual(reply["result"]["step"], step, reply)
                status = rpc.rpc("simulation.get_replay_status")["result"]
                self.assertEqual(status["step"], step, status)
            # by time: the recording's time went back at step 300 (the restore): its end is
            # 0.6 s, and 0.3 s is first reached at step 150
            status = rpc.rpc("simulation.get_replay_status")["result"]
            self.assertAlmostEqual(status["end_time"], 0.6, places=9)
            self.assertEqual(rpc.rpc("simulation.seek", {"sim_time": 0.3})["result"]["step"], 150)
            self.assertEqual(rpc.rpc("simulation.seek", {"sim_time": 0.0})["result"]["step"], 0)
            self.assertEqual(rpc.rpc("simulation.seek", {"step": 10 ** 9})["result"]["step"], 500)
            status = rpc.rpc("simulation.get_replay_status")["result"]
            self.assertIsNone(status["departed_at"], status)  # every step the recorded one
            self.assertEqual(rpc.rpc("robot.pose.get_local_data")["result"], end_pose)
            self.assertEqual(len(rpc.rpc("simulation.list_states")["result"]), 1)  # the last save only
            bad = rpc.rpc("simulation.seek", {"step": 3, "sim_time": 1.0})
            self.assertIn("one of them", bad["error"]["message"])
        finally:
            rpc.close()
            stop()

    def test_a_file_that_is_no_recording_is_exit_2_naming_what_is_wrong(self):
        text = os.path.join(self.workdir.name, "notes.mcap")
        with open(text, "w") as f:
            f.write("these are not the droids\n")
        done = subprocess.run([ARGS.simgate, "replay", text], capture_output=True, text=True, timeout=TIMEOUT)
        self.assertEqual(done.returncode, 2)
        self.assertIn("not an MCAP file", done.stderr)
        done = subprocess.run([ARGS.simgate, "replay", os.path.join(self.workdir.name, "missing.mcap")],
                              capture_output=True, text=True, timeout=TIMEOUT)
        self.assertEqual(done.returncode, 2)
        self.assertIn("missing.mcap", done.stderr)


def main():
    global ARGS
    parser = argparse.ArgumentParser()
    parser.add_argument("--simgate", required=True)
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--mcap-pythonpath", default="", help="where PyPI's mcap is installed")
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
