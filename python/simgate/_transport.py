"""Message transports under the client: newline-framed TCP and WebSocket (RFC 6455).

A transport moves whole messages (bytes without framing) both ways over one TCP connection.
`send` may be called from any thread (writes are serialised). Reading is split in two so that
whichever thread holds the client's read role (`simgate.client`) can read: `fill(timeout)`
appends what the socket has to the transport's buffer (waiting up to `timeout` seconds for
something; ``None``: until something comes) and returns False once the connection has ended;
`take()` removes the next whole message from the buffer, or returns ``None`` when the buffer
holds none. Only one thread at a time may call them (the client's read lock). `receive()` is
both, blocking, for a thread that owns the transport alone. `close` ends the connection from
any thread and wakes a thread waiting in `fill`.
"""

from __future__ import annotations

import base64
import hashlib
import os
import select
import socket
import struct
import threading
from typing import Iterable, List, Optional, Tuple

from .errors import ConnectionClosed, NotAuthorized

_WS_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"  # RFC 6455, section 1.3
_OP_CONT, _OP_TEXT, _OP_BINARY, _OP_CLOSE, _OP_PING, _OP_PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
_MAX_MESSAGE = 256 * 1024 * 1024  # a message larger than this ends the connection
_READ_SIZE = 64 * 1024  # one recv_into at most (a preallocated chunk: no allocation per read)


def _open(host: str, port: int, timeout: float) -> socket.socket:
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as e:
        raise ConnectionClosed(f"cannot connect to {host}:{port}: {e}") from e
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def wait_readable(sock: socket.socket, timeout: Optional[float]) -> bool:
    """Whether `sock` has something to read (data, its end, or an error) within `timeout`
    seconds (``None``: waits until it has). poll where there is one (no FD_SETSIZE limit)."""
    fd = sock.fileno()
    if fd < 0:
        return True  # closed: reading says so at once
    if hasattr(select, "poll"):
        poller = select.poll()
        poller.register(fd, select.POLLIN | select.POLLPRI)
        return bool(poller.poll(None if timeout is None else max(0, int(timeout * 1000 + 0.999))))
    return bool(select.select([fd], [], [], timeout)[0])


class _Reading:
    """The reading half both transports share: the socket, the buffer of bytes read and not
    yet taken, `fill` and `receive`."""

    _sock: socket.socket

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._chunk = memoryview(bytearray(_READ_SIZE))
        self._ended = False
        self.error: Optional[BaseException] = None  # why the connection ended, when not by its end

    def fill(self, timeout: Optional[float] = None) -> bool:
        """Append what the socket has to the buffer, waiting up to `timeout` seconds for
        something (``None``: until something comes; 0: what is there now). False once the
        connection has ended (the peer closed it, it failed, or `close` was called)."""
        if self._ended:
            return False
        try:
            if timeout is not None and not wait_readable(self._sock, timeout):
                return True
            n = self._sock.recv_into(self._chunk)
        except (OSError, ValueError) as e:
            self._ended, self.error = True, e
            return False
        if not n:
            self._ended = True
            return False
        self._buffer += self._chunk[:n]
        return True

    def take(self) -> Optional[bytes]:
        raise NotImplementedError

    def receive(self) -> Optional[bytes]:
        """The next message, waiting for it; ``None`` at the end of the connection."""
        while True:
            message = self.take()
            if message is not None:
                return message
            if not self.fill(None):
                return self.take()

    def fileno(self) -> int:
        return self._sock.fileno()


class LineTransport(_Reading):
    """One message per line (``\\n``-terminated): the jsonrpc and socket transports' framing."""

    def __init__(self, host: str, port: int, timeout: float) -> None:
        super().__init__()
        self._sock = _open(host, port, timeout)
        self._sock.settimeout(None)
        self._scanned = 0  # the buffer's first bytes known to hold no newline
        self._send_lock = threading.Lock()

    def send(self, message: bytes) -> None:
        self.send_many((message,))

    def send_many(self, messages: Iterable[bytes]) -> None:
        """Several messages in one write (they reach the server in one read when they fit)."""
        data = b"".join([m + b"\n" for m in messages])
        with self._send_lock:
            self._sock.sendall(data)

    def take(self) -> Optional[bytes]:
        end = self._buffer.find(b"\n", self._scanned)
        if end < 0:
            self._scanned = len(self._buffer)
            return None
        line = bytes(self._buffer[:end])
        del self._buffer[:end + 1]
        self._scanned = 0
        return line

    def close(self) -> None:
        _shutdown(self._sock)


class WebSocketTransport(_Reading):
    """The client side of RFC 6455 on a plain TCP socket: one text message per JSON text.

    The opening handshake sends a random ``Sec-WebSocket-Key`` and checks the server's
    ``Sec-WebSocket-Accept``; client frames are masked; fragmented messages are joined;
    pings are answered with pongs; a close frame is answered and ends the connection.
    A frame is read once it is whole in the buffer: `take` never waits.
    """

    def __init__(self, host: str, port: int, path: str, timeout: float,
                 token: Optional[str] = None) -> None:
        super().__init__()
        self._sock = _open(host, port, timeout)
        self._send_lock = threading.Lock()
        self._closing = False
        self._parts: List[bytes] = []  # the fragments of the message being received
        self._size = 0
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
        """For the handshake: more bytes, or EOFError."""
        data = self._sock.recv(65536)
        if not data:
            raise EOFError
        self._buffer += data

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

    def _next_frame(self) -> Optional[Tuple[bool, int, bytes]]:
        """The buffer's first frame (fin, opcode, payload) when it is whole, removed from it;
        None when it is not whole yet."""
        buf = self._buffer
        if len(buf) < 2:
            return None
        b0, b1 = buf[0], buf[1]
        if b0 & 0x70:
            raise ConnectionClosed("WebSocket: a frame with reserved bits set (no extension was agreed)")
        n, pos = b1 & 0x7F, 2
        if n == 126:
            if len(buf) < 4:
                return None
            (n,), pos = struct.unpack_from("!H", buf, 2), 4
        elif n == 127:
            if len(buf) < 10:
                return None
            (n,), pos = struct.unpack_from("!Q", buf, 2), 10
        if n > _MAX_MESSAGE:
            raise ConnectionClosed(f"WebSocket: a frame of {n} bytes (more than {_MAX_MESSAGE})")
        mask = None
        if b1 & 0x80:  # servers do not mask; accepted anyway
            if len(buf) < pos + 4:
                return None
            mask, pos = bytes(buf[pos:pos + 4]), pos + 4
        if len(buf) < pos + n:
            return None
        payload = bytes(buf[pos:pos + n])
        del buf[:pos + n]
        return bool(b0 & 0x80), b0 & 0x0F, _xor(payload, mask) if mask else payload

    def take(self) -> Optional[bytes]:
        while not self._ended:
            frame = self._next_frame()
            if frame is None:
                return None
            fin, opcode, payload = frame
            if opcode == _OP_PING:
                self._write_quietly(self._frame(_OP_PONG, payload))
            elif opcode == _OP_PONG:
                pass
            elif opcode == _OP_CLOSE:
                if not self._closing:  # answer the server's close with its code
                    self._closing = True
                    self._write_quietly(self._frame(_OP_CLOSE, payload[:2]))
                self._ended = True  # fill says so from now on
            elif (opcode == _OP_CONT) != bool(self._parts):
                raise ConnectionClosed(f"WebSocket: opcode {opcode} out of place in a message")
            elif opcode not in (_OP_CONT, _OP_TEXT, _OP_BINARY):
                raise ConnectionClosed(f"WebSocket: unknown opcode {opcode}")
            else:
                self._parts.append(payload)
                self._size += len(payload)
                if self._size > _MAX_MESSAGE:
                    raise ConnectionClosed(f"WebSocket: a message over {_MAX_MESSAGE} bytes")
                if fin:
                    message = b"".join(self._parts)
                    self._parts, self._size = [], 0
                    return message
        return None

    def _write_quietly(self, data: bytes) -> None:
        try:
            self._write(data)
        except OSError:
            pass  # the connection is going: reading says so

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
