#!/usr/bin/python3
"""E2E: simgates on several hosts, one client over DDS (issue #43, docs/worlds.md "Across hosts").

Three "hosts", network namespaces of the test's own, on one bridge (10.203.78.0/24), so
nothing leaves them:
- the client's host: the script re-runs itself in a new user and network namespace
  (`unshare -rn`), which holds the bridge (10.203.78.3);
- hosts A and B (10.203.78.1, .2): two more network namespaces (`unshare -n`, held by a
  sleeping process), each joined to the bridge by a veth pair; each runs `simgate run`
  (world_test's Gateway, through `nsenter`) with "worlds": 3, paused, its DDS transport in
  partition hostA / hostB, Cyclone on its veth only, multicast off, the three addresses as
  peers.
The client (Cyclone on the bridge, the same peers) lists both hosts' worlds with `simgate list
--transport dds --partition PATTERN` (text and --json), and steps w1/simulation on each host
with `simgate call --partition hostX`, checking with `simulation list_worlds` that only that
world of that host stepped. A pattern matching no simgate, and a pattern given to `call`,
are refused saying so. Every wait is bounded. Exit 77 (skipped) when this machine cannot
make user and network namespaces.
"""
import json
import os
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import own_network  # noqa: E402  (arguments, the namespace of its own)
import world_test  # noqa: E402  (its Gateway: `simgate run` of a changed config, stopped cleanly)

ARGS = None
TIMEOUT = world_test.TIMEOUT  # seconds, any single wait
SKIPPED = 77                  # ctest's SKIP_RETURN_CODE for this test
WORLDS = 3
BRIDGE = "sgbr"
SUBNET = "10.203.78."
CLIENT_ADDRESS = SUBNET + "3"
HOSTS = {"hostA": SUBNET + "1", "hostB": SUBNET + "2"}
PEERS = list(HOSTS.values()) + [CLIENT_ADDRESS]


def sh(*command):
    subprocess.run(command, check=True, timeout=TIMEOUT, capture_output=True)


def cyclone_xml(interface):
    """Cyclone on `interface` only, multicast off, discovery by unicast to every host."""
    peers = "".join('<Peer address="%s"/>' % address for address in PEERS)
    return ('<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any"><General><Interfaces>'
            '<NetworkInterface name="%s" multicast="false"/></Interfaces>'
            '<AllowMulticast>false</AllowMulticast></General><Discovery>'
            '<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>'
            '<Peers>%s</Peers></Discovery></Domain></CycloneDDS>' % (interface, peers))


class Host:
    """A network namespace of its own, held by a sleeping process, joined to the bridge by a veth
    pair (`veth` inside, `veth`-br on the bridge), with `address` on it and loopback up."""

    def __init__(self, name, address):
        self.name = name
        self.veth = "v" + name  # at most 15 characters, with "-br"
        self.holder = subprocess.Popen(["unshare", "-n", "sleep", str(10 * TIMEOUT)])
        mine = os.readlink("/proc/self/ns/net")
        deadline = time.monotonic() + TIMEOUT
        while os.readlink("/proc/%d/ns/net" % self.holder.pid) == mine:
            if self.holder.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("unshare -n did not make a network namespace for " + name)
            time.sleep(0.01)  # polling for the child's unshare; bounded by the deadline
        self.enter = ["nsenter", "-t", str(self.holder.pid), "-n"]
        sh("ip", "link", "add", self.veth, "type", "veth", "peer", "name", self.veth + "-br")
        sh("ip", "link", "set", self.veth, "netns", str(self.holder.pid))
        sh("ip", "link", "set", self.veth + "-br", "master", BRIDGE)
        sh("ip", "link", "set", self.veth + "-br", "up")
        sh(*self.enter, "ip", "addr", "add", address + "/24", "dev", self.veth)
        sh(*self.enter, "ip", "link", "set", self.veth, "up")
        sh(*self.enter, "ip", "link", "set", "lo", "up")

    def close(self):
        self.holder.kill()  # its namespace goes with it, and the veth pair with the namespace
        self.holder.wait(timeout=TIMEOUT)


class HostsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        world_test.ARGS = ARGS
        cls.workdir = tempfile.TemporaryDirectory(prefix="simgate-hosts-")
        cls.hosts, cls.gateways = [], {}
        try:
            sh("ip", "link", "set", "lo", "up")
            sh("ip", "link", "add", BRIDGE, "type", "bridge")
            sh("ip", "addr", "add", CLIENT_ADDRESS + "/24", "dev", BRIDGE)
            sh("ip", "link", "set", BRIDGE, "up")
            for name, address in HOSTS.items():
                host = Host(name, address)
                cls.hosts.append(host)
                workdir = os.path.join(cls.workdir.name, name)
                os.mkdir(workdir)

                def edit(config, host=host):
                    config["worlds"] = WORLDS
                    config["transports"]["dds"]["options"].update(
                        partition=host.name, config=cyclone_xml(host.veth))
                cls.gateways[name] = world_test.Gateway(workdir, edit=edit, prefix=host.enter)
        except BaseException:
            cls.stop_all()
            raise

    @classmethod
    def stop_all(cls):
        codes = {name: gateway.stop() for name, gateway in cls.gateways.items()}
        for host in cls.hosts:
            host.close()
        cls.workdir.cleanup()
        return codes

    @classmethod
    def tearDownClass(cls):
        codes = cls.stop_all()
        assert all(code == 0 for code in codes.values()), "simgate run exited with %s" % codes

    def simgate(self, command, *args, timeout=20):
        """`simgate COMMAND --transport dds --dds-config <the client's> ARGS`: (code, out, err)."""
        done = subprocess.run([ARGS.simgate, command, "--transport", "dds", "--dds-config", cyclone_xml(BRIDGE),
                               "--timeout", str(timeout)] + list(args),
                              capture_output=True, text=True, timeout=TIMEOUT)
        return done.returncode, done.stdout, done.stderr

    def steps(self, host):
        """World name -> steps taken, on `host` (simulation list_worlds, through DDS)."""
        code, out, err = self.simgate("call", "--partition", host, "simulation", "list_worlds")
        self.assertEqual(code, 0, out + err)
        return {w["name"]: w["steps"] for w in json.loads(out)["worlds"]}

    def test_1_list_shows_each_host_with_its_worlds_and_services(self):
        code, out, err = self.simgate("list", "--partition", "*")
        self.assertEqual(code, 0, out + err)
        sections = out.split("\n\n")
        self.assertEqual(len(sections), 2, out)
        for section, name in zip(sections, sorted(HOSTS)):
            lines = section.splitlines()
            self.assertRegex(lines[0], r"^partition %s: worlds w0, w1, w2; server [0-9a-f]{32}$" % name)
            self.assertIn("  simulation step(n=1)", section)
            self.assertIn("  w1/simulation step(n=1)", section)
            self.assertIn("  w2/robot.motion set_speed(v, w)", section)
            self.assertIn("  robot.pose stream OUT pose", section)  # world 0's streams
            self.assertTrue(all(line.startswith("  ") for line in lines[1:]), section)

        code, out, err = self.simgate("list", "--partition", "host?", "--json")
        self.assertEqual(code, 0, out + err)
        simgates = json.loads(out)
        self.assertEqual([s["partition"] for s in simgates], sorted(HOSTS))
        self.assertNotEqual(simgates[0]["server"], simgates[1]["server"])
        for simgate in simgates:
            self.assertEqual(simgate["worlds"], ["w0", "w1", "w2"])
            listed = {(s["component"], s["name"]) for s in simgate["services"]}
            self.assertIn(("w1/simulation", "step"), listed)
            self.assertIn(("robot.motion", "set_speed"), listed)

        # a partition named in full: that simgate, listed as ever (no partition line)
        code, out, err = self.simgate("list", "--partition", "hostB")
        self.assertEqual(code, 0, out + err)
        self.assertFalse(out.startswith("partition"), out)
        self.assertIn("\nw2/robot.motion set_speed(v, w)", out)

    def test_2_steps_world_1_of_each_host_and_nothing_else(self):
        before = {host: self.steps(host) for host in HOSTS}
        expected = {host: dict(worlds) for host, worlds in before.items()}
        for host, n in (("hostA", 3), ("hostB", 5)):
            code, out, err = self.simgate("call", "--partition", host, "w1/simulation", "step", str(n))
            self.assertEqual(code, 0, out + err)
            self.assertIn("steps_done", out)
            expected[host]["w1"] += n
            self.assertEqual({h: self.steps(h) for h in HOSTS}, expected)

    def test_3_a_pattern_matching_no_simgate_is_an_error_saying_so(self):
        code, out, err = self.simgate("list", "--partition", "nohost*", timeout=2)
        self.assertEqual(code, 1, out + err)
        self.assertIn("no simgate in domain 0 whose partition matches 'nohost*' within 2000 ms", err)

    def test_4_a_pattern_calls_every_host_at_once(self):
        # `call` with a pattern: the call on each simgate it matches, a JSON line each
        before = {host: self.steps(host) for host in HOSTS}
        code, out, err = self.simgate("call", "--partition", "host*", "simulation", "step_many", "n=4",
                                      "observe=[]")
        self.assertEqual(code, 0, out + err)
        lines = [json.loads(line) for line in out.splitlines()]
        self.assertEqual([line["partition"] for line in lines], sorted(HOSTS))
        for line in lines:
            self.assertEqual(line["status"], "SUCCESS", line)
            self.assertRegex(line["server"], "^[0-9a-f]{32}$")
            self.assertEqual([w["steps_done"] for w in line["result"]["worlds"]], [4, 4, 4], line)
        self.assertEqual({h: self.steps(h) for h in HOSTS},
                         {h: {w: n + 4 for w, n in worlds.items()} for h, worlds in before.items()})

        # one host refusing: its line says why, the other's call is made all the same; exit 1
        code, out, err = self.simgate("call", "--partition", "host?", "w2/simulation", "step", "n=-1")
        self.assertEqual(code, 1, out + err)
        lines = [json.loads(line) for line in out.splitlines()]
        self.assertEqual([(line["partition"], line["status"]) for line in lines],
                         [("hostA", "FAILED"), ("hostB", "FAILED")])
        self.assertIn("n", lines[0]["message"])
        self.assertIn("2 of 2 simgates did not succeed", err)

    def test_5_a_command_for_one_simgate_names_its_partition(self):
        code, out, err = self.simgate("watch", "--partition", "host*", "robot.pose", "--count", "1")
        self.assertEqual(code, 2, out + err)
        self.assertIn("--partition: 'host*' is a pattern (* or ?)", err)


def main():
    global ARGS
    ARGS, rest = own_network.arguments()
    if not ARGS.in_namespace:
        # a user and network namespace of our own, the client's host: nothing reaches a real
        # network, and the hosts' namespaces and links go with it
        probe = subprocess.run(["unshare", "-rn", "ip", "link", "add", BRIDGE, "type", "bridge"],
                               capture_output=True, text=True, timeout=TIMEOUT)
        if probe.returncode != 0:
            print("skipped: cannot make a user and network namespace with a bridge here "
                  "(unshare -rn ip link add ... type bridge: %s)" % probe.stderr.strip())
            return SKIPPED
        return own_network.run_inside(__file__, 600)
    return 0 if unittest.main(argv=[sys.argv[0]] + rest, exit=False, verbosity=2).result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main())
