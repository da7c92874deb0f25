#!/usr/bin/python3
"""E2E: issue #19's stepping and state services on every transport, in a real gateway.

`simgate run` serves the demo on the socket, JSON-RPC and DDS transports (ports 0, a
partition of its own, Cyclone on loopback with multicast off: the plugin's default), with
"scene": {"start_paused": true}. Through the MORSE socket protocol: the simulation starts
paused and stays so while served; step n answers the new time; bad counts are refused
naming n; save_state / restore_state / list_states / drop_state / reset / set_time_scale
answer as docs/world/*.md shows. Through JSON-RPC: the same services by name, with named
parameters, and rpc.discover lists them. Through DDS: `simgate call --transport dds` steps
it. Both the socket's list_services and JSON-RPC's rpc.discover list every new service.
The lockstep barrier (issue #35, item 11) with a socket client and a JSON-RPC client as its
two participants: one asking takes no step, both asking take the steps once, a plain step
is refused meanwhile, and a participant whose connection closes releases the other.
Every wait is bounded.
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
NEW_SERVICES = ["get_simulation_state", "pause", "play", "step", "reset", "save_state", "restore_state",
                "list_states", "drop_state", "lockstep_join", "lockstep_step"]


class Gateway:
    """`simgate run CONFIG` on ephemeral ports, with its endpoints read from --endpoints-file;
    `edit(config)` may change the configuration first (tests/e2e/worlds_test.py); `prefix`, a
    command that runs it (tests/e2e/hosts_test.py: nsenter, into a network namespace)."""

    def __init__(self, workdir, edit=None, prefix=()):
        with open(os.path.join(ARGS.source_dir, "config/all-transports.json")) as f:
            config = json.load(f)
        config["scene"]["mjcf"] = os.path.join(ARGS.source_dir, "config/scenes/demo.xml")
        config["scene"]["start_paused"] = True
        config["transports"]["socket"]["options"]["port"] = 0
        config["transports"]["socket"]["options"]["stream_port"] = 0
        config["transports"]["jsonrpc"]["options"]["port"] = 0
        self.partition = "simgate-world-test-%d" % os.getpid()
        config["transports"]["dds"]["options"]["partition"] = self.partition
        config["log_level"] = "warning"
        if edit:
            edit(config)
        path = os.path.join(workdir, "world.json")
        with open(path, "w") as f:
            json.dump(config, f)
        endpoints = os.path.join(workdir, "endpoints.json")
        self.log = open(os.path.join(workdir, "run.log"), "w+")
        command = list(prefix) + [ARGS.simgate, "run", path, "--endpoints-file", endpoints]
        self.process = subprocess.Popen(command,
                                        stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + TIMEOUT
        while not os.path.exists(endpoints):
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("simgate run did not start:\n" + self.output())
            time.sleep(0.01)  # polling for a file the child writes; bounded by the deadline
        with open(endpoints) as f:
            ports = json.load(f)
        self.socket_port = int(ports["socket"][0].rsplit(":", 1)[1])
        self.jsonrpc_port = int(ports["jsonrpc"][0].rsplit(":", 1)[1])

    def output(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self):
        self.process.send_signal(signal.SIGTERM)
        try:
            code = self.process.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait()
        self.log.close()
        return code


class Lines:
    """One TCP connection speaking lines, every read with a deadline."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT)
        self.reader = self.sock.makefile("rb")

    def ask(self, line):
        self.sock.sendall((line + "\n").encode())
        return self.reader.readline().decode().rstrip("\n")

    def close(self):
        # the file made by makefile() holds the socket open: closed first, the peer sees it leave
        self.reader.close()
        self.sock.close()


class GatewayTestCase(unittest.TestCase):
    """A test class with one gateway (its config changed by `edit`, a function of the config
    or None) and a socket and a JSON-RPC connection to it, for all of its tests."""
    edit = None

    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.TemporaryDirectory()
        cls.gateway = None
        try:
            cls.gateway = Gateway(cls.workdir.name, edit=cls.edit)
            cls.socket = Lines(cls.gateway.socket_port)
            cls.jsonrpc = Lines(cls.gateway.jsonrpc_port)
        except BaseException:
            if cls.gateway:
                cls.gateway.stop()  # tearDownClass does not run when this fails
            cls.workdir.cleanup()
            raise
        cls.rpc_id = 0

    @classmethod
    def tearDownClass(cls):
        cls.socket.close()
        cls.jsonrpc.close()
        code = cls.gateway.stop()
        cls.workdir.cleanup()
        assert code == 0, "simgate run exited with %s" % code

    def morse(self, rid, request):
        """A socket request; returns (status, value)."""
        reply = self.socket.ask("%s %s" % (rid, request))
        got_id, status, *rest = reply.split(" ", 2)
        self.assertEqual(got_id, rid, reply)
        return status, json.loads(rest[0]) if rest else None

    def rpc(self, method, params=None):
        cls = type(self)
        cls.rpc_id += 1
        request = {"jsonrpc": "2.0", "id": cls.rpc_id, "method": method}
        if params is not None:
            request["params"] = params
        response = json.loads(self.jsonrpc.ask(json.dumps(request)))
        self.assertEqual(response["id"], cls.rpc_id, response)
        return response


class WorldTest(GatewayTestCase):
    def state(self):
        status, value = self.morse("s", "simulation get_simulation_state")
        self.assertEqual(status, "SUCCESS")
        return value

    def test_1_starts_paused_and_steps_on_request_over_the_socket(self):
        # a connection is counted once the server has accepted it, which a client's connect()
        # does not wait for: one answered call on each proves both accepted
        self.rpc("simulation.list_robots")
        first = self.state()
        self.assertEqual(first["state"], "paused")
        self.assertEqual(first["steps"], 0)
        # this test's two connections, each counted by its transport
        self.assertEqual(first["clients_by_transport"]["socket"], 1, first)
        self.assertEqual(first["clients_by_transport"]["jsonrpc"], 1, first)
        self.assertEqual(first["clients"], sum(first["clients_by_transport"].values()), first)
        for _ in range(20):  # served, and nothing moves
            self.assertEqual(self.state()["steps"], 0)
        status, value = self.morse("1", "simulation step [5]")
        self.assertEqual(status, "SUCCESS")
        self.assertEqual(value["steps_done"], 5)
        self.assertAlmostEqual(value["sim_time"], 0.01, places=12)
        self.assertEqual(self.state()["steps"], 5)
        # the MORSE reply shape, byte for byte
        reply = self.socket.ask("2 simulation step [1]")
        self.assertRegex(reply, r'^2 SUCCESS \{"sim_time": 0\.012[0-9]*, "steps_done": 1\}$')

    def test_2_bad_counts_are_refused_naming_n(self):
        for bad in ["[0]", "[-4]", "[1.5]", "[\"x\"]", "[NaN]", "[1e12]"]:
            status, value = self.morse("b", "simulation step " + bad)
            self.assertEqual(status, "FAILED", bad)
            self.assertRegex(value, r"\bn\b", bad)
        self.assertEqual(self.state()["state"], "paused")

    def test_3_json_rpc_steps_with_named_parameters_and_discovers_the_services(self):
        before = self.state()["steps"]
        response = self.rpc("simulation.step", {"n": 3})
        self.assertEqual(response["result"]["steps_done"], 3, response)
        self.assertEqual(self.state()["steps"], before + 3)
        refused = self.rpc("simulation.step", {"n": 0})
        self.assertEqual(refused["error"]["data"]["parameter"], "n", refused)
        state = self.rpc("simulation.get_simulation_state")["result"]
        self.assertEqual(state["state"], "paused")
        methods = {m["name"] for m in self.rpc("rpc.discover")["result"]["methods"]}
        for service in NEW_SERVICES:
            self.assertIn("simulation." + service, methods)
        self.assertIn("time.set_time_scale", methods)
        status, services = self.morse("l", "simulation list_services")
        listed = {(d["component"], d["name"]) for d in services}
        for service in NEW_SERVICES:
            self.assertIn(("simulation", service), listed)

    def test_4_dds_steps_too(self):
        before = self.state()["steps"]
        done = subprocess.run([ARGS.simgate, "call", "--transport", "dds", "--partition", self.gateway.partition,
                               "--timeout", "20", "simulation", "step", "4"],
                              capture_output=True, text=True, timeout=TIMEOUT)
        self.assertEqual(done.returncode, 0, done.stdout + done.stderr)
        self.assertIn("steps_done", done.stdout)
        self.assertEqual(self.state()["steps"], before + 4)

    def test_5_snapshots_and_resets(self):
        status, handle = self.morse("a", "simulation save_state")
        self.assertEqual(status, "SUCCESS")
        saved = self.state()["sim_time"]
        self.morse("b", "robot.motion set_speed [1.0, 0.5]")
        self.morse("c", "simulation step [100]")
        status, value = self.morse("d", "simulation restore_state [%d]" % handle)
        self.assertEqual(status, "SUCCESS")
        self.assertEqual((value["sim_time"], value["exact"]), (saved, True))
        self.assertEqual(self.state()["sim_time"], saved)
        status, states = self.morse("e", "simulation list_states")
        self.assertIn(handle, [s["handle"] for s in states])
        self.assertEqual(self.socket.ask("f simulation drop_state [%d]" % handle), "f SUCCESS true")
        status, value = self.morse("g", "simulation restore_state [%d]" % handle)
        self.assertEqual(status, "FAILED")
        self.assertIn("no saved state", value)
        # reset robot: time goes on; reset all: time back to 0
        self.morse("h", "simulation step [10]")
        t = self.state()["sim_time"]
        self.assertEqual(self.morse("i", 'simulation reset ["robot", "robot"]')[0], "SUCCESS")
        self.assertEqual(self.state()["sim_time"], t)
        response = self.rpc("simulation.reset", {"scope": "all"})
        self.assertIn("result", response)
        self.assertEqual(self.state()["sim_time"], 0)

    def test_5c_a_saved_state_is_its_clients_to_drop_while_it_is_connected(self):
        # issue #35 item 10: any client dropped another's states, and one took all 64 slots
        status, handle = self.morse("a", "simulation save_state")
        self.assertEqual(status, "SUCCESS")
        states = {s["handle"]: s for s in self.rpc("simulation.list_states")["result"]}
        self.assertEqual((states[handle]["yours"], states[handle]["owner_connected"]), (False, True))
        dropped = self.rpc("simulation.drop_state", [handle])
        self.assertIn("error", dropped)
        self.assertIn("only it drops its states", dropped["error"]["message"])
        self.assertIn("result", self.rpc("simulation.restore_state", [handle]))  # anyone restores
        # a client that saves and leaves: its state may be dropped by anyone then
        other = Lines(self.gateway.socket_port)
        reply = other.ask("x simulation save_state")
        self.assertTrue(reply.startswith("x SUCCESS "), reply)
        left = int(reply.split(" ", 2)[2])
        other.close()
        for _ in range(100):  # bounded: the server sees the connection close within moments
            states = {s["handle"]: s for s in self.rpc("simulation.list_states")["result"]}
            if not states[left]["owner_connected"]:
                break
            time.sleep(0.05)
        self.assertEqual(self.rpc("simulation.drop_state", [left]).get("result"), True)
        # one client keeps at most 16
        handles = []
        for i in range(16):
            status, h = self.morse("q%d" % i, "simulation save_state")
            if status != "SUCCESS":
                break
            handles.append(h)
        status, value = self.morse("q", "simulation save_state")
        self.assertEqual(status, "FAILED")
        self.assertIn("the most one client keeps", value)
        for i, h in enumerate(handles + [handle]):
            self.assertEqual(self.socket.ask("r%d simulation drop_state [%d]" % (i, h)), "r%d SUCCESS true" % i)
        # every slot taken by clients that left: a save makes room by dropping the oldest of theirs
        for k in range(4):
            gone = Lines(self.gateway.socket_port)
            for i in range(16):
                reply = gone.ask("g%d simulation save_state" % i)
                self.assertTrue(reply.startswith("g%d SUCCESS " % i), reply)
            gone.close()
        for _ in range(100):  # bounded, as above
            if not any(s["owner_connected"] for s in self.rpc("simulation.list_states")["result"]):
                break
            time.sleep(0.05)
        status, h = self.morse("s", "simulation save_state")
        self.assertEqual(status, "SUCCESS", h)
        states = self.rpc("simulation.list_states")["result"]
        self.assertEqual(len(states), 64)
        for i, s in enumerate(states):
            self.assertEqual(self.socket.ask("t%d simulation drop_state [%d]" % (i, s["handle"])), "t%d SUCCESS true" % i)

    def test_5b_cancel_ends_a_step_preempted_with_the_steps_done(self):
        # socket: MORSE's cancel line, no reply of its own; the step answers PREEMPTED
        self.socket.sock.sendall(b"c1 simulation step [1000000]\n")
        self.state()  # queued after the step: it has started
        self.socket.sock.sendall(b"c1 cancel\n")
        reply = self.socket.reader.readline().decode().rstrip("\n")
        got_id, status, value = reply.split(" ", 2)
        self.assertEqual((got_id, status), ("c1", "PREEMPTED"), reply)
        value = json.loads(value)
        self.assertGreater(value["steps_done"], 0)
        self.assertLess(value["steps_done"], 1000000)
        self.assertEqual(value["steps_requested"], 1000000)
        self.assertEqual(self.state()["owed_steps"], 0)
        # JSON-RPC: rpc.cancel; the value rides in the error's data
        WorldTest.rpc_id += 2
        step_id, cancel_id = WorldTest.rpc_id - 1, WorldTest.rpc_id
        self.jsonrpc.sock.sendall((json.dumps({"jsonrpc": "2.0", "id": step_id, "method": "simulation.step",
                                               "params": [1000000]}) + "\n").encode())
        self.jsonrpc.sock.sendall((json.dumps({"jsonrpc": "2.0", "id": cancel_id, "method": "rpc.cancel",
                                               "params": {"id": step_id}}) + "\n").encode())
        replies = {}
        for _ in range(2):
            r = json.loads(self.jsonrpc.reader.readline())
            replies[r["id"]] = r
        self.assertEqual(replies[cancel_id]["result"], True, replies)
        error = replies[step_id]["error"]
        self.assertEqual(error["data"]["status"], "PREEMPTED", error)
        self.assertEqual(error["data"]["value"]["steps_requested"], 1000000, error)
        self.assertEqual(self.state()["state"], "paused")

    def test_6_time_scale_play_and_pause(self):
        self.assertEqual(self.socket.ask("t time set_time_scale [2.0]"), "t SUCCESS true")
        self.assertEqual(self.state()["target_realtime_factor"], 2.0)
        status, value = self.morse("u", "time set_time_scale [-1]")
        self.assertEqual(status, "FAILED")
        self.assertIn("value", value)
        self.assertEqual(self.morse("v", "simulation play")[0], "SUCCESS")
        self.assertEqual(self.state()["state"], "playing")
        status, value = self.morse("w", "simulation step [1]")
        self.assertEqual(status, "FAILED")
        self.assertIn("pause it first", value)
        moved = False
        before = self.state()["steps"]
        for _ in range(100000):  # bounded: answers, not time
            if self.state()["steps"] > before:
                moved = True
                break
        self.assertTrue(moved)
        self.assertEqual(self.morse("x", "simulation pause")[0], "SUCCESS")
        paused = self.state()
        self.assertEqual(paused["state"], "paused")
        self.assertEqual(self.state()["steps"], paused["steps"])

    def test_7_a_socket_and_a_json_rpc_client_step_in_lockstep(self):
        sock, rpc = Lines(self.gateway.socket_port), Lines(self.gateway.jsonrpc_port)
        try:
            before = self.state()["steps"]
            # each joins: the call runs as long as its client takes part (no reply until then);
            # the JSON-RPC one asks for progress, whose first report names it
            sock.sock.sendall(b'j simulation lockstep_join ["sock"]\n')
            rpc.sock.sendall((json.dumps({"jsonrpc": "2.0", "id": "join", "method": "simulation.lockstep_join",
                                          "params": {"participant": "rpc", "_meta": {"progress": True}}})
                              + "\n").encode())
            report = json.loads(rpc.reader.readline())
            self.assertEqual(report["method"], "rpc.progress", report)
            self.assertEqual(report["params"]["id"], "join", report)
            self.assertEqual(report["params"]["data"]["participant"], "rpc", report)
            # a sync call answered on the socket client's connection: its join was handled
            self.assertTrue(sock.ask("s simulation get_simulation_state").startswith("s SUCCESS"))
            self.assertEqual(sorted(self.state()["lockstep"]["participants"]), ["rpc", "sock"])

            # the socket participant asks: no step yet
            sock.sock.sendall(b'1 simulation lockstep_step ["sock", 3]\n')
            self.assertTrue(sock.ask("s simulation get_simulation_state").startswith("s SUCCESS"))
            state = self.state()
            self.assertEqual(state["steps"], before)
            self.assertEqual(state["lockstep"]["waiting"], ["sock"])
            # a plain step would move both unasked: refused
            status, value = self.morse("p", "simulation step [1]")
            self.assertEqual(status, "FAILED")
            self.assertIn("stepped in lockstep", value)
            # the JSON-RPC participant asks: the 3 steps are taken once, both asks complete
            rpc.sock.sendall((json.dumps({"jsonrpc": "2.0", "id": 1, "method": "simulation.lockstep_step",
                                          "params": {"participant": "rpc", "n": 3}}) + "\n").encode())
            response = json.loads(rpc.reader.readline())
            self.assertEqual(response["id"], 1, response)
            self.assertEqual(response["result"]["steps_done"], 3, response)
            reply = sock.reader.readline().decode().rstrip("\n")
            self.assertRegex(reply, r'^1 SUCCESS \{"sim_time": [0-9.e-]+, "steps_done": 3\}$')
            self.assertEqual(json.loads(reply.split(" ", 2)[2])["sim_time"], response["result"]["sim_time"])
            self.assertEqual(self.state()["steps"], before + 3)

            # the socket participant asks again, then the JSON-RPC client leaves (its connection
            # closes, its join is cancelled): the barrier no longer waits for it
            sock.sock.sendall(b'2 simulation lockstep_step ["sock", 2]\n')
            self.assertTrue(sock.ask("s simulation get_simulation_state").startswith("s SUCCESS"))
            self.assertEqual(self.state()["steps"], before + 3)
            rpc.close()
            reply = sock.reader.readline().decode().rstrip("\n")
            self.assertRegex(reply, r'^2 SUCCESS \{"sim_time": [0-9.e-]+, "steps_done": 2\}$')
            self.assertEqual(self.state()["steps"], before + 5)
            self.assertEqual(self.state()["lockstep"]["participants"], ["sock"])
        finally:
            sock.close()
            rpc.close()
        # the last participant gone (bounded: answers, not time), anyone steps again
        for _ in range(100000):
            if not self.state()["lockstep"]["participants"]:
                break
        self.assertEqual(self.state()["lockstep"]["participants"], [])
        self.assertEqual(self.morse("q", "simulation step [1]")[0], "SUCCESS")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--simgate", required=True)
    parser.add_argument("--source-dir", required=True)
    ARGS, rest = parser.parse_known_args()
    ARGS.source_dir = os.path.abspath(ARGS.source_dir)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
