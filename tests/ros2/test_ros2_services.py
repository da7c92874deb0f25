"""The ros2 transport's services as a ROS 2 client on rmw_cyclonedds calls them
(docs/transports/ros2.md, Services): simulation_interfaces 2.1 and simgate/call, through PyPI's
cyclonedds binding with the hand-declared types of ros2_types.py. The client does what
rmw_cyclonedds' client does: USER_DATA clientid=<id>; on its request writer and reply reader,
the service available once both have matched endpoints with the same serviceid, each request
prefixed by its id and sequence number, the reply of that request picked by them. simgate's own
view (the socket transport) is the reference."""

import json
import os
import time

import pytest
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

import ros2_types as ros
from conftest import DOMAIN_BASE, Gateway, ros2_config
from ros2_clients import WAIT, ServiceClient, user_data_value

OK, NOT_FOUND, INCORRECT_STATE, OPERATION_FAILED, FEATURE_UNSUPPORTED = 1, 2, 3, 4, 0
STOPPED, PLAYING, PAUSED = 0, 1, 2

# the services of the shipped config (config/ros2.json), their types
SERVICES = {
    "get_simulator_features": (ros.GetSimulatorFeaturesRequest, ros.GetSimulatorFeaturesResponse),
    "get_simulation_state": (ros.GetSimulationStateRequest, ros.GetSimulationStateResponse),
    "set_simulation_state": (ros.SetSimulationStateRequest, ros.SetSimulationStateResponse),
    "step_simulation": (ros.StepSimulationRequest, ros.StepSimulationResponse),
    "reset_simulation": (ros.ResetSimulationRequest, ros.ResetSimulationResponse),
    "get_entities": (ros.GetEntitiesRequest, ros.GetEntitiesResponse),
    "get_entities_states": (ros.GetEntitiesStatesRequest, ros.GetEntitiesStatesResponse),
    "get_entity_state": (ros.GetEntityStateRequest, ros.GetEntityStateResponse),
    "set_entity_state": (ros.SetEntityStateRequest, ros.SetEntityStateResponse),
    "get_entity_info": (ros.GetEntityInfoRequest, ros.GetEntityInfoResponse),
    "get_entity_bounds": (ros.GetEntityBoundsRequest, ros.GetEntityBoundsResponse),
    "spawn_entity": (ros.SpawnEntityRequest, ros.SpawnEntityResponse),
    "delete_entity": (ros.DeleteEntityRequest, ros.DeleteEntityResponse),
    "simgate/call": (ros.CallRequest, ros.CallResponse),
}


@pytest.fixture(scope="module")
def services_domain():
    return DOMAIN_BASE + 3


@pytest.fixture(scope="module")
def sim(tmp_path_factory, services_domain):
    """config/ros2.json as it ships, on a domain of its own (these tests pause, step, reset,
    spawn)."""
    config = ros2_config("ros2.json", services_domain)
    gw = Gateway(tmp_path_factory.mktemp("services"), config, "services")
    yield gw
    gw.kill()


@pytest.fixture(scope="module")
def participant(sim, services_domain):
    return DomainParticipant(services_domain)


@pytest.fixture(scope="module")
def clients(participant):
    made = {}

    def client(name):
        if name not in made:
            made[name] = ServiceClient(participant, name, *SERVICES[name])
        return made[name]
    return client


def ensure(clients, state):
    reply = clients("set_simulation_state").call(state=ros.SimulationState(state))
    assert reply.result.result in (OK, 101), reply.result


def test_every_service_is_offered_with_a_serviceid(sim, participant, clients):
    ids = set()
    for name in SERVICES:
        ids |= clients(name).wait_for_service()
    assert len(ids) == len(SERVICES)  # one id per service, shared by its two halves


def test_features_are_the_ones_implemented(sim, clients, own):
    reply = clients("get_simulator_features").call()
    features = set(reply.features.features)
    # spawning, deleting, bounds, inline resources, entity state get/set, info, reset (and its
    # scopes), simulation state get/set/pause, stepping one and many, the SimulateSteps action
    assert features == {0, 1, 5, 9, 10, 11, 12, 20, 21, 22, 24, 25, 26, 31, 32, 33}
    assert set(reply.features.spawn_formats) == set(own.call("simulation", "get_capabilities")
                                                    ["spawn_formats"])
    assert "ros2" in reply.features.custom_info


def test_state_pause_step_play(sim, clients, own):
    ensure(clients, PLAYING)
    state = clients("get_simulation_state").call()
    assert (state.state.state, state.result.result) == (PLAYING, OK)
    # stepping needs a paused simulation
    step = clients("step_simulation").call(steps=5)
    assert step.result.result == INCORRECT_STATE
    assert "pause" in step.result.error_message
    assert clients("set_simulation_state").call(state=ros.SimulationState(PAUSED)).result.result == OK
    again = clients("set_simulation_state").call(state=ros.SimulationState(PAUSED))
    assert again.result.result == 101  # ALREADY_IN_TARGET_STATE
    assert clients("get_simulation_state").call().state.state == PAUSED
    before = own.call("simulation", "get_simulation_state")
    step = clients("step_simulation").call(steps=50)
    assert (step.result.result, step.result.error_message) == (OK, "")
    after = own.call("simulation", "get_simulation_state")
    assert after["steps"] - before["steps"] == 50
    assert after["sim_time"] == pytest.approx(before["sim_time"] + 50 * after["timestep"])
    zero = clients("step_simulation").call(steps=0)
    assert zero.result.result == OPERATION_FAILED
    assert clients("set_simulation_state").call(state=ros.SimulationState(PLAYING)).result.result == OK
    assert own.call("simulation", "get_simulation_state")["state"] == "playing"
    unknown = clients("set_simulation_state").call(state=ros.SimulationState(4))  # NO_WORLD
    assert unknown.result.result == 103  # INCORRECT_TRANSITION


def test_stopped_is_paused_and_reset(sim, clients, own):
    ensure(clients, PLAYING)
    time.sleep(0.2)
    assert clients("set_simulation_state").call(state=ros.SimulationState(STOPPED)).result.result == OK
    state = own.call("simulation", "get_simulation_state")
    assert state["state"] == "paused" and state["sim_time"] == 0
    ensure(clients, PLAYING)


def test_reset_scopes(sim, clients, own):
    ensure(clients, PLAYING)
    time.sleep(0.2)
    spawned = clients("reset_simulation").call(scope=4)  # SCOPE_SPAWNED
    assert spawned.result.result == FEATURE_UNSUPPORTED
    assert "SCOPE_SPAWNED" in spawned.result.error_message
    ensure(clients, PAUSED)
    assert own.call("simulation", "get_simulation_state")["sim_time"] > 0
    assert clients("reset_simulation").call(scope=0).result.result == OK
    assert own.call("simulation", "get_simulation_state")["sim_time"] == 0
    ensure(clients, PLAYING)


def test_entities_filters_and_states(sim, clients, own):
    names = own.call("simulation", "list_entities")
    everything = clients("get_entities").call()
    assert (everything.result.result, list(everything.entities)) == (OK, names)
    robot = clients("get_entities").call(filters=ros.EntityFilters(filter="^robot($|_)"))
    assert list(robot.entities) == [n for n in names if n == "robot" or n.startswith("robot_")]
    bad = clients("get_entities").call(filters=ros.EntityFilters(filter="(robot"))
    assert bad.result.result == OPERATION_FAILED and "regular expression" in bad.result.error_message
    tagged = clients("get_entities").call(
        filters=ros.EntityFilters(tags=ros.TagsFilter(tags=["red"])))
    assert tagged.result.result == FEATURE_UNSUPPORTED
    states = clients("get_entities_states").call(filters=ros.EntityFilters(filter="^crate"))
    assert states.result.result == OK
    assert list(states.entities) == [n for n in names if n.startswith("crate")]
    assert len(states.states) == len(states.entities) > 0
    for name, state in zip(states.entities, states.states):
        pose = own.call("simulation", "get_entity_state", name)["pose"]
        assert state.header.frame_id == "world"
        assert [state.pose.position.x, state.pose.position.y, state.pose.position.z] == \
            pytest.approx(pose["position"], abs=1e-3)


def test_entity_state_get_and_set(sim, clients, own):
    reply = clients("get_entity_state").call(entity="crate1")
    assert reply.result.result == OK
    ours = own.call("simulation", "get_entity_state", "crate1")
    p, q = reply.state.pose.position, reply.state.pose.orientation
    assert [p.x, p.y, p.z] == pytest.approx(ours["pose"]["position"], abs=1e-3)
    assert [q.x, q.y, q.z, q.w] == pytest.approx(ours["pose"]["orientation"], abs=1e-3)
    assert reply.state.header.frame_id == "world" and reply.state.header.stamp.sec >= 0

    missing = clients("get_entity_state").call(entity="crate11")
    assert missing.result.result == NOT_FOUND
    assert "crate1" in missing.result.error_message  # simgate's "did you mean"

    target = ros.EntityState(pose=ros.Pose(position=ros.Point(x=1.5, y=-2.0, z=0.5)))
    moved = clients("set_entity_state").call(entity="crate1", state=target, set_pose=True)
    assert (moved.result.result, moved.result.error_message) == (OK, "")
    assert own.call("simulation", "get_object_pose", "crate1")[0][:2] == \
        pytest.approx([1.5, -2.0], abs=0.05)
    accel = clients("set_entity_state").call(entity="crate1", state=target, set_acceleration=True)
    assert accel.result.result == FEATURE_UNSUPPORTED
    elsewhere = ros.EntityState(header=ros.Header(frame_id="robot"))
    framed = clients("set_entity_state").call(entity="crate1", state=elsewhere, set_pose=True)
    assert framed.result.result == OPERATION_FAILED and "world" in framed.result.error_message
    nowhere = clients("set_entity_state").call(entity="nothing", state=target, set_pose=True)
    assert nowhere.result.result == NOT_FOUND


def test_entity_info_and_bounds(sim, clients, own):
    robot = clients("get_entity_info").call(entity="robot")
    assert (robot.result.result, robot.info.category.category) == (OK, 1)  # CATEGORY_ROBOT
    crate = clients("get_entity_info").call(entity="crate1")
    assert (crate.result.result, crate.info.category.category) == (OK, 0)  # CATEGORY_OBJECT
    assert clients("get_entity_info").call(entity="nothing").result.result == NOT_FOUND
    bounds = clients("get_entity_bounds").call(entity="crate1")
    assert (bounds.result.result, bounds.bounds.type) == (OK, 1)  # TYPE_BOX
    box = own.call("simulation", "get_object_bbox", "crate1")
    assert [[p.x, p.y, p.z] for p in bounds.bounds.points] == [pytest.approx(c) for c in box]
    assert clients("get_entity_bounds").call(entity="nothing").result.result == NOT_FOUND


BALL = ("<mujoco><worldbody><body><freejoint/><geom type='sphere' size='.1' mass='1'/>"
        "</body></worldbody></mujoco>")


def test_spawn_and_delete(sim, clients, own):
    spawn = clients("spawn_entity")
    made = spawn.call(name="ball", entity_resource=ros.Resource(resource_string=BALL),
                      initial_pose=ros.PoseStamped(pose=ros.Pose(position=ros.Point(x=3, y=3,
                                                                                     z=0.5))))
    assert (made.result.result, made.entity_name) == (OK, "ball"), made.result
    assert "ball" in own.call("simulation", "list_entities")
    taken = spawn.call(name="ball", entity_resource=ros.Resource(resource_string=BALL))
    assert taken.result.result == 101  # NAME_NOT_UNIQUE
    renamed = spawn.call(name="ball", allow_renaming=True,
                         entity_resource=ros.Resource(resource_string=BALL),
                         initial_pose=ros.PoseStamped(pose=ros.Pose(position=ros.Point(x=4, y=3,
                                                                                        z=0.5))))
    assert (renamed.result.result, renamed.entity_name) == (OK, "ball_1")
    nothing = spawn.call(name="cube")
    assert nothing.result.result == 104  # NO_RESOURCE
    broken = spawn.call(name="cube", entity_resource=ros.Resource(resource_string="<mujoco>"))
    assert broken.result.result == 106, broken.result  # RESOURCE_PARSE_ERROR
    elsewhere = spawn.call(name="cube", entity_resource=ros.Resource(resource_string=BALL),
                           initial_pose=ros.PoseStamped(header=ros.Header(frame_id="robot")))
    assert elsewhere.result.result == 109  # INVALID_POSE
    for name in ("ball", "ball_1"):
        assert clients("delete_entity").call(entity=name).result.result == OK
    assert "ball" not in own.call("simulation", "list_entities")
    assert clients("delete_entity").call(entity="ball").result.result == NOT_FOUND


def test_simgate_call_reaches_any_served_service(sim, clients):
    call = clients("simgate/call")
    pose = call.call(component="robot.pose", service="get_local_data")
    assert (pose.status, pose.message) == ("SUCCESS", "")
    assert set(json.loads(pose.result)) >= {"x", "y", "z", "yaw"}
    added = call.call(component="simulation", service="get_entity_state",
                      arguments=json.dumps({"name": "robot"}))
    assert added.status == "SUCCESS" and "pose" in json.loads(added.result)
    unknown = call.call(component="robot.pose", service="get_locale_data")
    assert unknown.status == "FAILED" and "get_local_data" in unknown.message
    garbled = call.call(component="robot.pose", service="get_local_data", arguments="{oops")
    assert garbled.status == "FAILED" and "arguments" in garbled.message
    assert garbled.result == "null"


def test_a_reply_waits_for_the_clients_reader(sim, participant):
    late = ServiceClient(participant, "get_simulation_state", *SERVICES["get_simulation_state"],
                         reader_later=True)
    late.wait_for_service()
    sequence = late.send()
    time.sleep(0.5)  # the reply is ready long before the client's reader exists
    reply = late.receive(sequence)
    assert reply.result.result == OK


def test_discovery_shows_ros_names_types_ids_and_the_node(sim, participant, clients):
    """What `ros2 service list -t` and `ros2 node info /simgate` are built from: the rq/ and rr/
    endpoints with the ROS type names and rmw_cyclonedds' serviceid, owned by the node in the
    graph (ros_discovery_info). Read as the matched endpoints of a client's own (the binding's
    built-in topic readers crash: test_ros2_topics.py)."""
    readers, writers = {}, {}
    for name in SERVICES:
        client = clients(name)
        client.wait_for_service()
        [reader] = [d for d in (client.writer.get_matched_subscription_data(h)
                                for h in client.writer.get_matched_subscriptions()) if d]
        [writer] = [d for d in (client.reader.get_matched_publication_data(h)
                                for h in client.reader.get_matched_publications()) if d]
        readers[name], writers[name] = reader, writer
        ids = {user_data_value(e.qos[Policy.Userdata].data, "serviceid") for e in (reader, writer)}
        assert len(ids) == 1 and None not in ids, name
        for endpoint in (reader, writer):
            assert isinstance(endpoint.qos[Policy.Reliability], Policy.Reliability.Reliable)
            assert endpoint.qos[Policy.Durability] == Policy.Durability.Volatile
    assert readers["step_simulation"].type_name == \
        "simulation_interfaces::srv::dds_::StepSimulation_Request_"
    assert writers["get_entity_state"].type_name == \
        "simulation_interfaces::srv::dds_::GetEntityState_Response_"
    assert readers["simgate/call"].type_name == "simgate_interfaces::srv::dds_::Call_Request_"
    # the node /simgate owns them
    qos = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(1),
              Policy.Durability.TransientLocal)
    graph = DataReader(participant, Topic(participant, "ros_discovery_info",
                                          ros.ParticipantEntitiesInfo), qos=qos)
    deadline = time.monotonic() + WAIT
    node = None
    while node is None and time.monotonic() < deadline:
        for info in graph.take(N=16):
            for n in info.node_entities_info_seq:
                if n.node_name == "simgate" and \
                        len(n.reader_gid_seq) >= len(SERVICES):
                    node = n
        time.sleep(0.01)  # polling the reader, bounded by the deadline
    assert node is not None
    owned_readers = {bytes(g.data).hex() for g in node.reader_gid_seq}
    owned_writers = {bytes(g.data).hex() for g in node.writer_gid_seq}
    assert {r.key.bytes.hex() for r in readers.values()} <= owned_readers
    assert {w.key.bytes.hex() for w in writers.values()} <= owned_writers


# simulation_interfaces' definitions as published (msg/Result.msg, msg/EntityState.msg,
# srv/GetEntityState.srv's response, registered as a message of its own): rosbags builds its
# own CDR (de)serialiser from them
SIM_MSGS = {
    "simulation_interfaces/msg/Result": "uint8 result\nstring error_message\n",
    "simulation_interfaces/msg/EntityState":
        "std_msgs/Header header\ngeometry_msgs/Pose pose\ngeometry_msgs/Twist twist\n"
        "geometry_msgs/Accel acceleration\n",
    "simulation_interfaces/msg/GetEntityState_Response":
        "simulation_interfaces/Result result\nsimulation_interfaces/EntityState state\n",
}


def test_reply_bytes_are_ros2_cdr(sim, participant):
    """The reply's bytes after rmw_cyclonedds' 16-byte header are what ROS 2 serialises for
    the response message (rosbags, from the published definitions)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in SIM_MSGS.items():
        store.register(get_types_from_msg(text, name))
    raw = []
    cls = ros.GetEntityStateResponse
    base = cls.deserialize.__func__

    def record(klass, data, has_header=True, use_version_2=None):
        raw.append(bytes(data))
        return base(klass, data, has_header=has_header, use_version_2=use_version_2)

    cls.deserialize = classmethod(record)
    try:
        client = ServiceClient(participant, "get_entity_state", *SERVICES["get_entity_state"])
        reply = client.call(entity="robot")
    finally:
        del cls.deserialize
    data = raw[-1]
    header, body = data[:4], data[4:]
    assert header[:2] == b"\x00\x01"  # CDR, little endian
    assert int.from_bytes(body[:8], "little") == client.guid
    assert int.from_bytes(body[8:16], "little", signed=True) == client.sequence
    # the message alone, as ROS 2 puts it in a CDR buffer of its own
    message = store.deserialize_cdr(header + body[16:],
                                    "simulation_interfaces/msg/GetEntityState_Response")
    assert message.result.result == reply.result.result == OK
    assert message.state.header.frame_id == "world"
    assert message.state.pose.position.x == reply.state.pose.position.x
    assert store.serialize_cdr(message, "simulation_interfaces/msg/GetEntityState_Response") == \
        header + body[16:]


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def test_the_dds_thread_sleeps_once_clients_have_matched(sim, participant, clients):
    """A reply writer's match wakes the DDS thread through the waitset; a wake not taken
    (the status not read) woke it again at once, forever: a whole CPU spent after the first
    client (fixed: Ros2Services::matches_changed on every such wake)."""
    for name in ("get_simulation_state", "get_entities", "step_simulation"):
        clients(name).wait_for_service()
    assert clients("get_simulation_state").call().result.result == OK
    pid = sim.process.pid
    before, started = cpu_seconds(pid), time.monotonic()
    time.sleep(2.0)
    used = (cpu_seconds(pid) - before) / (time.monotonic() - started)
    # the simulation at real time, /clock at 100 Hz and /tf at 30 Hz take a few percent; the
    # spinning thread took all of one CPU
    assert used < 0.5, f"simgate used {used:.2f} CPU seconds per second while nobody called"
