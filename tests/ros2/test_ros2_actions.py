"""The ros2 transport's SimulateSteps action (simulation_interfaces 2.1) as a ROS 2 action client
on rmw_cyclonedds uses it (docs/transports/ros2.md, Services), through PyPI's cyclonedds binding
with the hand-declared types of ros2_types.py. The client does what rcl_action's client does over
rmw_cyclonedds: three service clients (<action>/_action/send_goal, cancel_goal, get_result, each
as ros2_clients.ServiceClient), a feedback reader (ROS 2's default QoS) and a status reader
(reliable, transient-local); the server is available once the three services are and both
topics have a writer; a goal has a random UUID, its result is asked for as soon as it is
accepted. simgate's own view (the socket transport) is the reference."""

import time
import uuid

import pytest
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from rosbags.typesys import Stores, get_typestore

import ros2_types as ros
from conftest import DOMAIN_BASE, Gateway, ros2_config
from ros2_clients import WAIT, ServiceClient, endpoint_user_data

ACTION = "simulate_steps"
# action_msgs/GoalStatus
UNKNOWN, ACCEPTED, EXECUTING, CANCELING, SUCCEEDED, CANCELED, ABORTED = range(7)
# simulation_interfaces/Result
OK, INCORRECT_STATE, OPERATION_FAILED = 1, 3, 4
LONG = 1_000_000  # steps: the most one `simulation step` takes (some seconds here); cancelled
TOO_MANY = 10_000_000  # refused by simgate


def reliable(*policies):
    return Qos(Policy.Reliability.Reliable(duration(seconds=1)), *policies)


class ActionClient:
    """A ROS 2 action client as rcl_action makes one over rmw_cyclonedds, for the action
    `name`. Its readers keep more than rcl_action's (feedback 10, status 1) so that a test sees
    every message: `status_depth`, 256 feedback messages."""

    def __init__(self, participant, name=ACTION, status_depth=32):
        self.participant = participant
        part = f"{name}/_action/"
        self.goals = ServiceClient(participant, part + "send_goal",
                                   ros.SimulateStepsSendGoalRequest,
                                   ros.SimulateStepsSendGoalResponse)
        self.cancels = ServiceClient(participant, part + "cancel_goal", ros.CancelGoalRequest,
                                     ros.CancelGoalResponse)
        self.results = ServiceClient(participant, part + "get_result",
                                     ros.SimulateStepsGetResultRequest,
                                     ros.SimulateStepsGetResultResponse)
        self.feedback_topic = Topic(participant, f"rt/{part}feedback",
                                    ros.SimulateStepsFeedbackMessage)
        self.status_topic = Topic(participant, f"rt/{part}status", ros.GoalStatusArray)
        self.feedback_reader = DataReader(participant, self.feedback_topic,
                                          qos=reliable(Policy.History.KeepLast(256)))
        self.status_reader = self.status_reader_of(status_depth)
        self.feedback_seen = []  # (goal id, completed, remaining), in arrival order
        self.statuses_seen = []  # GoalStatusArray, in arrival order

    def status_reader_of(self, depth):
        return DataReader(self.participant, self.status_topic,
                          qos=reliable(Policy.Durability.TransientLocal,
                                       Policy.History.KeepLast(depth)))

    def wait_for_server(self, timeout=WAIT):
        """As rcl_action_server_is_available: the three services available, a feedback and a
        status writer matched."""
        deadline = time.monotonic() + timeout
        for client in (self.goals, self.cancels, self.results):
            client.wait_for_service(max(deadline - time.monotonic(), 0.1))
        while time.monotonic() < deadline:
            if self.feedback_reader.get_matched_publications() and \
                    self.status_reader.get_matched_publications():
                return
            time.sleep(0.01)  # polling discovery, bounded by the deadline
        pytest.fail(f"action /{ACTION}: no feedback or status writer in {timeout} s")

    def send_goal(self, steps):
        """(goal id, SendGoal response)."""
        goal_id = list(uuid.uuid4().bytes)
        reply = self.goals.call(goal_id=ros.UUID(goal_id), goal=ros.SimulateStepsGoal(steps))
        return goal_id, reply

    def ask_result(self, goal_id):
        """Sends a GetResult request (answered when the goal ends); its sequence number."""
        self.results.wait_for_service()
        return self.results.send(goal_id=ros.UUID(goal_id))

    def result(self, sequence, timeout=WAIT):
        return self.results.receive(sequence, timeout)

    def cancel(self, goal_id=None, stamp=None):
        info = ros.GoalInfo(goal_id=ros.UUID(goal_id or [0] * 16), stamp=stamp or ros.Time())
        return self.cancels.call(goal_info=info)

    def take(self):
        for message in self.feedback_reader.take(N=256):
            self.feedback_seen.append((list(message.goal_id.uuid),
                                       message.feedback.completed_steps,
                                       message.feedback.remaining_steps))
        self.statuses_seen.extend(self.status_reader.take(N=64))

    def feedback_of(self, goal_id):
        self.take()
        return [(done, left) for gid, done, left in self.feedback_seen if gid == goal_id]

    def statuses_of(self, goal_id):
        """The states the status topic has said `goal_id` was in, in order, repeats removed."""
        self.take()
        states = []
        for array in self.statuses_seen:
            for status in array.status_list:
                if list(status.goal_info.goal_id.uuid) == goal_id and \
                        (not states or states[-1] != status.status):
                    states.append(status.status)
        return states

    def wait_for_feedback(self, goal_id, timeout=WAIT):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.feedback_of(goal_id):
                return self.feedback_of(goal_id)
            time.sleep(0.01)  # polling the reader, bounded by the deadline
        pytest.fail(f"no feedback of goal {bytes(goal_id).hex()} in {timeout} s")

    def wait_for_status(self, goal_id, status, timeout=WAIT):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if status in self.statuses_of(goal_id):
                return
            time.sleep(0.01)  # polling the reader, bounded by the deadline
        pytest.fail(f"goal {bytes(goal_id).hex()} never {status}: {self.statuses_of(goal_id)}")


@pytest.fixture(scope="module")
def actions_domain():
    return DOMAIN_BASE + 4


@pytest.fixture(scope="module")
def sim(tmp_path_factory, actions_domain):
    """config/ros2.json on a domain of its own, feedback at most every millisecond (200 steps
    take a few here)."""
    config = ros2_config("ros2.json", actions_domain)
    config["transports"]["ros2"]["options"]["feedback_interval_ms"] = 1
    gw = Gateway(tmp_path_factory.mktemp("actions"), config, "actions")
    yield gw
    gw.kill()


@pytest.fixture(scope="module")
def participant(sim, actions_domain):
    return DomainParticipant(actions_domain)


@pytest.fixture
def client(participant, own):
    """An action client of a paused simulation, the server available."""
    own.call("simulation", "pause")
    action = ActionClient(participant)
    action.wait_for_server()
    return action


def test_200_steps_succeed_with_feedback_and_status(client, own):
    before = own.call("simulation", "get_simulation_state")
    goal_id, reply = client.send_goal(200)
    assert reply.accepted
    result = client.result(client.ask_result(goal_id))
    assert (result.status, result.result.result.result) == (SUCCEEDED, OK), result
    assert result.result.result.error_message == ""
    after = own.call("simulation", "get_simulation_state")
    assert after["steps"] - before["steps"] == 200
    assert after["sim_time"] == pytest.approx(before["sim_time"] + 200 * after["timestep"])
    assert after["state"] == "paused"
    # the goal's stamp: the simulated time it was accepted at
    assert reply.stamp.sec + reply.stamp.nanosec * 1e-9 == pytest.approx(before["sim_time"],
                                                                         abs=0.01)
    # feedback: steps done so far, in order, adding up to the goal
    client.wait_for_status(goal_id, SUCCEEDED)
    feedback = client.feedback_of(goal_id)
    assert feedback, "no feedback"
    done = [d for d, _ in feedback]
    assert done == sorted(set(done)) and done[-1] <= 200, feedback
    assert all(d + left == 200 for d, left in feedback), feedback
    # status: executing, then succeeded (accepted may be replaced before it is read)
    states = client.statuses_of(goal_id)
    assert states[-2:] == [EXECUTING, SUCCEEDED], states
    # asked again after the end: answered at once
    again = client.result(client.ask_result(goal_id))
    assert (again.status, again.result.result.result) == (SUCCEEDED, OK)


def test_cancel_ends_a_long_goal_with_the_steps_done(client, own):
    before = own.call("simulation", "get_simulation_state")
    goal_id, reply = client.send_goal(LONG)
    assert reply.accepted
    asked = client.ask_result(goal_id)
    client.wait_for_feedback(goal_id)
    cancel = client.cancel(goal_id)
    assert cancel.return_code == 0  # ERROR_NONE
    assert [list(g.goal_id.uuid) for g in cancel.goals_canceling] == [goal_id]
    assert (cancel.goals_canceling[0].stamp.sec, cancel.goals_canceling[0].stamp.nanosec) == \
        (reply.stamp.sec, reply.stamp.nanosec)
    result = client.result(asked)
    assert result.status == CANCELED, result
    assert result.result.result.result == OK
    after = own.call("simulation", "get_simulation_state")
    taken = after["steps"] - before["steps"]
    assert 0 < taken < LONG
    assert f"{taken} of {LONG} steps" in result.result.result.error_message
    assert after["state"] == "paused" and after["owed_steps"] == 0
    client.wait_for_status(goal_id, CANCELED)
    assert client.statuses_of(goal_id)[-3:] == [EXECUTING, CANCELING, CANCELED]
    # nothing to cancel any more
    assert client.cancel(goal_id).return_code == 3  # ERROR_GOAL_TERMINATED
    assert client.cancel(list(uuid.uuid4().bytes)).return_code == 2  # ERROR_UNKNOWN_GOAL_ID


def test_a_goal_while_another_runs_is_rejected(client, own):
    first, reply = client.send_goal(LONG)
    assert reply.accepted
    asked = client.ask_result(first)
    client.wait_for_feedback(first)
    second, refused = client.send_goal(10)
    assert not refused.accepted
    assert (refused.stamp.sec, refused.stamp.nanosec) == (0, 0)
    # a rejected goal is not known
    unknown = client.result(client.ask_result(second))
    assert unknown.status == UNKNOWN
    # cancel every goal (id and stamp zero): the first one
    cancel = client.cancel()
    assert cancel.return_code == 0
    assert [list(g.goal_id.uuid) for g in cancel.goals_canceling] == [first]
    assert client.result(asked).status == CANCELED
    # a goal id already taken (a goal kept with its result) is refused
    assert not client.goals.call(goal_id=ros.UUID(first), goal=ros.SimulateStepsGoal(5)).accepted
    # then the next goal is accepted
    third, reply = client.send_goal(10)
    assert reply.accepted
    assert client.result(client.ask_result(third)).status == SUCCEEDED


def test_result_of_an_unknown_goal_is_status_unknown(client):
    reply = client.result(client.ask_result(list(uuid.uuid4().bytes)))
    assert reply.status == UNKNOWN
    assert reply.result.result.result == 0 and reply.result.result.error_message == ""


def test_a_goal_on_a_playing_simulation_is_aborted_incorrect_state(client, own):
    own.call("simulation", "play")
    try:
        goal_id, reply = client.send_goal(100)
        assert reply.accepted  # accepted, so that the result can say why
        result = client.result(client.ask_result(goal_id))
        assert result.status == ABORTED
        assert result.result.result.result == INCORRECT_STATE
        assert "pause" in result.result.result.error_message
        assert client.feedback_of(goal_id) == []
    finally:
        own.call("simulation", "pause")


def test_a_count_simgate_refuses_aborts_the_goal(client, own):
    before = own.call("simulation", "get_simulation_state")["steps"]
    goal_id, reply = client.send_goal(TOO_MANY)
    assert reply.accepted
    result = client.result(client.ask_result(goal_id))
    assert (result.status, result.result.result.result) == (ABORTED, OPERATION_FAILED)
    assert "range" in result.result.result.error_message
    assert own.call("simulation", "get_simulation_state")["steps"] == before


def test_a_late_status_reader_gets_the_latest_status(client):
    goal_id, reply = client.send_goal(20)
    assert reply.accepted
    assert client.result(client.ask_result(goal_id)).status == SUCCEEDED
    client.wait_for_status(goal_id, SUCCEEDED)
    # a reader made now, as rcl_action's client makes it (keep-last 1, transient-local)
    late = client.status_reader_of(1)
    deadline = time.monotonic() + WAIT
    arrays = []
    while not arrays and time.monotonic() < deadline:
        arrays = late.take(N=4)
        time.sleep(0.01)  # polling the reader, bounded by the deadline
    assert len(arrays) == 1
    latest = {bytes(s.goal_info.goal_id.uuid): s.status for s in arrays[0].status_list}
    assert latest[bytes(goal_id)] == SUCCEEDED
    # every goal kept is there, each in a final state (none runs)
    assert set(latest.values()) <= {SUCCEEDED, CANCELED, ABORTED}


def test_discovery_shows_ros_names_types_qos_and_the_node(client, participant):
    """What `ros2 action list -t` and `ros2 action info /simulate_steps` are built from."""
    types = {}
    for service in (client.goals, client.cancels, client.results):
        service.wait_for_service()
        [reader], [writer] = service.matched_server()
        ids = {endpoint_user_data(e, "serviceid") for e in (reader, writer)}
        assert len(ids) == 1 and None not in ids, service.name
        types[service.name] = (reader.type_name, writer.type_name)
    assert types[f"{ACTION}/_action/send_goal"] == (
        "simulation_interfaces::action::dds_::SimulateSteps_SendGoal_Request_",
        "simulation_interfaces::action::dds_::SimulateSteps_SendGoal_Response_")
    assert types[f"{ACTION}/_action/cancel_goal"] == (
        "action_msgs::srv::dds_::CancelGoal_Request_", "action_msgs::srv::dds_::CancelGoal_Response_")
    assert types[f"{ACTION}/_action/get_result"] == (
        "simulation_interfaces::action::dds_::SimulateSteps_GetResult_Request_",
        "simulation_interfaces::action::dds_::SimulateSteps_GetResult_Response_")
    [feedback] = [d for d in (client.feedback_reader.get_matched_publication_data(h)
                              for h in client.feedback_reader.get_matched_publications()) if d]
    [status] = [d for d in (client.status_reader.get_matched_publication_data(h)
                            for h in client.status_reader.get_matched_publications()) if d]
    assert feedback.type_name == "simulation_interfaces::action::dds_::SimulateSteps_FeedbackMessage_"
    # ROS 2's default QoS
    assert isinstance(feedback.qos[Policy.Reliability], Policy.Reliability.Reliable)
    assert feedback.qos[Policy.Durability] == Policy.Durability.Volatile
    assert feedback.qos[Policy.History] == Policy.History.KeepLast(10)
    assert status.type_name == "action_msgs::msg::dds_::GoalStatusArray_"
    # rcl_action's status QoS
    assert isinstance(status.qos[Policy.Reliability], Policy.Reliability.Reliable)
    assert status.qos[Policy.Durability] == Policy.Durability.TransientLocal
    assert status.qos[Policy.History] == Policy.History.KeepLast(1)
    # the node /simgate owns the action's endpoints
    graph = DataReader(participant, Topic(participant, "ros_discovery_info",
                                          ros.ParticipantEntitiesInfo),
                       qos=reliable(Policy.History.KeepLast(1), Policy.Durability.TransientLocal))
    wanted = {feedback.key.bytes.hex(), status.key.bytes.hex()}
    deadline = time.monotonic() + WAIT
    owned = set()
    while not wanted <= owned and time.monotonic() < deadline:
        for info in graph.take(N=16):
            for node in info.node_entities_info_seq:
                if node.node_name == "simgate":
                    owned = {bytes(g.data).hex() for g in node.writer_gid_seq}
        time.sleep(0.01)  # polling the reader, bounded by the deadline
    assert wanted <= owned


def test_status_bytes_are_ros2_cdr(client):
    """The status topic's bytes are what ROS 2 serialises for action_msgs/GoalStatusArray
    (rosbags' own definition of it)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    raw = []
    cls = ros.GoalStatusArray
    base = cls.deserialize.__func__

    def record(klass, data, has_header=True, use_version_2=None):
        raw.append(bytes(data))
        return base(klass, data, has_header=has_header, use_version_2=use_version_2)

    cls.deserialize = classmethod(record)
    try:
        goal_id, reply = client.send_goal(5)
        assert reply.accepted
        assert client.result(client.ask_result(goal_id)).status == SUCCEEDED
        client.wait_for_status(goal_id, SUCCEEDED)
    finally:
        del cls.deserialize
    data = raw[-1]
    assert data[:2] == b"\x00\x01"  # CDR, little endian
    message = store.deserialize_cdr(data, "action_msgs/msg/GoalStatusArray")
    assert [bytes(s.goal_info.goal_id.uuid) for s in message.status_list][-1] == bytes(goal_id)
    assert message.status_list[-1].status == SUCCEEDED
    # the same bytes but for the padding Cyclone adds at the end (its count in the header's
    # options, as XCDR has it)
    padding = data[3] & 3
    again = bytes(store.serialize_cdr(message, "action_msgs/msg/GoalStatusArray"))
    assert again[4:] == data[4:len(data) - padding]
