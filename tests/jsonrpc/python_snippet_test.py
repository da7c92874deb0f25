#!/usr/bin/env python3
"""Runs the 10-line Python client of docs/transports/jsonrpc.md against a server.

    python_snippet_test.py DOC.md SERVER [ARGS...]

SERVER must print "listening on tcp://127.0.0.1:<port>" and serve tests/jsonrpc/test_services.h;
it stops when its stdin closes. Exit code 0 when every check passes.
"""
import re
import subprocess
import sys


def main():
    doc, server = sys.argv[1], sys.argv[2:]
    text = open(doc, encoding="utf-8").read()
    snippet = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    proc = subprocess.Popen(server, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        line = proc.stdout.readline().decode()
        port = int(re.search(r"tcp://127\.0\.0\.1:(\d+)", line).group(1))
        scope = {}
        exec(snippet, scope)  # the documented client, verbatim
        rpc = scope["JsonRpc"](port=port)
        checks = [
            ("positional", rpc.call("robot.arm.add", 1, 2), 3.0),
            ("named with default", rpc.call("robot.arm.greet", name="ada"), "hello, ada"),
            ("discover", rpc.call("rpc.discover")["openrpc"], "1.2.6"),
        ]
        try:
            rpc.call("robot.arm.fail", "jammed")
            checks.append(("error raised", "no exception", "RuntimeError"))
        except RuntimeError as e:
            checks.append(("error raised", e.args[0], -32000))
        failed = [c for c in checks if c[1] != c[2]]
        for name, got, want in checks:
            print(("ok - " if got == want else "not ok - ") + f"{name}: got {got!r}, want {want!r}")
        return 1 if failed else 0
    finally:
        proc.stdin.close()
        proc.wait(timeout=30)


if __name__ == "__main__":
    sys.exit(main())
