#!/usr/bin/python3
"""E2E: many worlds in one simgate (issue #43, docs/worlds.md).

`simgate run` serves the demo with "worlds": 3 on the socket, JSON-RPC and DDS transports
(ports 0, a DDS partition of its own), paused (lockstep). Each world is a simulation of its
own, addressed as "w<k>/<component>" on every transport; world 0 keeps its names. Checked:
- addressing: w1/..., w2/... reach their world; w0/ is world 0; a world there is not is
  FAILED naming the worlds there are (socket, JSON-RPC);
- isolation: steps, a teleport and a reset in one world leave the others as they were, to
  the last digit (their poses compared as text);
- listings: JSON-RPC's rpc.discover and `simgate list` show every world's services;
- DDS: `simgate call --transport dds w2/simulation step 3` steps world 2 only;
- pymorse (Debian's, unchanged) drives world 0 as ever and reaches world 1 by rpc();
- `simulation step_many`: worlds stepped together end exactly as stepped one by one; what
  does not fit (a world there is not, a wrong action size, an out-of-range control) is
  refused whole, before any world steps;
- `simulation create_world` / `delete_world` / `list_worlds`: a world made at run time is
  served through socket, JSON-RPC and DDS and listed; deleting it answers its pending call
  FAILED, takes it out of every listing and leaves the others as they were; its index is
  not given again; world 0 and worlds there are not are refused; at the config's
  `"worlds": {"max": N}` create_world is refused saying so (QuotaTest), and past its
  `"max_memory_mb"` (MemoryQuotaTest); a world of another scene (a file under
  spawn.allowed_dirs), its refusals;
- a world at start of another scene, the config's `"worlds": {"scenes"}` (SceneWorldsTest):
  list_worlds names its file and its number of actuators, it has that scene's bodies and
  the config's robots, step_many steps it beside world 0 with an action of its size, and
  the worlds of the config's scene do not have its bodies.
Every wait is bounded.
"""
import argparse
import base64
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
import unittest
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import world_test  # noqa: E402  (its GatewayTestCase: a gateway and a socket and JSON-RPC client)

warnings.simplefilter("ignore", DeprecationWarning)  # asyncore/asynchat on Python 3.11
import pymorse  # noqa: E402

ARGS = None
TIMEOUT = world_test.TIMEOUT
WORLDS = 3
# the scene files clients may name (spawn.allowed_dirs): the demo with a rock on the Moon, and
# a scene without the robots' bodies
SCENES = tempfile.TemporaryDirectory()
LIFT = os.path.join(SCENES.name, "lift.xml")  # world 1's scene in SceneWorldsTest's config


def write_scenes(source_dir):
    with open(os.path.join(source_dir, "config/scenes/demo.xml")) as f:
        demo = f.read()
    moon = demo.replace('<option timestep="0.002" integrator="implicit"/>',
                        '<option timestep="0.002" integrator="implicit" gravity="0 0 -1.62"/>')
    moon = moon.replace("<worldbody>", '<worldbody>\n    <body name="moon_rock" pos="3 3 0.2">'
                        '<geom type="sphere" size="0.2"/></body>', 1)
    assert moon != demo and "moon_rock" in moon
    with open(os.path.join(SCENES.name, "moon.xml"), "w") as f:
        f.write(moon)
    with open(os.path.join(SCENES.name, "bare.xml"), "w") as f:
        f.write('<mujoco><worldbody><geom type="plane" size="5 5 0.1"/></worldbody></mujoco>')
    # a scene with one more actuator (a lift on a slide joint), for a world of the config
    lift = demo.replace("<worldbody>", '<worldbody>\n    <body name="lift" pos="0 3 0.5"><joint name="lift_slide" '
                        'type="slide" axis="0 0 1"/><geom type="box" size="0.2 0.2 0.2"/></body>', 1)
    lift = lift.replace("</actuator>", '  <motor name="lift_motor" joint="lift_slide" ctrlrange="-50 50" '
                        'ctrllimited="true"/>\n  </actuator>', 1)
    assert "lift_motor" in lift and "lift_slide" in lift
    with open(LIFT, "w") as f:
        f.write(lift)


def with_worlds(config):
    config.update(worlds=WORLDS, spawn={"allowed_dirs": [SCENES.name]})


class WorldsGateway(world_test.GatewayTestCase):
    """A gateway of this script's (its ARGS given to world_test) for the test classes below."""

    @classmethod
    def setUpClass(cls):
        world_test.ARGS = ARGS
        super().setUpClass()


class WorldsTest(WorldsGateway):
    edit = staticmethod(with_worlds)

    def morse(self, request):
        """A socket request under id "r"; returns (status, value)."""
        return super().morse("r", request)

    def ok(self, request):
        status, value = self.morse(request)
        self.assertEqual(status, "SUCCESS", "%s: %s" % (request, value))
        return value

    def world_prefix(self, k):
        return "" if k == 0 else "w%d/" % k

    def snapshot(self, k):
        """World k's time, steps and robot pose, as the server wrote them."""
        state = self.ok(self.world_prefix(k) + "simulation get_simulation_state")
        pose = self.socket.ask("p %srobot.pose get_local_data" % self.world_prefix(k))
        return state["sim_time"], state["steps"], pose.split(" ", 2)[2]

    def test_1_each_world_is_addressed_by_its_prefix_and_world_0_keeps_its_names(self):
        for k in range(WORLDS):
            self.assertEqual(self.ok(self.world_prefix(k) + "simulation list_robots"), ["robot", "human"])
        self.assertEqual(self.ok("w0/simulation list_robots"), ["robot", "human"])
        status, value = self.morse("w7/robot.pose get_local_data")
        self.assertEqual(status, "FAILED")
        self.assertIn("no world 'w7' (the worlds here: w0, w1, w2)", value)
        error = self.rpc("w7/robot.pose.get_local_data")["error"]
        self.assertIn("no world 'w7'", error["message"])
        self.assertEqual(error["data"]["worlds"], ["w0", "w1", "w2"])

    def test_2_steps_teleports_and_resets_stay_in_their_world(self):
        before = [self.snapshot(k) for k in range(WORLDS)]
        self.ok("w1/simulation step [25]")
        after = [self.snapshot(k) for k in range(WORLDS)]
        self.assertEqual(after[1][1], before[1][1] + 25)
        self.assertGreater(after[1][0], before[1][0])
        self.assertEqual(after[0], before[0])
        self.assertEqual(after[2], before[2])

        self.ok("w2/robot.teleport translate [1.0, 0.5, 0.0]")
        moved = [self.snapshot(k) for k in range(WORLDS)]
        self.assertNotEqual(moved[2][2], after[2][2])
        self.assertEqual(moved[0], after[0])
        self.assertEqual(moved[1], after[1])

        self.ok("w2/simulation reset")
        reset = [self.snapshot(k) for k in range(WORLDS)]
        self.assertEqual(reset[2][1], 0)
        self.assertEqual(reset[0], after[0])
        self.assertEqual(reset[1], after[1])  # world 1 keeps its 25 steps

    def test_3_listings_show_every_world(self):
        methods = [m["name"] for m in self.rpc("rpc.discover")["result"]["methods"]]
        for k in range(WORLDS):
            self.assertIn(self.world_prefix(k) + "robot.motion.set_speed", methods)
            self.assertIn(self.world_prefix(k) + "simulation.step", methods)
        listed = subprocess.run([ARGS.simgate, "list", "--transport", "jsonrpc", "--port",
                                 str(self.gateway.jsonrpc_port)],
                                capture_output=True, text=True, timeout=TIMEOUT)
        self.assertEqual(listed.returncode, 0, listed.stdout + listed.stderr)
        self.assertIn("w2/robot.motion", listed.stdout)

    def test_4_dds_steps_one_world(self):
        before = [self.snapshot(k) for k in range(WORLDS)]
        done = subprocess.run([ARGS.simgate, "call", "--transport", "dds", "--partition",
                               self.gateway.partition, "--timeout", "20", "w2/simulation", "step", "3"],
                              capture_output=True, text=True, timeout=TIMEOUT)
        self.assertEqual(done.returncode, 0, done.stdout + done.stderr)
        after = [self.snapshot(k) for k in range(WORLDS)]
        self.assertEqual(after[2][1], before[2][1] + 3)
        self.assertEqual(after[0], before[0])
        self.assertEqual(after[1], before[1])

    def test_6_step_many_steps_worlds_together_as_one_by_one(self):
        observe = ["qpos", "qvel", "ctrl", "sensordata"]
        actions = [[0.3, -0.2], [0.3, -0.2]]

        def fresh(*worlds):
            for k in worlds:
                self.ok(self.world_prefix(k) + "simulation reset")

        fresh(1, 2)
        together = self.rpc("simulation.step_many", {"worlds": [1, 2], "n": 40, "actions": actions,
                                                     "observe": observe})["result"]["worlds"]
        fresh(1, 2)
        alone = [self.rpc("simulation.step_many", {"worlds": [k], "n": 40, "actions": [actions[0]],
                                                   "observe": observe})["result"]["worlds"][0]
                 for k in (2, 1)]
        self.assertEqual([w["world"] for w in together], [1, 2])
        self.assertEqual(together[0]["steps_done"], 40)
        self.assertEqual(together[0]["ctrl"], actions[0])
        # bit for bit: the same start and actions give the same numbers, batched or not
        for batched, single in zip(together, reversed(alone)):
            self.assertEqual(batched, single)
        self.assertEqual({k: v for k, v in together[0].items() if k != "world"},
                         {k: v for k, v in together[1].items() if k != "world"})

    def test_6b_step_many_in_base64_gives_the_same_doubles(self):
        observe = ["qpos", "qvel", "ctrl", "sensordata"]
        params = {"worlds": [1], "n": 7, "actions": [[0.25, -0.5]], "observe": observe}
        self.ok("w1/simulation reset")
        numbers = self.rpc("simulation.step_many", params)["result"]["worlds"][0]
        self.ok("w1/simulation reset")
        encoded = self.rpc("simulation.step_many", dict(params, encoding="base64"))["result"]["worlds"][0]
        self.assertEqual(encoded["steps_done"], 7)
        for what in observe:
            raw = base64.b64decode(encoded[what])
            self.assertEqual(len(raw), 8 * len(numbers[what]), what)
            # IEEE 754 binary64, little-endian: bit for bit the numbers JSON gives
            self.assertEqual(list(struct.unpack("<%dd" % len(numbers[what]), raw)), numbers[what], what)

    def test_7_step_many_refuses_what_does_not_fit_before_anything_steps(self):
        before = [self.snapshot(k) for k in range(WORLDS)]
        for params, parameter, words in [
                ({"worlds": [0, 5]}, "worlds[1]", "no world number 5 (the worlds here: 0, 1, 2)"),
                ({"worlds": [1, 1]}, "worlds[1]", "world 1 twice"),
                ({"worlds": [1, 2], "actions": [[0.1, 0.1], [0.1]]}, "actions[1]",
                 "world 2 has 2 actuators: expected 2 numbers"),
                ({"actions": [None]}, "actions", "one entry per world named (3"),
                ({"n": 0}, "n", "expected 1 to 1000000 steps"),
                ({"observe": ["qpos", "xpos"]}, "observe[1]", "expected one of qpos, qvel"),
                ({"encoding": "hex"}, "encoding", "expected json (numbers) or base64"),
                ({"worlds": [1], "actions": [[float("1e300"), 0]]}, "actions[0][0]", "out of bounds")]:
            error = self.rpc("simulation.step_many", params)["error"]
            self.assertEqual(error["code"], -32602, error)
            self.assertEqual(error["data"]["parameter"], parameter, error)
            self.assertIn(words, error["message"])
        self.assertEqual([self.snapshot(k) for k in range(WORLDS)], before)
        # only world 0 offers it
        self.assertEqual(self.rpc("w1/simulation.step_many", {})["error"]["code"], -32601)

    def test_5_pymorse_drives_world_0_and_reaches_the_others_by_rpc(self):
        # not `with pymorse.Morse()`: its close() with wait_publishers=True raises a TypeError in
        # Debian's pymorse (its proxies' __getattribute__), whatever the server
        simu = pymorse.Morse(host="127.0.0.1", port=self.gateway.socket_port)
        try:
            self.assertEqual(sorted(simu.robots), ["human", "robot"])
            before = [self.snapshot(k) for k in range(WORLDS)]
            simu.rpc("simulation", "step", 2)
            self.assertEqual(simu.rpc("w1/simulation", "list_robots"), ["robot", "human"])
            after = [self.snapshot(k) for k in range(WORLDS)]
            self.assertEqual(after[0][1], before[0][1] + 2)
            self.assertEqual(after[1:], before[1:])
        finally:
            simu.close(wait_publishers=False)

    def test_8_a_world_made_at_run_time_is_served_listed_and_deleted(self):
        listed = self.rpc("simulation.list_worlds")["result"]
        self.assertEqual([w["name"] for w in listed["worlds"]], ["w0", "w1", "w2"])
        self.assertEqual((listed["count"], listed["max"]), (3, 16))  # max: 16 by default
        for w in listed["worlds"]:
            self.assertGreater(w["memory_bytes"], 100000, w)  # the demo's model and data
            self.assertEqual(w["state"], "paused")
            self.assertEqual(w["actuators"], 2)  # the demo robot's wheels: step_many's action size
        before = [self.snapshot(k) for k in range(WORLDS)]

        made = self.rpc("simulation.create_world")["result"]
        self.assertEqual(made, {"world": 3, "name": "w3", "count": 4, "max": 16})
        self.assertEqual(self.ok("w3/simulation list_robots"), ["robot", "human"])
        self.ok("w3/simulation step [7]")
        self.assertEqual(self.snapshot(3)[1], 7)
        methods = [m["name"] for m in self.rpc("rpc.discover")["result"]["methods"]]
        self.assertIn("w3/robot.motion.set_speed", methods)
        done = subprocess.run([ARGS.simgate, "call", "--transport", "dds", "--partition",
                               self.gateway.partition, "--timeout", "20", "w3/simulation", "step", "2"],
                              capture_output=True, text=True, timeout=TIMEOUT)
        self.assertEqual(done.returncode, 0, done.stdout + done.stderr)
        stepped = self.rpc("simulation.step_many", {"worlds": [3], "n": 1, "observe": []})["result"]
        self.assertEqual(stepped["worlds"][0]["steps_done"], 1)
        self.assertEqual(self.snapshot(3)[1], 10)
        self.assertEqual([self.snapshot(k) for k in range(WORLDS)], before)

        # a call pending in w3 (a sleep in a paused world: simulated time stands still)
        self.socket.sock.sendall(b"z w3/time sleep [60]\n")
        gone = self.rpc("simulation.delete_world", {"world": 3})["result"]
        self.assertEqual(gone, {"world": 3, "name": "w3", "count": 3})
        got_id, status, value = self.socket.reader.readline().decode().rstrip("\n").split(" ", 2)
        self.assertEqual((got_id, status), ("z", "FAILED"), value)
        status, value = self.morse("w3/simulation list_robots")
        self.assertEqual(status, "FAILED")
        self.assertIn("no world 'w3' (the worlds here: w0, w1, w2)", value)
        methods = [m["name"] for m in self.rpc("rpc.discover")["result"]["methods"]]
        self.assertFalse([m for m in methods if m.startswith("w3/")])
        self.assertEqual([self.snapshot(k) for k in range(WORLDS)], before)

        for params, words in [({"world": 3}, "no world 3 (the worlds here: w0, w1, w2)"),
                              ({"world": 0}, "world 0 is the simulation itself"),
                              ({"world": -1}, "no world -1")]:
            error = self.rpc("simulation.delete_world", params)["error"]
            self.assertEqual(error["code"], -32602, error)
            self.assertEqual(error["data"]["parameter"], "world", error)
            self.assertIn(words, error["message"])
        # an index is never given twice: a client holding "w3" cannot reach another world
        again = self.rpc("simulation.create_world")["result"]
        self.assertEqual(again["name"], "w4")
        self.assertEqual(self.snapshot(4)[1], 0)
        self.assertEqual(self.rpc("simulation.delete_world", [4])["result"]["count"], 3)

    def test_9_step_many_reads_services_of_each_world_and_keeps_null_controls(self):
        for k in (1, 2):
            self.ok("w%d/simulation step [3]" % k)
        reads = [{"component": "robot.pose", "service": "get_local_data"},
                 {"component": "simulation", "service": "get_entity_state", "params": {"name": "robot"}}]
        ctrl = self.rpc("simulation.step_many", {"worlds": [1], "n": 1, "observe": ["ctrl"]})["result"]
        kept = ctrl["worlds"][0]["ctrl"]
        stepped = self.rpc("simulation.step_many", {"worlds": [1, 2], "n": 2, "observe": ["ctrl"],
                                                    "actions": [[None, 0.25], None], "reads": reads})["result"]
        one, two = stepped["worlds"]
        self.assertEqual(one["ctrl"], [kept[0], 0.25])  # the null control kept
        # each world's reads, as the same services called alone give them
        for k, slot in ((1, one), (2, two)):
            self.assertEqual(len(slot["reads"]), 2, slot)
            self.assertEqual(slot["reads"][0], self.rpc("w%d/robot.pose.get_local_data" % k)["result"])
            self.assertEqual(slot["reads"][1],
                             self.rpc("w%d/simulation.get_entity_state" % k, {"name": "robot"})["result"])
        for params, parameter, words in [
                ({"reads": [{"component": "robot.pose"}]}, "reads[0]", "expected {"),
                ({"reads": [{"component": "robot.pose", "service": "nope"}]}, "reads[0]",
                 "has no service robot.pose.nope"),
                ({"reads": [{"component": "simulation", "service": "step"}]}, "reads[0]", "is asynchronous"),
                ({"reads": [{"component": "robot.pose", "service": "get_local_data", "param": 1}]},
                 "reads[0].param", "unknown key"),
                ({"reads": [{"component": "simulation", "service": "get_entity_state", "params": [1, 2, 3]}]},
                 "reads[0].params", "wrong # of parameters")]:
            before = [self.snapshot(k) for k in range(WORLDS)]
            error = self.rpc("simulation.step_many", params)["error"]
            self.assertEqual(error["code"], -32602, error)
            self.assertEqual(error["data"]["parameter"], parameter, error)
            self.assertIn(words, error["message"])
            self.assertEqual([self.snapshot(k) for k in range(WORLDS)], before)

    def test_9x_a_world_of_another_scene(self):  # after test_8 (which counts indices)
        made = self.rpc("simulation.create_world", {"scene": "moon.xml"})["result"]
        prefix = made["name"] + "/"
        rock = self.rpc(prefix + "simulation.get_object_pose", ["moon_rock"])
        self.assertIn("result", rock, rock)
        self.assertIn("error", self.rpc("simulation.get_object_pose", ["moon_rock"]))  # not in world 0
        self.assertEqual(self.ok(prefix + "simulation list_robots"), ["robot", "human"])
        scenes = {w["name"]: w["scene"] for w in self.rpc("simulation.list_worlds")["result"]["worlds"]}
        self.assertEqual(scenes, {"w0": None, "w1": None, "w2": None, made["name"]: "moon.xml"})
        count = self.rpc("simulation.list_worlds")["result"]["count"]
        for scene, words in [("../../etc/passwd", "is no file under the directories the config allows"),
                             (5, "expected an MJCF file name"),
                             ("bare.xml", "robot"),  # the robots' bodies are not in it
                             ("nope.xml", "is no file under")]:
            error = self.rpc("simulation.create_world", {"scene": scene})["error"]
            self.assertEqual(error["code"], -32602, error)
            self.assertEqual(error["data"]["parameter"], "scene", error)
            self.assertIn(words, error["message"])
            self.assertEqual(self.rpc("simulation.list_worlds")["result"]["count"], count)  # nothing made
        self.rpc("simulation.delete_world", {"world": made["world"]})
        # a world refused takes no index
        self.assertEqual(self.rpc("simulation.create_world")["result"]["world"], made["world"] + 1)


class AsyncStepManyTest(WorldsGateway):
    """step_many steps off the thread that received it: the connection goes on serving."""
    edit = staticmethod(with_worlds)

    def send(self, method, params):
        """A JSON-RPC request sent without waiting for its reply; its id."""
        cls = type(self)
        cls.rpc_id += 1
        self.jsonrpc.sock.sendall((json.dumps({"jsonrpc": "2.0", "id": cls.rpc_id, "method": method,
                                               "params": params}) + "\n").encode())
        return cls.rpc_id

    def replies(self, count):
        """The next `count` JSON-RPC replies, by id (in any order)."""
        got = {}
        for _ in range(count):
            reply = json.loads(self.jsonrpc.reader.readline())
            got[reply["id"]] = reply
        return got

    def steps(self, k):
        status, value = self.morse("s", "%ssimulation get_simulation_state" % ("w%d/" % k if k else ""))
        self.assertEqual(status, "SUCCESS", value)
        return value["steps"]

    def test_1_other_calls_are_answered_while_it_steps_and_a_cancel_stops_it(self):
        before = self.steps(1)
        long_call = self.send("simulation.step_many", {"worlds": [1], "n": 1000000, "observe": []})
        # on the same connection: answered while world 1 steps (it used to wait for all its steps)
        other = self.send("w2/simulation.get_simulation_state", {})
        self.assertIn("steps", self.replies(1)[other]["result"])
        cancel = self.send("rpc.cancel", {"id": long_call})
        got = self.replies(2)
        self.assertEqual(got[cancel]["result"], True, got)
        self.assertEqual(got[long_call]["error"]["data"]["status"], "PREEMPTED", got)
        # world 1 stopped at its next step: served again, far short of a million steps
        self.assertLess(self.steps(1), before + 1000000)

    def test_2_calls_naming_the_same_world_step_it_in_the_order_they_came(self):
        first = {"n": 20, "actions": [[0.3, -0.2]], "observe": ["qpos", "qvel", "ctrl"]}
        second = dict(first, actions=[[-0.1, 0.4]])
        for k in (1, 2):
            self.ok_reset(k)
        # world 1: both calls in flight at once; world 2: one after the other
        ids = [self.send("simulation.step_many", dict(params, worlds=[1])) for params in (first, second)]
        got = self.replies(2)
        one_by_one = [self.rpc("simulation.step_many", dict(params, worlds=[2]))["result"]["worlds"][0]
                      for params in (first, second)]
        for i, alone in zip(ids, one_by_one):
            slot = got[i]["result"]["worlds"][0]
            self.assertEqual(slot["world"], 1)
            self.assertEqual({k: v for k, v in slot.items() if k != "world"},
                             {k: v for k, v in alone.items() if k != "world"})

    def ok_reset(self, k):
        status, value = self.morse("r", "w%d/simulation reset" % k)
        self.assertEqual(status, "SUCCESS", value)

    def test_3_deleting_a_world_stops_the_call_stepping_it(self):
        made = self.rpc("simulation.create_world")["result"]["world"]
        long_call = self.send("simulation.step_many", {"worlds": [1, made], "n": 1000000, "observe": []})
        self.assertIn("result", self.rpc("w2/simulation.get_simulation_state"))  # the call was checked
        # delete_world waits for the world's stepping to stop, not for the million steps
        status, value = self.morse("d", "simulation delete_world [%d]" % made)
        self.assertEqual(status, "SUCCESS", value)
        cancel = self.send("rpc.cancel", {"id": long_call})  # world 1 would step on
        got = self.replies(2)
        self.assertEqual(got[cancel]["result"], True, got)
        self.assertEqual(got[long_call]["error"]["data"]["status"], "PREEMPTED", got)
        self.assertNotIn("w%d" % made, [w["name"] for w in self.rpc("simulation.list_worlds")["result"]["worlds"]])

    def test_4_a_world_deleted_before_its_turn_says_so_in_its_slot(self):
        made = self.rpc("simulation.create_world")["result"]["world"]
        # the first call holds the world; the second waits for its turn on it, then finds it gone
        first = self.send("simulation.step_many", {"worlds": [made], "n": 1000000, "observe": []})
        second = self.send("simulation.step_many", {"worlds": [made, 2], "n": 3, "observe": []})
        self.assertIn("result", self.rpc("w2/simulation.get_simulation_state"))  # both were checked
        status, value = self.morse("d", "simulation delete_world [%d]" % made)
        self.assertEqual(status, "SUCCESS", value)
        got = self.replies(2)
        self.assertIn("result", got[first], got)
        slot = got[first]["result"]["worlds"][0]
        # during its steps, or before they began (its thread had not yet taken it)
        self.assertIn("was deleted (simulation delete_world)", slot["error"])
        self.assertLess(slot["steps_done"], 1000000)
        gone, stepped = got[second]["result"]["worlds"]
        self.assertEqual((gone["steps_done"], stepped["steps_done"]), (0, 3), got[second])
        self.assertIn("was deleted (simulation delete_world) before its turn", gone["error"])


    def test_5_a_deadline_stops_its_worlds(self):
        before = self.steps(1)
        call = self.send("simulation.step_many", {"worlds": [1], "n": 1000000, "observe": [],
                                                  "_meta": {"timeout_ms": 200}})
        error = self.replies(1)[call]["error"]
        self.assertEqual(error["data"]["failure"], "timeout", error)
        # world 1 stopped at its next step: served again, far short of a million steps
        self.assertLess(self.steps(1), before + 1000000)


class StopTest(unittest.TestCase):
    """simgate stops at once with a step_many under way (its worlds stop at their next step)."""

    def test_simgate_stops_while_a_call_steps_its_worlds(self):
        world_test.ARGS = ARGS
        with tempfile.TemporaryDirectory() as workdir:
            gateway = world_test.Gateway(workdir, edit=with_worlds)
            rpc = world_test.Lines(gateway.jsonrpc_port)
            try:
                rpc.sock.sendall((json.dumps({"jsonrpc": "2.0", "id": 1, "method": "simulation.step_many",
                                              "params": {"n": 1000000, "observe": []}}) + "\n").encode())
                status = rpc.ask(json.dumps({"jsonrpc": "2.0", "id": 2, "method": "simulation.list_worlds"}))
                self.assertEqual(json.loads(status)["id"], 2)  # answered: the call is under way
                started = time.monotonic()
                self.assertEqual(gateway.stop(), 0)
                # a million steps of three worlds take tens of seconds: stopped long before that
                self.assertLess(time.monotonic() - started, 5.0)
            finally:
                rpc.close()


class QuotaTest(WorldsGateway):
    edit = staticmethod(lambda config: config.update(worlds={"count": 2, "max": 3}))

    def test_create_world_is_refused_at_the_configured_most_saying_so(self):
        self.assertEqual(self.rpc("simulation.create_world")["result"]["name"], "w2")
        error = self.rpc("simulation.create_world")["error"]
        self.assertIn("3 worlds run, the most this simgate allows", error["message"])
        self.assertIn('"max": 3', error["message"])
        self.assertEqual((error["data"]["count"], error["data"]["max"]), (3, 3), error)
        self.assertEqual(self.rpc("simulation.list_worlds")["result"]["count"], 3)
        # deleting one makes room
        self.rpc("simulation.delete_world", {"world": 1})
        self.assertEqual(self.rpc("simulation.create_world")["result"]["name"], "w3")


class MemoryQuotaTest(WorldsGateway):
    # a demo world holds 14.9 MB (MuJoCo's model and data): two fit in 40 MB, three do not
    edit = staticmethod(lambda config: config.update(worlds={"count": 2, "max_memory_mb": 40}))

    def test_create_world_is_refused_past_the_memory_allowed_saying_so(self):
        listed = self.rpc("simulation.list_worlds")["result"]
        self.assertEqual(listed["max_memory_bytes"], 40000000)
        self.assertEqual(listed["memory_bytes"], sum(w["memory_bytes"] for w in listed["worlds"]))
        error = self.rpc("simulation.create_world")["error"]
        self.assertIn("a world of this scene holds", error["message"])
        self.assertIn("of the 40.0 MB the config allows", error["message"])
        data = error["data"]
        self.assertEqual(data["memory_bytes"], listed["memory_bytes"])
        self.assertGreater(data["memory_bytes"] + data["world_memory_bytes"], data["max_memory_bytes"])
        # nothing was made: no world w2 anywhere, the count as it was
        self.assertEqual(self.rpc("simulation.list_worlds")["result"]["count"], 2)
        methods = [m["name"] for m in self.rpc("rpc.discover")["result"]["methods"]]
        self.assertFalse([m for m in methods if m.startswith("w2/")])



class SceneWorldsTest(WorldsGateway):
    # world 1 of another scene, given by the config (worlds.scenes), not by a client
    edit = staticmethod(lambda config: config.update(worlds={"count": 3, "scenes": {"1": LIFT}}))

    def test_a_world_runs_the_scene_the_config_gives_it_with_the_robots(self):
        listed = {w["name"]: w for w in self.rpc("simulation.list_worlds")["result"]["worlds"]}
        self.assertEqual({name: w["scene"] for name, w in listed.items()}, {"w0": None, "w1": LIFT, "w2": None})
        self.assertEqual({name: w["actuators"] for name, w in listed.items()}, {"w0": 2, "w1": 3, "w2": 2})
        self.assertIn("result", self.rpc("w1/simulation.get_object_pose", ["lift"]))
        for prefix in ("", "w2/"):  # the config's scene
            self.assertIn("error", self.rpc(prefix + "simulation.get_object_pose", ["lift"]))
        for prefix in ("", "w1/", "w2/"):
            self.assertEqual(self.rpc(prefix + "simulation.list_robots")["result"], ["robot", "human"])
        # stepped together, each world with an action of its own size
        stepped = self.rpc("simulation.step_many", {"worlds": [0, 1], "n": 5, "observe": ["ctrl"],
                                                    "actions": [[0.3, -0.2], [0.3, -0.2, 20.0]]})["result"]
        self.assertEqual([(w["world"], w["steps_done"], w["ctrl"]) for w in stepped["worlds"]],
                         [(0, 5, [0.3, -0.2]), (1, 5, [0.3, -0.2, 20.0])])
        error = self.rpc("simulation.step_many", {"worlds": [1], "actions": [[0.3, -0.2]]})["error"]
        self.assertEqual(error["data"]["parameter"], "actions[0]", error)
        self.assertIn("world 1 has 3 actuators", error["message"])


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--simgate", required=True)
    parser.add_argument("--source-dir", required=True)
    ARGS, rest = parser.parse_known_args()
    ARGS.source_dir = os.path.abspath(ARGS.source_dir)
    write_scenes(ARGS.source_dir)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
