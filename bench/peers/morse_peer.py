#!/usr/bin/python3
"""MORSE's own SocketRequestManager, run outside Blender, serving the seed's `add`.

This is the peer the socket transport is compared with: the code of Debian's
python3-morse-simulator (morse/middleware/socket_request_manager.py), unmodified, driven by
the seed's standalone loop `while True: req_manager.process()`. Stubs, all in this file:
  * the server binds 127.0.0.1 instead of all interfaces: socket.socket.bind is wrapped
    for the duration of initialization() so any host MORSE asks for becomes 127.0.0.1;
  * the port comes from --port (0 = ephemeral; MORSE's module global SERVER_PORT is set
    before the manager is created) and is printed as {"port": N} on stdout;
  * the loop stops on SIGTERM/SIGINT or after --max-seconds (a bounded run).
MORSE polls with select(timeout=0), so the loop spins a CPU, as it does inside Blender;
inside Blender process() runs once per frame (60 Hz), so this is MORSE at its fastest.

Usage: /usr/bin/python3 bench/peers/morse_peer.py [--port 0] [--max-seconds 600]
"""
import argparse
import json
import signal
import socket
import sys
import time
import warnings


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--max-seconds", type=float, default=600)
    args = parser.parse_args()

    warnings.simplefilter("ignore")
    from morse.middleware import socket_request_manager as srm

    # 127.0.0.1 only, on the requested port
    srm.SERVER_HOST = "127.0.0.1"
    srm.SERVER_PORT = args.port
    original_bind = socket.socket.bind

    def loopback_bind(sock, address):
        if isinstance(address, tuple) and sock.family == socket.AF_INET:
            address = ("127.0.0.1",) + tuple(address[1:])
        return original_bind(sock, address)

    socket.socket.bind = loopback_bind
    try:
        def add(a, b):
            return a + b

        req_manager = srm.SocketRequestManager()
        req_manager.register_service("test_component", add)
    finally:
        socket.socket.bind = original_bind
    if req_manager._server is None:
        print("morse_peer: MORSE could not bind its server socket", file=sys.stderr)
        return 1
    port = req_manager._server.getsockname()[1]
    print(json.dumps({"port": port}), flush=True)

    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    deadline = time.monotonic() + args.max_seconds
    checks = 0
    while not stop:
        # the seed's loop; the clock is read every 1000 iterations only
        req_manager.process()
        checks += 1
        if checks % 1000 == 0 and time.monotonic() > deadline:
            break
    req_manager.finalization()
    return 0


if __name__ == "__main__":
    sys.exit(main())
