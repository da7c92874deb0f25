"""ROS 2 clients as rmw_cyclonedds makes them, on PyPI's cyclonedds binding with the
hand-declared types of ros2_types.py, shared by the service and action tests: a service client
does what rmw_cyclonedds' client does (USER_DATA clientid=<id>; on its request writer and reply
reader, the service available once both have matched endpoints with the same serviceid, each
request prefixed by its id and sequence number, the reply of that request picked by them)."""

import itertools
import time
import uuid

import pytest
from cyclonedds.core import Policy, Qos
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

WAIT = 20  # seconds: the longest any test waits for what it expects

_client_ids = itertools.count(1)


def service_qos(user_data):
    # ROS 2's services profile: reliable, volatile, keep-last 10
    return Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(10),
               Policy.Userdata(data=user_data))


def user_data_value(data, key):
    for entry in bytes(data or b"").decode(errors="replace").split(";"):
        if entry.startswith(key + "="):
            return entry[len(key) + 1:]
    return None


def endpoint_user_data(endpoint, key):
    """`key`'s value in a discovered endpoint's USER_DATA, or None."""
    return user_data_value(endpoint.qos[Policy.Userdata].data if Policy.Userdata in endpoint.qos
                           else b"", key)


class ServiceClient:
    """A ROS 2 service client as rmw_cyclonedds makes one, of service `name` (its ROS name
    without the leading '/') whose request and reply types are `request_cls` and `reply_cls`.
    `reader_later`: the reply reader is made only at the first call, after the request is
    written (a client whose reader simgate has not matched yet when the reply is ready)."""

    def __init__(self, participant, name, request_cls, reply_cls, reader_later=False):
        self.participant = participant
        self.name = name
        self.request_cls, self.reply_cls = request_cls, reply_cls
        self.client_id = f"{uuid.uuid4().hex[:8]}.{next(_client_ids)}"
        self.qos = service_qos(f"clientid={self.client_id};".encode())
        self.request_topic = Topic(participant, f"rq/{name}Request", self.request_cls)
        self.reply_topic = Topic(participant, f"rr/{name}Reply", self.reply_cls)
        self.writer = DataWriter(participant, self.request_topic, qos=self.qos)
        self.reader = None if reader_later else self._make_reader()
        self.guid = int.from_bytes(self.writer.get_guid().bytes[:8], "little")
        self.sequence = 0

    def _make_reader(self):
        return DataReader(self.participant, self.reply_topic, qos=self.qos)

    def matched_server(self):
        """The service's request reader and reply writer this client has matched (discovery
        data; None for what it has not)."""
        readers = [d for d in (self.writer.get_matched_subscription_data(h)
                               for h in self.writer.get_matched_subscriptions()) if d]
        writers = [] if self.reader is None else \
            [d for d in (self.reader.get_matched_publication_data(h)
                         for h in self.reader.get_matched_publications()) if d]
        return readers, writers

    def wait_for_service(self, timeout=WAIT):
        """As rmw_cyclonedds' service_server_is_available: a matched request reader and a
        matched reply writer with the same serviceid."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            matched_readers, matched_writers = self.matched_server()
            readers = {endpoint_user_data(d, "serviceid") for d in matched_readers}
            if self.reader is None:
                if readers - {None}:
                    return readers
            else:
                writers = {endpoint_user_data(d, "serviceid") for d in matched_writers}
                if (readers & writers) - {None}:
                    return readers & writers
            time.sleep(0.01)  # polling discovery, bounded by the deadline
        pytest.fail(f"service /{self.name} not available in {timeout} s")

    def send(self, **fields):
        self.sequence += 1
        self.writer.write(self.request_cls(client_guid=self.guid, sequence=self.sequence,
                                           **fields))
        return self.sequence

    def receive(self, sequence, timeout=WAIT):
        if self.reader is None:
            self.reader = self._make_reader()
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for reply in self.reader.take(N=16):
                if reply.client_guid == self.guid and reply.sequence == sequence:
                    return reply
            time.sleep(0.005)  # polling the reader, bounded by the deadline
        pytest.fail(f"no reply to /{self.name} request {sequence} in {timeout} s")

    def call(self, timeout=WAIT, **fields):
        self.wait_for_service()
        return self.receive(self.send(**fields), timeout)
