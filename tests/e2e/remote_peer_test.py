#!/usr/bin/python3
"""E2E: what a client on another machine meets (issue #17): authentication and the
per-peer connection limit of the socket and JSON-RPC transports.

A non-loopback peer needs a network the test owns: the script re-runs itself in a new user
and network namespace (`unshare -rn`), where loopback is up and also carries 10.77.0.1/32.
simgate listens on 0.0.0.0 of that private namespace; a client connecting to 10.77.0.1 is
seen as the non-loopback peer 10.77.0.1, one connecting to 127.0.0.1 as loopback. Nothing
leaves the namespace. The token comes from the environment (token_env). Every wait bounded.
"""
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import own_network  # noqa: E402  (arguments, the namespace of its own)

ARGS = None
TIMEOUT = 30  # seconds, any single wait
REMOTE = "10.77.0.1"
TOKEN = "c2ltZ2F0ZS10ZXN0LXRva2VuLTEyMzQ1Ng"
PER_PEER = 3


def read_line(sock):
    """One line without its newline; b"" when the server closed first."""
    data = b""
    while not data.endswith(b"\n"):
        chunk = sock.recv(1)
        if not chunk:
            return data
        data += chunk
    return data.rstrip(b"\n")


def connect(host, port):
    s = socket.create_connection((host, port), timeout=TIMEOUT)
    s.settimeout(TIMEOUT)
    return s


class Gateway:
    """`simgate run` on the demo scene, socket and JSON-RPC on 0.0.0.0 (of the namespace)."""

    def __init__(self, workdir):
        with open(os.path.join(ARGS.source_dir, "config", "demo.json")) as f:
            config = json.load(f)
        config["scene"]["mjcf"] = os.path.join(ARGS.source_dir, "config", "scenes", "demo.xml")
        auth = {"token_env": "SIMGATE_TEST_TOKEN"}
        common = {"host": "0.0.0.0", "port": 0, "auth": auth, "max_connections_per_peer": PER_PEER}
        config["transports"] = {"socket": {"plugin": "socket", "options": dict(common)},
                                "jsonrpc": {"plugin": "jsonrpc", "options": dict(common)}}
        config["services"] = {"default": ["socket", "jsonrpc"]}
        config.pop("streams", None)  # no datastream ports: not this test's subject
        config["log_level"] = "info"
        self.config_path = os.path.join(workdir, "remote.json")
        with open(self.config_path, "w") as f:
            json.dump(config, f)
        endpoints = os.path.join(workdir, "endpoints.json")
        self.log = open(os.path.join(workdir, "gateway.log"), "w+")
        env = dict(os.environ, SIMGATE_TEST_TOKEN=TOKEN)
        self.process = subprocess.Popen([ARGS.simgate, "run", self.config_path, "--endpoints-file", endpoints],
                                        stdout=self.log, stderr=subprocess.STDOUT, env=env)
        deadline = time.monotonic() + TIMEOUT
        while not os.path.exists(endpoints):
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("gateway did not start:\n" + self.output())
            time.sleep(0.01)  # polling for a file the child writes; bounded by the deadline
        with open(endpoints) as f:
            self.ports = {name: int(e[0].rsplit(":", 1)[1]) for name, e in json.load(f).items()}

    def output(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self):
        self.process.send_signal(signal.SIGTERM)
        try:
            return self.process.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            self.process.kill()
            return self.process.wait()


class RemotePeerTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.TemporaryDirectory(prefix="simgate-remote-")
        cls.gateway = Gateway(cls.workdir.name)
        cls.socket_port = cls.gateway.ports["socket"]
        cls.jsonrpc_port = cls.gateway.ports["jsonrpc"]

    @classmethod
    def tearDownClass(cls):
        code = cls.gateway.stop()
        log = cls.gateway.output()
        cls.workdir.cleanup()
        if code != 0:
            raise RuntimeError("gateway exited with %d:\n%s" % (code, log))
        if TOKEN in log:
            raise RuntimeError("the token was written to the log")

    def rpc(self, sock, method, params=None, id=1):
        message = {"jsonrpc": "2.0", "id": id, "method": method}
        if params is not None:
            message["params"] = params
        sock.sendall(json.dumps(message).encode() + b"\n")
        line = read_line(sock)
        return json.loads(line) if line else None

    # ---- socket transport

    def test_socket_loopback_clients_need_no_token(self):
        with connect("127.0.0.1", self.socket_port) as s:
            s.sendall(b"1 simulation list_robots\n")
            self.assertEqual(read_line(s), b'1 SUCCESS ["robot", "human"]')

    def test_socket_remote_client_must_send_the_token_line_first(self):
        with connect(REMOTE, self.socket_port) as s:
            s.sendall(b"1 simulation list_robots\n")
            reply = read_line(s)
            self.assertTrue(reply.startswith(b'1 FAILED "Authentication required: send the line \'auth <token>\''), reply)
            s.sendall(b"auth " + TOKEN.encode() + b"\n")
            self.assertEqual(read_line(s), b"auth SUCCESS")
            s.sendall(b"2 simulation list_robots\n")
            self.assertEqual(read_line(s), b'2 SUCCESS ["robot", "human"]')

    def test_socket_wrong_token_closes_the_connection(self):
        with connect(REMOTE, self.socket_port) as s:
            s.sendall(b"auth " + b"x" * len(TOKEN) + b"\n")
            self.assertEqual(read_line(s), b'auth FAILED "wrong token: connection closed"')
            self.assertEqual(read_line(s), b"")  # closed: one guess per connection

    def test_socket_per_peer_limit_counts_remote_peers_only(self):
        held = [connect(REMOTE, self.socket_port) for _ in range(PER_PEER)]
        try:
            # the held ones are accepted (they are answered)
            for i, s in enumerate(held):
                s.sendall(b"%d simulation list_robots\n" % i)
                self.assertIn(b"FAILED \"Authentication required", read_line(s))
            with connect(REMOTE, self.socket_port) as extra:
                self.assertEqual(read_line(extra), b'- FAILED "too many connections from 10.77.0.1 '
                                                   b'(max_connections_per_peer 3)"')
                self.assertEqual(read_line(extra), b"")
            # loopback clients are not counted against it
            local = [connect("127.0.0.1", self.socket_port) for _ in range(PER_PEER + 2)]
            for s in local:
                s.sendall(b"1 simulation list_robots\n")
                self.assertEqual(read_line(s), b'1 SUCCESS ["robot", "human"]')
            for s in local:
                s.close()
            # one remote leaves: room for another
            held.pop().close()
            deadline = time.monotonic() + TIMEOUT
            while True:
                with connect(REMOTE, self.socket_port) as again:
                    again.sendall(b"auth " + TOKEN.encode() + b"\n")
                    reply = read_line(again)
                    if reply == b"auth SUCCESS" or time.monotonic() > deadline:
                        break
                time.sleep(0.05)  # the server sees the close asynchronously; bounded by the deadline
            self.assertEqual(reply, b"auth SUCCESS")
        finally:
            for s in held:
                s.close()

    # ---- JSON-RPC transport

    def test_jsonrpc_remote_client_must_log_in(self):
        with connect(REMOTE, self.jsonrpc_port) as s:
            r = self.rpc(s, "simulation.list_robots")
            self.assertEqual(r["error"]["code"], -32005, r)
            self.assertIn("rpc.login", r["error"]["message"])
            self.assertEqual(self.rpc(s, "rpc.discover")["error"]["code"], -32005)
            self.assertEqual(self.rpc(s, "rpc.login", {"token": TOKEN}, id=2)["result"], True)
            self.assertEqual(self.rpc(s, "simulation.list_robots", id=3)["result"], ["robot", "human"])

    def test_jsonrpc_wrong_token_closes_the_connection(self):
        with connect(REMOTE, self.jsonrpc_port) as s:
            r = self.rpc(s, "rpc.login", [TOKEN[:-1] + "x"])
            self.assertEqual(r["error"]["code"], -32005, r)
            self.assertEqual(read_line(s), b"")

    def test_jsonrpc_login_takes_the_token_and_nothing_else(self):
        with connect(REMOTE, self.jsonrpc_port) as s:
            self.assertEqual(self.rpc(s, "rpc.login", {"password": TOKEN})["error"]["code"], -32602)
            self.assertEqual(self.rpc(s, "rpc.login", [42])["error"]["code"], -32602)

    def test_jsonrpc_loopback_clients_need_no_login(self):
        with connect("127.0.0.1", self.jsonrpc_port) as s:
            self.assertEqual(self.rpc(s, "simulation.list_robots")["result"], ["robot", "human"])
            self.assertEqual(self.rpc(s, "rpc.login", {"token": TOKEN}, id=2)["result"], True)

    # ---- configuration

    def check(self, auth, env=None):
        with open(self.gateway.config_path) as f:
            config = json.load(f)
        config["transports"]["socket"]["options"]["auth"] = auth
        path = os.path.join(self.workdir.name, "check.json")
        with open(path, "w") as f:
            json.dump(config, f)
        run = subprocess.run([ARGS.simgate, "check", path], capture_output=True, text=True, timeout=TIMEOUT,
                             env=dict(os.environ, **(env or {})))
        return run.returncode, run.stdout + run.stderr

    def test_check_refuses_a_token_in_the_config_and_a_missing_one(self):
        code, out = self.check({"token": TOKEN})
        self.assertNotEqual(code, 0)
        self.assertIn("transports.socket.options.auth.token: a token is never written in the config", out)
        self.assertNotIn(TOKEN, out)
        code, out = self.check({"token_env": "SIMGATE_NO_SUCH_VARIABLE"})
        self.assertNotEqual(code, 0)
        self.assertIn("the environment variable SIMGATE_NO_SUCH_VARIABLE is not set", out)
        code, out = self.check({"token_env": "SIMGATE_TEST_TOKEN"}, {"SIMGATE_TEST_TOKEN": "short"})
        self.assertNotEqual(code, 0)
        self.assertIn("expected at least 16", out)
        code, out = self.check({"token_env": "SIMGATE_TEST_TOKEN"}, {"SIMGATE_TEST_TOKEN": TOKEN})
        self.assertEqual(code, 0, out)


def in_private_network():
    """Sets up loopback (and 10.77.0.1 on it) in the namespace this process runs in."""
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True, timeout=TIMEOUT)
    subprocess.run(["ip", "addr", "add", REMOTE + "/32", "dev", "lo"], check=True, timeout=TIMEOUT)


def main():
    global ARGS
    ARGS, rest = own_network.arguments()
    if not ARGS.in_namespace:
        # a user and network namespace of our own: nothing reaches a real network
        return own_network.run_inside(__file__, 300)
    in_private_network()
    return 0 if unittest.main(argv=[sys.argv[0]] + rest, exit=False).result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main())
