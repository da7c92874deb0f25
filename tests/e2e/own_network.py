"""What the e2e tests that need a network of their own share (remote_peer_test.py,
hosts_test.py): their arguments, and running the test script again inside a new user and
network namespace (`unshare -rn`), where nothing reaches a real network and whatever the test
makes there goes with it."""
import argparse
import os
import subprocess
import sys


def arguments():
    """(ARGS, the rest for unittest): --simgate and --source-dir (made absolute), and
    --in-namespace, which the script's second run inside the namespace gets."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--simgate", required=True)
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--in-namespace", action="store_true")
    args, rest = parser.parse_known_args()
    args.source_dir = os.path.abspath(args.source_dir)
    args.simgate = os.path.abspath(args.simgate)
    return args, rest


def run_inside(script, timeout):
    """The exit status of `script` run again with these arguments in a new user and network
    namespace (bounded by `timeout` seconds)."""
    return subprocess.run(["unshare", "-rn", sys.executable, script, "--in-namespace"] + sys.argv[1:],
                          timeout=timeout).returncode
