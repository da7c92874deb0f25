"""Message transports under the client: newline-framed TCP and WebSocket (RFC 6455).

A transport moves whole messages (bytes without framing) both ways over one TCP connection:
`send` may be called from any thread (writes are serialised), `receive` only from the
connection's reader thread; it blocks until a message arrives and returns ``None`` at the
end of the connection. `close` ends it from any thread and wakes a blocked `receive`.
"""

from __future__ import annotations

import base64
import hashlib
import os
import socket
import struct
import threading
from typing import Iterable, List, Optional, Tuple

from .errors import ConnectionClosed, NotAuthorized

_WS_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"  # RFC 6455, section 1.3
_OP_CONT, _OP_TEXT, _OP_BINARY, _OP_CLOSE, _OP_PING, _OP_PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
_MAX_MESSAGE = 256 * 1024 * 1024  # a message larger than this ends the connection


def _open(host: str, port: int, timeout: float) -> socket.socket:
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as e:
        raise ConnectionClosed(f"cannot connect to {host}:{port}: {e}") from e
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


class LineTransport:
    """One message per line (``\\n``-terminated): the jsonrpc and socket transports' framing."""

    def __init__(self, host: str, port: int, timeout: float) -> None:
        self._sock = _open(host, port, timeout)
        self._sock.settimeout(None)
        self._reader = self._sock.makefile("rb")
        self._send_lock = threading.Lock()

    def send(self, message: bytes) -> None:
        self.send_many((message,))

    def send_many(self, messages: Iterable[bytes]) -> None:
        """Several messages in one write (they reach the server in one read when they fit)."""
        data = b"".join(m + b"\n" for m in messages)
        with self._send_lock:
            self._sock.sendall(data)

    def receive(self) -> Optional[bytes]:
        line = self._reader.readline()
        if not line:
            return None
        return line[:-1] if line.endswith(b"\n") else line

    def close(self) -> None:
        _shutdown(self._sock)


class WebSocketTransport:
    """The client side of RFC 6455 on a plain TCP socket: one text message per JSON text.

    The opening handshake sends a random ``Sec-WebSocket-Key`` and checks the server's
    ``Sec-WebSocket-Accept``; client frames are masked; fragmented messages are joined;
    pings are answered with pongs; a close frame is answered and ends the connection.
    """

    def __init__(self, host: str, port: int, path: str, timeout: float,
                 token: Optional[str] = None) -> None:
        self._sock = _open(host, port, timeout)
        self._send_lock = threading.Lock()
        self._buffer = bytearray()
        self._closing = False
        try:
            self._handshake(host, port, path or "/", token)
        except BaseException:
            _shutdown(self._sock)
            raise
        self._sock.settimeout(None)

    def _handshake(self, host: str, port: int, path: str, token: Optional[str]) -> None:
        key = base64.b64encode(os.urandom(16)).decode()
        lines = [f"GET {path} HTTP/1.1", f"Host: {host}:{port}", "Upgrade: websocket",
                 "Connection: Upgrade", f"Sec-WebSocket-Key: {key}", "Sec-WebSocket-Version: 13"]
        if token is not None:
            lines.append(f"Authorization: Bearer {token}")
        self._sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        while b"\r\n\r\n" not in self._buffer:
            if len(self._buffer) > 65536:
                raise ConnectionClosed(f"ws://{host}:{port}{path}: the upgrade's answer has no end")
            self._fill()
        head, _, rest = bytes(self._buffer).partition(b"\r\n\r\n")
        self._buffer = bytearray(rest)  # frames the server sent right after its answer
        status_line, *header_lines = head.decode("latin-1").split("\r\n")
        headers = {}
        for line in header_lines:
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
        parts = status_line.split(" ", 2)
        if len(parts) < 2 or parts[1] != "101":
            error = NotAuthorized if len(parts) > 1 and parts[1] == "401" else ConnectionClosed
            raise error(f"ws://{host}:{port}{path}: the server refused the upgrade: {status_line}")
        expected = base64.b64encode(hashlib.sha1(key.encode() + _WS_GUID).digest()).decode()
        if headers.get("upgrade", "").lower() != "websocket" or \
                "upgrade" not in headers.get("connection", "").lower():
            raise ConnectionClosed(f"ws://{host}:{port}{path}: not a WebSocket upgrade: {head!r}")
        if headers.get("sec-websocket-accept") != expected:
            raise ConnectionClosed(f"ws://{host}:{port}{path}: Sec-WebSocket-Accept is "
                                   f"{headers.get('sec-websocket-accept')!r}, expected {expected!r}")

    def _fill(self) -> None:
        data = self._sock.recv(65536)
        if not data:
            raise EOFError
        self._buffer += data

    def _take(self, n: int) -> bytes:
        while len(self._buffer) < n:
            self._fill()
        data = bytes(self._buffer[:n])
        del self._buffer[:n]
        return data

    def _frame(self, opcode: int, payload: bytes) -> bytes:
        """One final, masked client frame."""
        n = len(payload)
        if n < 126:
            head = struct.pack("!BB", 0x80 | opcode, 0x80 | n)
        elif n < 65536:
            head = struct.pack("!BBH", 0x80 | opcode, 0x80 | 126, n)
        else:
            head = struct.pack("!BBQ", 0x80 | opcode, 0x80 | 127, n)
        mask = os.urandom(4)
        return head + mask + _xor(payload, mask)

    def send(self, message: bytes) -> None:
        self._write(self._frame(_OP_TEXT, message))

    def send_many(self, messages: Iterable[bytes]) -> None:
        self._write(b"".join(self._frame(_OP_TEXT, m) for m in messages))

    def _write(self, data: bytes) -> None:
        with self._send_lock:
            self._sock.sendall(data)

    def _read_frame(self) -> Tuple[bool, int, bytes]:
        b0, b1 = self._take(2)
        if b0 & 0x70:
            raise ConnectionClosed("WebSocket: a frame with reserved bits set (no extension was agreed)")
        n = b1 & 0x7F
        if n == 126:
            (n,) = struct.unpack("!H", self._take(2))
        elif n == 127:
            (n,) = struct.unpack("!Q", self._take(8))
        if n > _MAX_MESSAGE:
            raise ConnectionClosed(f"WebSocket: a frame of {n} bytes (more than {_MAX_MESSAGE})")
        mask = self._take(4) if b1 & 0x80 else None  # servers do not mask; accepted anyway
        payload = self._take(n)
        return bool(b0 & 0x80), b0 & 0x0F, _xor(payload, mask) if mask else payload

    def receive(self) -> Optional[bytes]:
        parts: List[bytes] = []
        size = 0
        try:
            while True:
                fin, opcode, payload = self._read_frame()
                if opcode == _OP_PING:
                    self._write(self._frame(_OP_PONG, payload))
                elif opcode == _OP_PONG:
                    pass
                elif opcode == _OP_CLOSE:
                    if not self._closing:  # answer the server's close with its code
                        self._closing = True
                        self._write(self._frame(_OP_CLOSE, payload[:2]))
                    return None
                elif (opcode == _OP_CONT) != bool(parts):
                    raise ConnectionClosed(f"WebSocket: opcode {opcode} out of place in a message")
                elif opcode not in (_OP_CONT, _OP_TEXT, _OP_BINARY):
                    raise ConnectionClosed(f"WebSocket: unknown opcode {opcode}")
                else:
                    parts.append(payload)
                    size += len(payload)
                    if size > _MAX_MESSAGE:
                        raise ConnectionClosed(f"WebSocket: a message over {_MAX_MESSAGE} bytes")
                    if fin:
                        return b"".join(parts)
        except (EOFError, OSError):
            return None

    def close(self) -> None:
        if not self._closing:
            self._closing = True
            try:
                self._write(self._frame(_OP_CLOSE, struct.pack("!H", 1000)))
            except OSError:
                pass
        _shutdown(self._sock)


def _xor(data: bytes, mask: bytes) -> bytes:
    """`data` XOR the 4-byte `mask` repeated (RFC 6455, section 5.3), as one big integer."""
    n = len(data)
    if n == 0:
        return b""
    key = (mask * (n // 4 + 1))[:n]
    return (int.from_bytes(data, "big") ^ int.from_bytes(key, "big")).to_bytes(n, "big")


def _shutdown(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    sock.close()
