"""The client's RFC 6455 framing against a scripted server (what simgate never sends:
fragmented messages, pings between fragments, a wrong Sec-WebSocket-Accept, a close from the
server), checking the client's frames are masked. Every wait is bounded."""

import base64
import hashlib
import socket
import struct
import threading

import pytest

import simgate
from simgate._transport import WebSocketTransport

GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
WAIT = 10


def frame(opcode, payload, fin=True):
    head = bytes([(0x80 if fin else 0) | opcode])
    n = len(payload)
    if n < 126:
        head += bytes([n])
    elif n < 65536:
        head += bytes([126]) + struct.pack("!H", n)
    else:
        head += bytes([127]) + struct.pack("!Q", n)
    return head + payload  # servers do not mask


def read_exactly(conn, n):
    data = b""
    while len(data) < n:
        chunk = conn.recv(n - len(data))
        assert chunk, "the client closed early"
        data += chunk
    return data


def read_client_frame(conn):
    b0, b1 = read_exactly(conn, 2)
    assert b1 & 0x80, "a client frame must be masked"
    n = b1 & 0x7F
    if n == 126:
        (n,) = struct.unpack("!H", read_exactly(conn, 2))
    elif n == 127:
        (n,) = struct.unpack("!Q", read_exactly(conn, 8))
    mask = read_exactly(conn, 4)
    payload = bytes(b ^ mask[i % 4] for i, b in enumerate(read_exactly(conn, n)))
    return b0 & 0x0F, payload


class ScriptedServer:
    """Accepts one upgrade, then runs `script(conn)` on its own thread."""

    def __init__(self, script, accept=None):
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.error = None
        self.thread = threading.Thread(target=self.serve, args=(script, accept), daemon=True)
        self.thread.start()

    def serve(self, script, accept):
        try:
            self.listener.settimeout(WAIT)
            conn, _ = self.listener.accept()
            conn.settimeout(WAIT)
            request = b""
            while b"\r\n\r\n" not in request:
                request += conn.recv(4096)
            key = [line.split(b":", 1)[1].strip() for line in request.split(b"\r\n")
                   if line.lower().startswith(b"sec-websocket-key:")][0]
            accept = accept or base64.b64encode(hashlib.sha1(key + GUID).digest())
            conn.sendall(b"HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n"
                         b"Connection: Upgrade\r\nSec-WebSocket-Accept: " + accept + b"\r\n\r\n")
            script(conn)
            conn.close()
        except Exception as e:  # reported by join()
            self.error = e

    def join(self):
        self.thread.join(WAIT)
        self.listener.close()
        assert not self.thread.is_alive() and self.error is None, self.error


def test_fragments_with_a_ping_between_them_make_one_message_and_the_ping_is_answered():
    def script(conn):
        opcode, payload = read_client_frame(conn)
        assert (opcode, payload) == (1, b"hello")
        conn.sendall(frame(1, b'{"a":', fin=False) + frame(9, b"are you there")
                     + frame(0, b"1,", fin=False) + frame(0, b'"b":2}'))
        assert read_client_frame(conn) == (0xA, b"are you there")
        big = b"x" * 70000  # a 64-bit length
        conn.sendall(frame(2, big))
        conn.sendall(frame(8, struct.pack("!H", 1000)))
        opcode, payload = read_client_frame(conn)
        assert opcode == 8 and payload == struct.pack("!H", 1000)  # the close is answered

    server = ScriptedServer(script)
    ws = WebSocketTransport("127.0.0.1", server.port, "/", WAIT)
    ws.send(b"hello")
    assert ws.receive() == b'{"a":1,"b":2}'
    assert ws.receive() == b"x" * 70000
    assert ws.receive() is None  # the server closed
    ws.close()
    server.join()


def test_a_wrong_accept_key_is_refused():
    server = ScriptedServer(lambda conn: None, accept=b"bm90IHRoZSByaWdodCBrZXk=")
    with pytest.raises(simgate.ConnectionClosed, match="Sec-WebSocket-Accept"):
        WebSocketTransport("127.0.0.1", server.port, "/", WAIT)
    server.join()


def test_a_server_closing_mid_call_fails_the_call():
    def script(conn):
        opcode, payload = read_client_frame(conn)  # the call
        assert opcode == 1 and b'"method":"robot.arm.hold"' in payload
        conn.sendall(frame(8, struct.pack("!H", 1001)))

    server = ScriptedServer(script)
    sim = simgate.connect(f"ws://127.0.0.1:{server.port}/", timeout=WAIT)
    call = sim.submit("robot.arm", "hold", ["k"])
    with pytest.raises(simgate.ConnectionClosed, match="server closed the connection"):
        call.result(WAIT)
    sim.close()
    server.join()
