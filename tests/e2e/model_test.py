#!/usr/bin/python3
"""E2E: `simgate run --model FILE.xml` on models nobody on the team wrote (issue #18).

For each of Debian's libmujoco-samples models that MuJoCo 4.0 loads (humanoid, slider_crank)
and the project's own tendon arm (tests/models, standing in for arm26, which 4.0 refuses):
`simgate check --model` accepts it; `simgate run --model` (the transports of a small config:
socket on port 0) serves the robots the model has with their generic components; a client
lists the robots and services, moves a joint of each robot with an armature and reads it
back through armature_pose. pymorse (Debian's python3-morse-simulator) connects to the
humanoid and moves a joint through its proxies. A file that is not a model is refused with
exit 2, naming --model, and so are the samples 4.0 refuses (2.2.2's <composite> particles,
arm26's muscles), with MuJoCo's message, file and line. Every wait is bounded.
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
import warnings

warnings.simplefilter("ignore", DeprecationWarning)  # asyncore/asynchat on Python 3.11
import pymorse  # noqa: E402

ARGS = None
TIMEOUT = 60
MODELS = "/usr/share/mujoco/model"
OWN_MODELS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "models")


class ModelRun:
    """`simgate run --model MODEL CONFIG`, CONFIG giving a socket transport on port 0."""

    def __init__(self, model, workdir, port_base=None):
        """port_base: no CONFIG, `--port port_base` (socket there, JSON-RPC one above)."""
        if port_base is None:
            config = os.path.join(workdir, "transports.json")
            with open(config, "w") as f:
                json.dump({"scene": {"mjcf": "replaced-by-the-model.xml", "realtime_factor": 4.0},
                           "transports": {"socket": {"plugin": "socket", "options": {"port": 0}}},
                           "log_level": "warning"}, f)
            where = [config]
        else:
            where = ["--port", str(port_base)]
        endpoints = os.path.join(workdir, "endpoints.json")
        self.endpoints_file = endpoints
        self.log = open(os.path.join(workdir, "run.log"), "w+")
        self.process = subprocess.Popen([ARGS.simgate, "run", "--model", model, *where, "--endpoints-file", endpoints],
                                        stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + TIMEOUT
        while not os.path.exists(endpoints):
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("simgate run --model did not start:\n" + self.output())
            time.sleep(0.01)  # polling for a file the child writes; bounded by the deadline
        with open(endpoints) as f:
            self.port = int(json.load(f)["socket"][0].rsplit(":", 1)[1])
        self.sock = socket.create_connection(("127.0.0.1", self.port), timeout=TIMEOUT)
        self.reader = self.sock.makefile("rb")
        self.next_id = 0

    def call(self, component, service, *params):
        """One request; returns (status, value)."""
        self.next_id += 1
        rid = str(self.next_id)
        line = "%s %s %s %s\n" % (rid, component, service, json.dumps(list(params)))
        self.sock.sendall(line.encode())
        reply = self.reader.readline().decode().rstrip("\n")
        got_id, status, *rest = reply.split(" ", 2)
        assert got_id == rid, reply
        return status, json.loads(rest[0]) if rest else None

    def output(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self):
        self.sock.close()
        self.process.send_signal(signal.SIGTERM)
        try:
            code = self.process.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait()
        self.log.close()
        return code


class ModelTest(unittest.TestCase):
    def setUp(self):
        self.workdir = tempfile.TemporaryDirectory(prefix="simgate-model-")

    def tearDown(self):
        self.workdir.cleanup()

    def check(self, model, *more):
        run = subprocess.run([ARGS.simgate, "check", "--model", model, *more], capture_output=True, text=True,
                             timeout=TIMEOUT)
        return run.returncode, run.stdout + run.stderr

    def move_a_joint_of_each_robot(self, model, expected_robots):
        code, out = self.check(model)
        self.assertEqual(code, 0, out)
        run = ModelRun(model, self.workdir.name)
        try:
            status, robots = run.call("simulation", "list_robots")
            self.assertEqual(status, "SUCCESS")
            self.assertEqual(robots, expected_robots)
            status, services = run.call("simulation", "list_services")
            names = {(s["component"], s["name"]) for s in services}
            for robot in robots:
                self.assertIn((robot + ".armature", "rotate_joints"), names)
                self.assertIn((robot + ".armature_pose", "get_state"), names)
                self.assertIn((robot + ".actuators", "set_controls"), names)
                status, joints = run.call(robot + ".armature", "get_joints")
                self.assertEqual(status, "SUCCESS")
                joint = joints[0]
                status, state = run.call(robot + ".armature_pose", "get_state")
                before = state[joint]["position"]
                target = before + 0.1
                status, reason = run.call(robot + ".armature", "set_rotation", joint, target)
                if status == "FAILED" and "prismatic" in str(reason):
                    status, reason = run.call(robot + ".armature", "set_translation", joint, target)
                self.assertEqual(status, "SUCCESS", reason)
                self.assertEqual(run.call("time", "sleep", 0.2)[0], "SUCCESS")  # the joint is held there
                status, state = run.call(robot + ".armature_pose", "get_state")
                # a joint without a position servo is set kinematically at every step, and the
                # step's own dynamics (the humanoid falls and lands) move it within that step
                self.assertAlmostEqual(state[joint]["position"], target, delta=0.05, msg=(model, robot, joint))
                # bad input reaches nothing: an unknown joint, NaN
                self.assertEqual(run.call(robot + ".armature", "set_rotation", "no_such_joint", 0.0)[0], "FAILED")
            self.assertEqual(run.call("simulation", "list_robots")[0], "SUCCESS")  # still serving
        finally:
            output = run.output()
            self.assertEqual(run.stop(), 0, output)

    def test_humanoid(self):
        self.move_a_joint_of_each_robot(MODELS + "/humanoid/humanoid.xml", ["torso"])

    def test_tendon_arm(self):
        self.move_a_joint_of_each_robot(os.path.join(OWN_MODELS, "tendon_arm.xml"), ["body1"])

    def test_urdf_arm(self):
        # URDF through MuJoCo's own parser: the base, on its slider, is the robot
        self.move_a_joint_of_each_robot(os.path.join(OWN_MODELS, "urdf_arm.urdf"), ["base"])

    def test_port_base_puts_the_socket_there_and_json_rpc_above(self):
        # two free ports in a row (bounded search; another process may take one meanwhile)
        base = None
        for candidate in range(23000, 23400, 2):
            try:
                with socket.socket() as a, socket.socket() as b:
                    a.bind(("127.0.0.1", candidate))
                    b.bind(("127.0.0.1", candidate + 1))
                base = candidate
                break
            except OSError:
                continue
        self.assertIsNotNone(base, "no two free ports in a row in 23000-23400")
        run = ModelRun(os.path.join(OWN_MODELS, "urdf_arm.urdf"), self.workdir.name, port_base=base)
        try:
            with open(run.endpoints_file) as f:
                endpoints = json.load(f)
            self.assertEqual(endpoints["socket"], ["tcp://127.0.0.1:%d" % base])
            self.assertEqual(endpoints["jsonrpc"], ["tcp://127.0.0.1:%d" % (base + 1)])
            self.assertEqual(run.call("simulation", "list_robots"), ("SUCCESS", ["base"]))
        finally:
            output = run.output()
            self.assertEqual(run.stop(), 0, output)
        # with a CONFIG, or without --model: a usage error
        config = os.path.join(self.workdir.name, "transports.json")
        code, out = self.check(os.path.join(OWN_MODELS, "urdf_arm.urdf"), "--port", "5000", config)
        self.assertEqual(code, 2, out)
        self.assertIn("--port: only for --model without CONFIG", out)

    def test_composite_particles_are_scenery_and_a_floating_base_gets_pose_and_odometry(self):
        # current_mujoco.xml: a pendulum (a robot) and a 3x3 flexcomp (9 particle bodies: scenery)
        code, out = self.check(os.path.join(OWN_MODELS, "current_mujoco.xml"))
        self.assertEqual(code, 0, out)
        self.assertIn("OK (1 robot(s)", out)
        # Debian's humanoid: a free root joint, so pose and odometry besides its armature
        run = ModelRun(MODELS + "/humanoid/humanoid.xml", self.workdir.name)
        try:
            status, pose = run.call("torso.pose", "get_local_data")
            self.assertEqual(status, "SUCCESS")
            self.assertIn("z", pose)
            self.assertEqual(run.call("torso.odometry", "get_local_data")[0], "SUCCESS")
        finally:
            output = run.output()
            self.assertEqual(run.stop(), 0, output)

    def test_every_debian_sample_loads_or_is_refused_with_mujocos_message(self):
        # MuJoCo 4.0 loads these; the 2022 samples it refuses say why, where (exit 2)
        for sample in ("humanoid/humanoid.xml", "humanoid/22_humanoids.xml", "humanoid100/humanoid100.xml",
                       "mug/mug.xml", "slider_crank/slider_crank.xml"):
            code, out = self.check(os.path.join(MODELS, sample))
            self.assertEqual(code, 0, (sample, out))
        for sample, why in (("composite/rope.xml", "Schema violation: unrecognized element\nElement 'composite', line 26"),
                            ("flag/flag.xml", "Element 'composite', line 34"),
                            ("tendon_arm/arm26.xml", "Lengthrange computation did not converge in actuator 1")):
            code, out = self.check(os.path.join(MODELS, sample))
            self.assertEqual(code, 2, (sample, out))
            self.assertIn("--model: expected a loadable MJCF model, found an error: scene '" + os.path.join(MODELS, sample), out)
            self.assertIn(why, out)

    def test_slider_crank(self):
        self.move_a_joint_of_each_robot(MODELS + "/slider_crank/slider_crank.xml", ["body1", "body3"])

    def test_pymorse_drives_the_humanoid(self):
        run = ModelRun(MODELS + "/humanoid/humanoid.xml", self.workdir.name)
        try:
            simu = pymorse.Morse(host="127.0.0.1", port=run.port)  # sends `simulation details`
            try:
                joints = simu.torso.armature.get_joints().result(timeout=TIMEOUT)
                self.assertIn("abdomen_y", joints)
                # async, interruptible: completes once the joint is there
                simu.torso.armature.rotate("abdomen_y", 0.3, 1.0).result(timeout=TIMEOUT)
                state = simu.torso.armature_pose.get_state().result(timeout=TIMEOUT)
                self.assertAlmostEqual(state["abdomen_y"]["position"], 0.3, delta=0.05)
                actuators = simu.torso.actuators.list_actuators().result(timeout=TIMEOUT)
                self.assertEqual(actuators["abdomen_y"]["type"], "motor")
                simu.torso.actuators.set_controls({"abdomen_y": 0.1}).result(timeout=TIMEOUT)
                self.assertEqual(simu.torso.actuators.get_controls().result(timeout=TIMEOUT)["abdomen_y"], 0.1)
            finally:
                # pymorse's close() with wait_publishers=True trips over its own proxies (known bug)
                simu.close(wait_publishers=False)
        finally:
            output = run.output()
            self.assertEqual(run.stop(), 0, output)

    def test_a_file_that_is_not_a_model_is_refused(self):
        bad = os.path.join(self.workdir.name, "not-a-model.xml")
        with open(bad, "w") as f:
            f.write("<mujoco><worldbody><body><geom type='nonsense'/></body></worldbody></mujoco>")
        code, out = self.check(bad)
        self.assertEqual(code, 2, out)
        self.assertIn("--model: expected a loadable MJCF model, found an error", out)
        code, out = self.check(os.path.join(self.workdir.name, "missing.xml"))
        self.assertEqual(code, 2, out)


def main():
    global ARGS
    parser = argparse.ArgumentParser()
    parser.add_argument("--simgate", required=True)
    ARGS, rest = parser.parse_known_args()
    if not os.path.exists(MODELS + "/humanoid/humanoid.xml"):
        print("libmujoco-samples is not installed (scripts/test installs it)")
        return 1
    return 0 if unittest.main(argv=[sys.argv[0]] + rest, exit=False).result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main())
