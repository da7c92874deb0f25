"""The mcp transport's HTTP, byte by byte (raw sockets, the standard library only): what the
kit's HTTP/1.1 connection (kit/http_connection.h) and the transport's rules do with requests
an MCP SDK never sends: pipelined requests, Expect: 100-continue, a chunked body, a body or a
header too large, a malformed request, a page of another origin, no token or a wrong one,
sessions missing, unknown or ended, bodies that are not one JSON-RPC request, a method other
than POST and DELETE, an unserved protocol revision, the rate limit, and a client that leaves
while its call runs (the call is cancelled). Every refusal names its reason and the server
keeps serving.

Usage: mcp_http_test.py SIMGATE run gateway_mcp_http.json --plugin-path DIR
"""

import json
import os
import re
import socket
import subprocess
import sys
import time

TOKEN = f"mcp-http-test-token-{os.getpid()}-0123456789"
CHECKS = 0


def check(condition, what):
    global CHECKS
    CHECKS += 1
    if not condition:
        raise AssertionError("check failed: " + what)


class Gateway:
    def __init__(self, argv):
        env = dict(os.environ, SIMGATE_MCP_TEST_TOKEN=TOKEN)
        self.process = subprocess.Popen(argv, stdout=subprocess.PIPE, env=env, text=True)
        deadline = time.monotonic() + 60
        self.port = None
        while time.monotonic() < deadline:
            line = self.process.stdout.readline()
            if not line:
                break
            m = re.match(r"mcp: http://127\.0\.0\.1:(\d+)/mcp$", line.strip())
            if m:
                self.port = int(m.group(1))
                break
        if self.port is None:
            self.process.kill()
            raise RuntimeError("the gateway did not say where it listens")

    def stop(self):
        self.process.terminate()
        try:
            self.process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()


def read_response(conn, deadline_s=20):
    """One HTTP response (status, headers, body) from `conn` (an Http: its socket, and the
    bytes read past the last response): Content-Length, chunked, or to the end."""
    sock = conn.sock
    sock.settimeout(deadline_s)
    data = conn.pending
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(65536)
        if not chunk:
            raise ConnectionError("closed before a response: " + repr(data[:200]))
        data += chunk
    head, _, rest = data.partition(b"\r\n\r\n")
    head = head.decode()
    status = int(head.split(" ", 2)[1])
    headers = {}
    for line in head.split("\r\n")[1:]:
        name, _, value = line.partition(":")
        headers[name.strip().lower()] = value.strip()
    if status == 100:
        conn.pending = rest
        return status, headers, b""
    if "content-length" in headers:
        n = int(headers["content-length"])
        while len(rest) < n:
            chunk = sock.recv(65536)
            if not chunk:
                raise ConnectionError("closed inside a body")
            rest += chunk
        conn.pending = rest[n:]
        return status, headers, rest[:n]
    if headers.get("transfer-encoding") == "chunked":
        body = b""
        while True:
            while b"\r\n" not in rest:
                rest += sock.recv(65536)
            size_line, _, rest = rest.partition(b"\r\n")
            size = int(size_line, 16)
            while len(rest) < size + 2:
                chunk = sock.recv(65536)
                if not chunk:
                    raise ConnectionError("closed inside a chunk")
                rest += chunk
            body += rest[:size]
            rest = rest[size + 2:]
            if size == 0:
                conn.pending = rest
                return status, headers, body
    while True:
        chunk = sock.recv(65536)
        if not chunk:
            return status, headers, rest
        rest += chunk


def message_of(headers, body):
    """The JSON-RPC message answering a request: the body, or a stream's last event (a client
    must take both, the spec says)."""
    if headers.get("content-type") == "text/event-stream":
        data = [line[6:] for line in body.decode().split("\n") if line.startswith("data: ")]
        return json.loads(data[-1])
    return json.loads(body)


def request_bytes(method, body=b"", headers=None, target="/mcp"):
    lines = [f"{method} {target} HTTP/1.1", "Host: 127.0.0.1"]
    for name, value in (headers or {}).items():
        lines.append(f"{name}: {value}")
    if body and not any(k.lower() == "transfer-encoding" for k in (headers or {})):
        lines.append(f"Content-Length: {len(body)}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode() + body


def base_headers(session=None, token=TOKEN):
    h = {"Content-Type": "application/json", "Accept": "application/json, text/event-stream"}
    if token is not None:
        h["Authorization"] = f"Bearer {token}"
    if session:
        h["Mcp-Session-Id"] = session
    return h


class Http:
    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=20)
        self.pending = b""

    def send(self, data):
        self.sock.sendall(data)

    def post(self, message, session=None, token=TOKEN, extra=None):
        headers = base_headers(session, token)
        headers.update(extra or {})
        body = message if isinstance(message, bytes) else json.dumps(message).encode()
        self.send(request_bytes("POST", body, headers))
        return self.read()

    def read(self):
        return read_response(self)

    def closed_by_server(self):
        self.sock.settimeout(10)
        try:
            rest = self.pending + self.sock.recv(65536)
            return rest == b""
        except (ConnectionResetError, BrokenPipeError):
            return True

    def close(self):
        self.sock.close()


def initialize(port):
    http = Http(port)
    status, headers, body = http.post({"jsonrpc": "2.0", "id": 1, "method": "initialize",
                                       "params": {"protocolVersion": "2025-11-25", "capabilities": {},
                                                  "clientInfo": {"name": "mcp_http_test", "version": "1"}}})
    check(status == 200, f"initialize: {status} {body[:200]}")
    session = headers.get("mcp-session-id")
    check(session and re.fullmatch(r"[0-9a-f]{32}", session), f"a session id of 128 bits: {session}")
    return http, session


def call(n, name, arguments=None):
    return {"jsonrpc": "2.0", "id": n, "method": "tools/call",
            "params": {"name": name, "arguments": arguments or {}}}


def test_pipelined_requests_are_answered_in_order(port):
    http, session = initialize(port)
    ping = json.dumps({"jsonrpc": "2.0", "id": "a", "method": "ping"}).encode()
    listing = json.dumps({"jsonrpc": "2.0", "id": "b", "method": "tools/list"}).encode()
    http.send(request_bytes("POST", ping, base_headers(session)) +
              request_bytes("POST", listing, base_headers(session)))
    s1, _, b1 = http.read()
    s2, _, b2 = http.read()
    check(s1 == 200 and json.loads(b1)["id"] == "a", f"the first answer is the ping's: {b1[:100]}")
    check(s2 == 200 and json.loads(b2)["id"] == "b" and json.loads(b2)["result"]["tools"],
          "the second is the tools/list's")
    http.close()


def test_expect_continue_and_a_chunked_body(port):
    http, session = initialize(port)
    body = json.dumps({"jsonrpc": "2.0", "id": 2, "method": "ping"}).encode()
    headers = base_headers(session)
    headers["Expect"] = "100-continue"
    http.send(request_bytes("POST", b"", headers).rstrip(b"\r\n") + f"\r\nContent-Length: {len(body)}\r\n\r\n".encode())
    status, _, _ = http.read()
    check(status == 100, f"Expect: 100-continue is answered 100 before the body ({status})")
    http.send(body)
    status, _, answer = http.read()
    check(status == 200 and json.loads(answer)["result"] == {}, f"then the request: {status} {answer}")
    headers = base_headers(session)
    headers["Transfer-Encoding"] = "chunked"
    chunked = b"".join(f"{len(part):x}\r\n".encode() + part + b"\r\n" for part in (body[:10], body[10:])) + b"0\r\n\r\n"
    http.send(request_bytes("POST", chunked, headers))
    status, _, answer = http.read()
    check(status == 200 and json.loads(answer)["id"] == 2, f"a chunked body is read: {status} {answer}")
    http.close()


def test_too_large_and_malformed_requests_are_refused_and_closed(port):
    http, session = initialize(port)
    big = b"{" + b" " * 70000 + b"}"
    status, _, body = http.post(big, session)
    check(status == 413 and b"max_message_bytes" in body, f"a body over max_message_bytes: 413 naming it ({status} {body[:200]})")
    check(http.closed_by_server(), "the connection then closes")
    http = Http(port)
    headers = base_headers(session)
    headers["X-Padding"] = "p" * 20000
    http.send(request_bytes("POST", b"{}", headers))
    status, _, body = http.read()
    check(status == 431, f"a header over 16 KiB: 431 ({status} {body[:200]})")
    http = Http(port)
    http.send(b"POST /mcp HTTP/1.1\r\nContent-Length: banana\r\n\r\n")
    status, _, body = http.read()
    check(status == 400 and b"malformed" in body, f"a malformed request: 400 ({status} {body[:200]})")
    check(http.closed_by_server(), "the connection then closes")


def test_origin_and_token(port):
    http, session = initialize(port)
    status, _, body = http.post({"jsonrpc": "2.0", "id": 3, "method": "ping"}, session,
                                extra={"Origin": "http://evil.example"})
    check(status == 403 and b"origin" in body, f"a page of another origin: 403 ({status} {body[:200]})")
    status, _, _ = http.post({"jsonrpc": "2.0", "id": 4, "method": "ping"}, session,
                             extra={"Origin": f"http://127.0.0.1:{port}"})
    check(status == 200, f"the server's own origin is allowed ({status})")
    status, headers, body = http.post({"jsonrpc": "2.0", "id": 5, "method": "ping"}, session, token=None)
    check(status == 401 and headers.get("www-authenticate", "").startswith("Bearer"),
          f"no token: 401 with WWW-Authenticate ({status} {headers})")
    status, _, _ = http.post({"jsonrpc": "2.0", "id": 6, "method": "ping"}, session)
    check(status == 200, "the same connection with the token goes on")
    status, _, body = http.post({"jsonrpc": "2.0", "id": 7, "method": "ping"}, session, token="x" * 20)
    check(status == 403 and b"wrong token" in body, f"a wrong token: 403 ({status} {body[:100]})")
    check(http.closed_by_server(), "one guess per connection: it closes")


def test_sessions_and_bad_messages(port):
    http, session = initialize(port)
    status, _, body = http.post({"jsonrpc": "2.0", "id": 1, "method": "ping"})
    check(status == 400 and b"Mcp-Session-Id" in body, f"no session header: 400 ({status} {body[:200]})")
    status, _, body = http.post({"jsonrpc": "2.0", "id": 1, "method": "ping"}, "0" * 32)
    check(status == 404, f"an unknown session: 404 ({status})")
    status, _, body = http.post(b"{not json", session)
    check(status == 400 and json.loads(body)["error"]["code"] == -32700, f"not JSON: -32700 ({body[:200]})")
    status, _, body = http.post(b"[" * 50000, session)
    check(status == 400 and b"nests deeper" in body, f"deep nesting is refused unparsed: 400 ({body[:200]})")
    status, _, body = http.post([{"jsonrpc": "2.0", "id": 1, "method": "ping"}], session)
    check(status == 400 and b"batch" in body, f"a batch: 400 ({body[:200]})")
    status, _, body = http.post({"jsonrpc": "2.0", "id": 1, "method": "prompts/get"}, session)
    check(status == 200 and json.loads(body)["error"]["code"] == -32601, f"an unknown method: -32601 ({body[:200]})")
    status, _, body = http.post({"jsonrpc": "2.0", "id": 1, "method": "tools/call",
                                 "params": {"name": "no_such_tool", "arguments": {}}}, session)
    check(json.loads(body)["error"]["code"] == -32602 and b"Unknown tool" in body, f"an unknown tool: -32602 ({body[:200]})")
    status, _, body = http.post({"jsonrpc": "2.0", "id": 1, "method": "ping"}, session,
                                extra={"MCP-Protocol-Version": "1999-01-01"})
    check(status == 400 and b"not served" in body, f"an unserved revision: 400 ({body[:200]})")
    status, _, _ = http.post({"jsonrpc": "2.0", "method": "notifications/initialized"}, session)
    check(status == 202, f"a notification: 202 ({status})")
    http.send(request_bytes("PUT", b"", base_headers(session)))
    status, headers, _ = http.read()
    check(status == 405 and "GET" in headers.get("allow", ""), f"PUT: 405 with Allow ({status} {headers})")
    json_only = base_headers(session)
    json_only["Accept"] = "application/json"
    http.send(request_bytes("GET", b"", json_only))
    status, _, _ = http.read()
    check(status == 406, f"GET without Accept: text/event-stream: 406 ({status})")
    # GET opens the session's stream of notifications, which its end ends
    events = Http(port)
    events.send(request_bytes("GET", b"", base_headers(session)))
    status, headers, rest = read_head_only(events.sock)
    check(status == 200 and headers.get("content-type") == "text/event-stream",
          f"GET opens the session's event stream ({status} {headers})")
    http.send(request_bytes("DELETE", b"", base_headers(session)))
    status, _, _ = http.read()
    check(status == 200, f"DELETE ends the session ({status})")
    events.sock.settimeout(10)
    while b"0\r\n\r\n" not in rest:
        chunk = events.sock.recv(4096)
        if not chunk:
            break
        rest += chunk
    check(b"0\r\n\r\n" in rest, f"the session's end ends its event stream ({rest[-40:]})")
    events.close()
    status, _, _ = http.post({"jsonrpc": "2.0", "id": 1, "method": "ping"}, session)
    check(status == 404, f"an ended session: 404 ({status})")
    http.close()


def test_the_rate_limit(port):
    http, session = initialize(port)
    statuses = []
    for n in range(6):
        status, headers, body = http.post(call(n, "simulation_list_robots"), session)
        statuses.append(status)
        if status == 429:
            check("retry-after" in headers and b"max_calls_per_s" in body, f"429 says why ({body[:200]})")
    check(statuses[0] == 200 and 429 in statuses, f"2 calls per second: the burst passes, then 429 ({statuses})")
    http.close()


def test_a_client_that_leaves_mid_call_has_it_cancelled(port):
    http, session = initialize(port)
    time.sleep(1.1)  # the rate limit's bucket refills
    goto = call(10, "rover_waypoint_goto", {"x": 3, "y": 0, "z": 0})
    goto["params"]["_meta"] = {"progressToken": "go"}
    http.send(request_bytes("POST", json.dumps(goto).encode(), base_headers(session)))
    status, headers, rest = read_head_only(http.sock)
    check(status == 200 and headers.get("content-type") == "text/event-stream", f"a goto streams ({status} {headers})")
    # its events carry ids; the connection drops after two, and a GET with Last-Event-ID
    # resumes the stream after the last one seen (within resume_window_s, 1 s here)
    seen = read_event_ids(http.sock, rest, 2)
    http.sock.close()
    resumed = Http(port)
    headers = base_headers(session)
    headers["Last-Event-ID"] = f"{seen[-1][0]}-{seen[-1][1]}"
    resumed.send(request_bytes("GET", b"", headers))
    status, headers, rest = read_head_only(resumed.sock)
    check(status == 200 and headers.get("content-type") == "text/event-stream", f"the stream resumes ({status} {headers})")
    more = read_event_ids(resumed.sock, rest, 1)
    check(more[0][0] == seen[-1][0] and more[0][1] > seen[-1][1],
          f"the resumed stream goes on after the last event seen ({seen} then {more})")
    bad = Http(port)
    headers = base_headers(session)
    headers["Last-Event-ID"] = "999-1"
    bad.send(request_bytes("GET", b"", headers))
    status, _, _ = bad.read()
    check(status == 404, f"a stream that is not there cannot be resumed: 404 ({status})")
    bad.close()
    http = resumed  # and now it is gone for good: not resumed within 1 s, the goto is cancelled
    other, other_session = initialize(port)
    status, headers, body = other.post(call(11, "rover_waypoint_get_status"), other_session)
    check(status == 200 and message_of(headers, body)["result"]["structuredContent"]["result"] == "Transit",
          f"the rover goes ({status} {headers} {body[:200]})")
    http.sock.close()  # gone, mid-call
    state = None
    for _ in range(50):
        time.sleep(0.6)  # within the rate limit
        status, headers, body = other.post(call(12, "rover_waypoint_get_status"), other_session)
        if status == 200:
            state = message_of(headers, body)["result"]["structuredContent"]["result"]
            if state != "Transit":
                break
    # a cancelled goto stops the rover where it is (MORSE: its destination becomes its place)
    check(state == "Arrived", f"its goto was cancelled: the waypoint says {state}")
    time.sleep(0.6)
    status, headers, body = other.post(call(13, "rover_pose_get_local_data"), other_session)
    check(status == 200, f"the pose: {status} {headers} {body[:300]}")
    x = message_of(headers, body)["result"]["structuredContent"]["x"]
    check(x < 2.0, f"far from its destination, x = 3 (x = {x:.2f})")
    other.close()


def read_event_ids(sock, data, count):
    """The (stream, event) ids of the next `count` events of a stream (after `data`, read
    already)."""
    sock.settimeout(20)
    while len(re.findall(rb"id: (\d+)-(\d+)\n", data)) < count:
        chunk = sock.recv(65536)
        if not chunk:
            break
        data += chunk
    return [(int(a), int(b)) for a, b in re.findall(rb"id: (\d+)-(\d+)\n", data)][:count]


def read_head_only(sock):
    """A response's status and headers, and what came after them."""
    data = b""
    while b"\r\n\r\n" not in data:
        data += sock.recv(4096)
    head, _, rest = data.partition(b"\r\n\r\n")
    head = head.decode()
    headers = {}
    for line in head.split("\r\n")[1:]:
        name, _, value = line.partition(":")
        headers[name.strip().lower()] = value.strip()
    return int(head.split(" ", 2)[1]), headers, rest


def main(argv):
    gateway = Gateway(argv)
    try:
        for test in (test_pipelined_requests_are_answered_in_order, test_expect_continue_and_a_chunked_body,
                     test_too_large_and_malformed_requests_are_refused_and_closed, test_origin_and_token,
                     test_sessions_and_bad_messages, test_the_rate_limit,
                     test_a_client_that_leaves_mid_call_has_it_cancelled):
            test(gateway.port)
            print(f"ok: {test.__name__}")
        check(gateway.process.poll() is None, "the gateway is still serving")
    finally:
        gateway.stop()
    print(f"PASS: {CHECKS} checks")


if __name__ == "__main__":
    main(sys.argv[1:])
