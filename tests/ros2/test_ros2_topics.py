"""The ros2 transport as a ROS 2 node sees it (docs/transports/ros2.md), through clients nobody
on the team wrote: PyPI's cyclonedds binding (its own Cyclone DDS) reads and writes the ROS 2
topics with the types of ros2_types.py, declared by hand from the .msg definitions and named as
ROS 2 names them; rosbags' ROS 2 CDR (de)serialiser reads the very bytes that came on the wire
and writes them again. simgate's own view (the socket transport) is the reference for what the
messages must say."""

import base64
import gc
import math
import os
import struct
import subprocess
import time
import zlib

import pytest
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from rosbags.typesys import Stores, get_typestore

import ros2_types as ros
from conftest import SOURCE_DIR, START_TIMEOUT, check_config, simgate_binary

WAIT = 20  # seconds: the longest any test waits for what it expects

# ROS 2's default profile (reliable, volatile, keep-last 10), and the transient-local one of
# /tf_static and ros_discovery_info
DEFAULT_QOS = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(10))
LATCHED_QOS = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(1),
                  Policy.Durability.TransientLocal)

ROSBAGS = get_typestore(Stores.ROS2_JAZZY)


class RawRecorder:
    """Keeps the serialized bytes (with their encapsulation header) of every sample a reader of
    `cls` takes: the cyclonedds binding hands them to cls.deserialize."""

    def __init__(self, cls):
        self.cls = cls
        self.raw = []
        self.original = cls.__dict__["deserialize"] if "deserialize" in cls.__dict__ else None
        base = cls.deserialize.__func__

        def deserialize(klass, data, has_header=True, use_version_2=None):
            self.raw.append(bytes(data))
            return base(klass, data, has_header=has_header, use_version_2=use_version_2)

        cls.deserialize = classmethod(deserialize)

    def close(self):
        if self.original is None:
            del self.cls.deserialize
        else:
            self.cls.deserialize = self.original


class Node:
    """A participant on `domain` with readers and writers of the ROS 2 topics."""

    def __init__(self, domain):
        self.domain = domain
        self.participant = DomainParticipant(domain)
        self.topics = {}

    def topic(self, name, cls):
        if name not in self.topics:
            self.topics[name] = Topic(self.participant, name, cls)
        return self.topics[name]

    def reader(self, name, cls, qos=DEFAULT_QOS):
        return DataReader(self.participant, self.topic(name, cls), qos=qos)

    def writer(self, name, cls, qos=DEFAULT_QOS):
        return DataWriter(self.participant, self.topic(name, cls), qos=qos)


def take_until(reader, predicate, timeout=WAIT):
    """Samples taken until one satisfies `predicate` (returned with all before it); fails the
    test after `timeout` seconds."""
    taken = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for sample in reader.take(N=64):
            taken.append(sample)
            if predicate(sample):
                return taken
        time.sleep(0.01)  # polling the reader, bounded by the deadline
    pytest.fail(f"nothing expected on {reader.topic.name} in {timeout} s (took {len(taken)})")


def first(reader, timeout=WAIT):
    return take_until(reader, lambda s: True, timeout)[-1]


def seconds(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


def gid_hex(gid):
    return bytes(gid.data).hex()


@pytest.fixture(scope="module")
def node(rover, rover_domain):
    return Node(rover_domain)


@pytest.fixture(scope="module")
def scene(rover):
    client = rover.socket()
    yield client.call("simulation", "get_scene_geometry", False)
    client.close()


def test_clock_is_the_simulated_time_and_advances(rover, node):
    reader = node.reader("rt/clock", ros.Clock)
    samples = take_until(reader, lambda s: True)
    start = seconds(samples[-1].clock)
    later = take_until(reader, lambda s: seconds(s.clock) >= start + 0.2)
    times = [seconds(s.clock) for s in samples + later]
    assert times == sorted(times)
    assert all(0 <= s.clock.nanosec < 1_000_000_000 for s in samples + later)
    # the same clock as the samples' stamps: /tf's stamp is a time /clock said or will say
    tf = first(node.reader("rt/tf", ros.TFMessage))
    assert abs(seconds(tf.transforms[0].header.stamp) - times[-1]) < 2.0


def test_tf_has_every_body_in_its_parent_body(rover, node, scene):
    bodies = scene["bodies"]
    message = first(node.reader("rt/tf", ros.TFMessage))
    frames = {t.child_frame_id: t for t in message.transforms}
    assert sorted(frames) == sorted(b["name"] for b in bodies[1:])
    for body in bodies[1:]:
        parent = bodies[body["parent"]]["name"]
        assert frames[body["name"]].header.frame_id == parent
    # the robot hangs from the world where simgate says it is (it stands still)
    world_pose = rover.socket().call("simulation", "get_object_pose", "robot")
    robot = frames["robot"].transform
    assert [robot.translation.x, robot.translation.y, robot.translation.z] == pytest.approx(
        world_pose[0], abs=1e-3)
    q = robot.rotation
    assert [q.x, q.y, q.z, q.w] == pytest.approx(world_pose[1], abs=1e-3)  # [qx, qy, qz, qw]
    assert math.isclose(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w, 1.0, rel_tol=1e-9)
    # a wheel, in the robot's frame: beside it (the demo's wheels are 0.21 m off its axis)
    wheel = frames["robot_left_wheel"].transform.translation
    assert abs(wheel.y) == pytest.approx(0.21, abs=1e-3)


def test_tf_static_holds_the_sensing_frames_for_late_joiners(rover, node, scene):
    message = first(node.reader("rt/tf_static", ros.TFMessage, LATCHED_QOS))
    expected = {f["name"].replace(".", "/"): scene["bodies"][f["body"]]["name"]
                for f in scene["frames"]}
    assert {t.child_frame_id: t.header.frame_id for t in message.transforms} == expected
    assert "robot/odometry" in expected


def test_cmd_vel_drives_the_robot_and_odom_follows(rover, node):
    odom = node.reader("rt/robot/odom", ros.Odometry)
    before = first(odom)
    assert before.header.frame_id == "robot/odom"
    assert before.child_frame_id == "robot/odometry"
    cmd_vel = node.writer("rt/robot/cmd_vel", ros.Twist)
    try:
        deadline = time.monotonic() + WAIT
        moved = None
        while time.monotonic() < deadline and moved is None:
            cmd_vel.write(ros.Twist(linear=ros.Vector3(x=0.5), angular=ros.Vector3(z=0.0)))
            for sample in odom.take(N=64):
                if sample.pose.pose.position.x > before.pose.pose.position.x + 0.2:
                    moved = sample
            time.sleep(0.05)  # a teleop's 20 Hz, bounded by the deadline
        assert moved is not None, "the robot did not move on /robot/cmd_vel"
        # forward at about the speed asked, in the robot's own frame
        assert moved.twist.twist.linear.x == pytest.approx(0.5, abs=0.15)
        assert seconds(moved.header.stamp) > seconds(before.header.stamp)
        # simgate saw the same
        pose = rover.socket().call("simulation", "get_object_pose", "robot")
        assert pose[0][0] > 0.2
    finally:
        cmd_vel.write(ros.Twist())


def test_imu_reads_as_simgate_reads_it_in_the_sensors_frame(rover, node, scene):
    """/robot/imu from robot.imu: its rates and specific force in the sensor's frame (on
    /tf_static under its body), no orientation estimate (orientation_covariance[0] = -1)."""
    client = rover.socket()
    client.call("robot.motion", "set_speed", 0, 0)  # at rest (another test drives it)
    deadline = time.monotonic() + WAIT
    while True:  # until simgate's own imu reads gravity alone
        ours = client.call("robot.imu", "get_local_data")
        if ours["linear_acceleration"] == pytest.approx([0, 0, 9.81], abs=0.05):
            break
        assert time.monotonic() < deadline, ours
        time.sleep(0.05)  # polling simgate, bounded by the deadline
    client.close()
    reader = node.reader("rt/robot/imu", ros.Imu)
    [message] = take_until(reader, lambda m: [m.linear_acceleration.x, m.linear_acceleration.y,
                                              m.linear_acceleration.z]
                           == pytest.approx([0, 0, 9.81], abs=0.05))[-1:]
    assert message.header.frame_id == "robot/imu"
    assert message.orientation_covariance[0] == -1
    assert list(message.angular_velocity_covariance) == [0.0] * 9  # unknown
    w = message.angular_velocity
    assert [w.x, w.y, w.z] == pytest.approx(ours["angular_velocity"], abs=0.05)
    static = first(node.reader("rt/tf_static", ros.TFMessage, LATCHED_QOS))
    assert "robot/imu" in {t.child_frame_id for t in static.transforms}


def test_a_twist_the_robot_refuses_is_counted_and_changes_nothing(rover, node):
    client = rover.socket()

    def motion():
        [stats] = [s for s in client.call("simulation", "get_stream_statistics")
                   if s["component"] == "robot.motion"]
        return stats

    before = motion()
    cmd_vel = node.writer("rt/robot/cmd_vel", ros.Twist)
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline and motion()["refused"] == before["refused"]:
        cmd_vel.write(ros.Twist(linear=ros.Vector3(x=float("nan"))))
        time.sleep(0.1)  # until simgate counts it, bounded by the deadline
    after = motion()
    assert after["refused"] > before["refused"]
    assert "v" in after["last_refusal"], after["last_refusal"]
    client.close()


def matched(endpoint, participant_gid, publications):
    """The endpoints of simgate's participant (`participant_gid`) matched with `endpoint` (a
    reader: the writers; a writer: the readers), as DDS discovery describes them."""
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        if publications:
            found = [endpoint.get_matched_publication_data(h)
                     for h in endpoint.get_matched_publications()]
        else:
            found = [endpoint.get_matched_subscription_data(h)
                     for h in endpoint.get_matched_subscriptions()]
        found = [d for d in found if d is not None and d.participant_key.bytes == participant_gid]
        if found:
            return found
        time.sleep(0.05)  # polling discovery, bounded by the deadline
    pytest.fail(f"simgate's endpoints on {endpoint.topic.name} not matched in {WAIT} s")


def test_ros_graph_names_the_node_and_its_endpoints(rover, node):
    graph = node.reader("ros_discovery_info", ros.ParticipantEntitiesInfo, LATCHED_QOS)
    info = first(graph)
    assert [(n.node_namespace, n.node_name) for n in info.node_entities_info_seq] == [
        ("/", "simgate")]
    participant = bytes(info.gid.data)
    # every ROS endpoint of simgate's participant, as discovery shows it to a matching one
    publications = {}
    for name, cls, qos in [("rt/clock", ros.Clock, DEFAULT_QOS),
                           ("rt/tf", ros.TFMessage, DEFAULT_QOS),
                           ("rt/tf_static", ros.TFMessage, LATCHED_QOS),
                           ("rt/robot/odom", ros.Odometry, DEFAULT_QOS),
                           ("rt/robot/imu", ros.Imu, DEFAULT_QOS)]:
        [publications[name]] = matched(node.reader(name, cls, qos), participant, True)
    [cmd_vel] = matched(node.writer("rt/robot/cmd_vel", ros.Twist), participant, False)
    [graph_writer] = matched(graph, participant, True)
    # the participant's USER_DATA, as rmw_cyclonedds writes it (read by a plain C reader of the
    # DCPSParticipant topic: the Python binding's built-in readers crash)
    if os.environ.get("SIMGATE_ROS2_PROBE"):
        probe = subprocess.run([os.environ["SIMGATE_ROS2_PROBE"], str(node.domain),
                                participant.hex()], capture_output=True, text=True, timeout=30)
        assert probe.returncode == 0, probe.stderr
        assert probe.stdout.strip() == "enclave=/;"

    # the node owns them all: its GIDs are their GUIDs (the graph's own writer apart), beside
    # its services' readers and writers (test_ros2_services.py: one each per service; the
    # SimulateSteps action's three among them) and the action's feedback and status writers
    # (test_ros2_actions.py)
    node_info = info.node_entities_info_seq[0]
    services = 14 + 3
    action_topics = 2
    writers = {gid_hex(g) for g in node_info.writer_gid_seq}
    readers = {gid_hex(g) for g in node_info.reader_gid_seq}
    assert {p.key.bytes.hex() for p in publications.values()} <= writers
    assert len(writers) == len(publications) + services + action_topics
    assert cmd_vel.key.bytes.hex() in readers and len(readers) == 1 + services
    # ROS 2's type names and QoS
    assert {k: v.type_name for k, v in publications.items()} == {
        "rt/clock": "rosgraph_msgs::msg::dds_::Clock_",
        "rt/tf": "tf2_msgs::msg::dds_::TFMessage_",
        "rt/tf_static": "tf2_msgs::msg::dds_::TFMessage_",
        "rt/robot/odom": "nav_msgs::msg::dds_::Odometry_",
        "rt/robot/imu": "sensor_msgs::msg::dds_::Imu_"}
    assert cmd_vel.type_name == "geometry_msgs::msg::dds_::Twist_"
    assert graph_writer.type_name == "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"
    depths = {"rt/clock": 10, "rt/tf": 100, "rt/tf_static": 1, "rt/robot/odom": 10, "rt/robot/imu": 10}
    for name, endpoint in [*publications.items(), ("rt/robot/cmd_vel", cmd_vel),
                           ("ros_discovery_info", graph_writer)]:
        assert isinstance(endpoint.qos[Policy.Reliability], Policy.Reliability.Reliable), name
        latched = name in ("rt/tf_static", "ros_discovery_info")
        assert endpoint.qos[Policy.Durability] == (
            Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile), name
        assert endpoint.qos[Policy.History] == Policy.History.KeepLast(
            depths.get(name, 1 if latched else 10)), name


def test_joint_states_are_the_arms_joints(arm, arm_domain):
    client = arm.socket()
    joints = client.call("arm.armature_pose", "get_joints")
    node = Node(arm_domain)
    message = first(node.reader("rt/arm/joint_states", ros.JointState))
    assert sorted(message.name) == sorted(joints)
    assert len(message.position) == len(message.name)
    assert message.velocity == [] and message.effort == []
    now = client.call("arm.armature_pose", "get_local_data")
    by_name = dict(zip(message.name, message.position))
    for joint in joints:
        assert by_name[joint] == pytest.approx(now[joint], abs=0.05), joint
    client.close()


def test_joint_command_moves_the_arms_joints_and_unknown_names_are_ignored(arm, arm_domain):
    """A sensor_msgs/JointState on /arm/joint_command sets arm.armature's joints (its
    joint_positions input): /arm/joint_states and simgate's own reading follow; a name that is
    no joint of the armature is logged once and left out."""
    node = Node(arm_domain)
    states = node.reader("rt/arm/joint_states", ros.JointState)
    command = node.writer("rt/arm/joint_command", ros.JointState)
    target = {"elbow": 0.6, "wrist_pitch": -0.4}
    message = ros.JointState(name=["elbow", "no_such_joint", "wrist_pitch"],
                             position=[0.6, 1.0, -0.4])

    def there(m):
        by_name = dict(zip(m.name, m.position))
        return all(abs(by_name[j] - v) < 0.03 for j, v in target.items())

    deadline = time.monotonic() + WAIT
    reached = None
    while time.monotonic() < deadline and reached is None:
        command.write(message)
        reached = next((m for m in states.take(N=64) if there(m)), None)
        time.sleep(0.1)  # a command stream's 10 Hz, bounded by the deadline
    assert reached is not None, "the arm did not move on /arm/joint_command"
    client = arm.socket()
    now = client.call("arm.armature_pose", "get_local_data")
    client.close()
    for joint, value in target.items():
        assert now[joint] == pytest.approx(value, abs=0.03), joint
    # written several times, logged once
    assert arm.output().count("'no_such_joint'") == 1, arm.output()


# ---- the bytes on the wire, read and written again by rosbags ----

def as_plain(value):
    """A cyclonedds sample or a rosbags message as nested dicts and lists, to compare."""
    if hasattr(value, "__dataclass_fields__"):
        fields = value.__dataclass_fields__
        return {name: as_plain(getattr(value, name)) for name in fields
                if name != "__msgtype__"}
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if hasattr(value, "tolist"):  # numpy arrays (rosbags)
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [as_plain(v) for v in value]
    return value


def check_bytes(raw, cls, ros_type, store=ROSBAGS):
    # plain CDR, little endian (XCDR1's CDR_LE), as rmw_cyclonedds writes it
    assert raw[:2] == b"\x00\x01", raw[:4].hex()
    message = store.deserialize_cdr(raw, ros_type)
    assert as_plain(message) == as_plain(cls.deserialize(raw))
    again = store.serialize_cdr(message, ros_type)
    # the same bytes; Cyclone pads the payload to a multiple of 4 (the options' low bits say
    # by how much)
    padding = raw[3] & 0x3
    assert raw[4:len(raw) - padding] == again[4:], (raw.hex(), again.hex())
    assert raw[len(raw) - padding:] == b"\x00" * padding


@pytest.mark.parametrize("topic, cls, ros_type, qos", [
    ("rt/clock", ros.Clock, "rosgraph_msgs/msg/Clock", DEFAULT_QOS),
    ("rt/tf", ros.TFMessage, "tf2_msgs/msg/TFMessage", DEFAULT_QOS),
    ("rt/tf_static", ros.TFMessage, "tf2_msgs/msg/TFMessage", LATCHED_QOS),
    ("rt/robot/odom", ros.Odometry, "nav_msgs/msg/Odometry", DEFAULT_QOS),
    ("rt/robot/imu", ros.Imu, "sensor_msgs/msg/Imu", DEFAULT_QOS),
    ("ros_discovery_info", ros.ParticipantEntitiesInfo,
     "rmw_dds_common/msg/ParticipantEntitiesInfo", LATCHED_QOS),
])
def test_rover_bytes_are_ros2_cdr(rover, rover_domain, topic, cls, ros_type, qos):
    recorder = RawRecorder(cls)
    try:
        node = Node(rover_domain)
        first(node.reader(topic, cls, qos))
        assert recorder.raw
        check_bytes(recorder.raw[-1], cls, ros_type)
    finally:
        recorder.close()


def test_joint_state_bytes_are_ros2_cdr(arm, arm_domain):
    recorder = RawRecorder(ros.JointState)
    try:
        node = Node(arm_domain)
        first(node.reader("rt/arm/joint_states", ros.JointState))
        check_bytes(recorder.raw[-1], ros.JointState, "sensor_msgs/msg/JointState")
    finally:
        recorder.close()


# ---- two worlds: world 1's topics in its namespace ----

def test_a_worlds_topics_are_in_its_namespace_and_its_own(worlds_rover, worlds_domain):
    """World 1's streams on /w1/...: its /w1/tf and /w1/tf_static (frames named as world 0's:
    each world's tree is its own), its robot's /w1/robot/odom and /w1/robot/cmd_vel; a robot
    teleported in world 1 shows on /w1/tf only, a Twist on /w1/robot/cmd_vel drives world 1's
    robot only."""
    node = Node(worlds_domain)
    client = worlds_rover.socket()
    tf0 = node.reader("rt/tf", ros.TFMessage)
    tf1 = node.reader("rt/w1/tf", ros.TFMessage)
    odom1 = node.reader("rt/w1/robot/odom", ros.Odometry)
    static1 = first(node.reader("rt/w1/tf_static", ros.TFMessage, LATCHED_QOS))
    scene = client.call("w1/simulation", "get_scene_geometry", False)
    expected = {f["name"].replace(".", "/"): scene["bodies"][f["body"]]["name"]
                for f in scene["frames"]}
    assert {t.child_frame_id: t.header.frame_id for t in static1.transforms} == expected
    message = first(tf1)
    assert sorted(t.child_frame_id for t in message.transforms) == sorted(
        b["name"] for b in scene["bodies"][1:])
    before = first(odom1)
    assert (before.header.frame_id, before.child_frame_id) == ("robot/odom", "robot/odometry")

    # teleported in world 1: there on /w1/tf, not on /tf
    client.call("w1/robot.teleport", "translate", 0, 3)

    def robot_y(sample):
        return next(t.transform.translation.y for t in sample.transforms
                    if t.child_frame_id == "robot")
    take_until(tf1, lambda s: robot_y(s) > 2.5)
    assert abs(robot_y(take_until(tf0, lambda s: True)[-1])) < 1

    # driven on /w1/robot/cmd_vel: world 1's robot moves, world 0's stays
    x0 = client.call("simulation", "get_object_pose", "robot")[0][0]
    cmd_vel = node.writer("rt/w1/robot/cmd_vel", ros.Twist)
    try:
        start = first(odom1).pose.pose.position.x
        deadline = time.monotonic() + WAIT
        moved = False
        while time.monotonic() < deadline and not moved:
            cmd_vel.write(ros.Twist(linear=ros.Vector3(x=0.5), angular=ros.Vector3(z=0.0)))
            moved = any(s.pose.pose.position.x > start + 0.2 for s in odom1.take(N=64))
            time.sleep(0.05)  # a teleop's 20 Hz, bounded by the deadline
        assert moved, "world 1's robot did not move on /w1/robot/cmd_vel"
    finally:
        cmd_vel.write(ros.Twist())
    assert client.call("w1/simulation", "get_object_pose", "robot")[0][0] > 0.2
    assert client.call("simulation", "get_object_pose", "robot")[0][0] == pytest.approx(
        x0, abs=0.02)
    client.close()


# ---- a robot with a pose sensor only; the options ----

def test_pose_sensor_gives_odom_in_the_world_frame(pose_rover, pose_domain):
    node = Node(pose_domain)
    odom = first(node.reader("rt/robot/odom", ros.Odometry))
    assert odom.header.frame_id == "map"
    assert odom.child_frame_id == "robot"
    assert odom.twist.covariance[0] == -1  # no velocity in a pose sample: unknown
    pose = pose_rover.socket().call("simulation", "get_object_pose", "robot")
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    assert [p.x, p.y, p.z] == pytest.approx(pose[0], abs=1e-3)
    assert [q.x, q.y, q.z, q.w] == pytest.approx(pose[1], abs=1e-3)
    # no simulation stream here: no /tf writer; cmd_vel is read
    probe = node.reader("rt/tf", ros.TFMessage)
    cmd_vel = node.writer("rt/robot/cmd_vel", ros.Twist)
    deadline = time.monotonic() + WAIT
    while not cmd_vel.get_matched_subscriptions() and time.monotonic() < deadline:
        time.sleep(0.05)  # polling discovery, bounded by the deadline
    assert cmd_vel.get_matched_subscriptions()
    assert probe.get_matched_publications() == []


@pytest.mark.parametrize("options, expected", [
    ({"node_name": "1simgate"}, "node_name"),
    ({"node_name": "sim-gate"}, "node_name"),
    ({"domain": 231}, "domain"),
    ({"clock_hz": -1}, "clock_hz"),
    ({"robots": "robot"}, "robots"),
    ({"robots": ["robot", "robot"]}, "robots[1]"),
    ({"world_frame": "/world"}, "world_frame"),
    ({"tf": "yes"}, "tf"),
    ({"clock": 100}, "clock"),
    ({"ros_distro": "foxy"}, "ros_distro"),
    ({"feedback_interval_ms": 60001}, "feedback_interval_ms"),
    ({"config": "<CycloneDDS><Domain><Bogus/></Domain></CycloneDDS>"}, "config"),
])
def test_bad_options_are_refused_with_their_key(tmp_path, options, expected):
    code, output = check_config(tmp_path, options)
    assert code != 0, output
    assert "ros2" in output and expected in output, output


def test_good_options_pass_the_check(tmp_path):
    code, output = check_config(tmp_path, {"domain": 7, "node_name": "sim_1", "clock_hz": 0,
                                           "robots": ["robot"], "world_frame": "map",
                                           "tf": False, "ros_distro": "humble"})
    assert code == 0, output


def test_humble_graph_has_24_byte_gids(pose_rover, pose_domain):
    recorder = RawRecorder(ros.HumbleParticipantEntitiesInfo)
    try:
        node = Node(pose_domain)
        info = first(node.reader("ros_discovery_info", ros.HumbleParticipantEntitiesInfo,
                                 LATCHED_QOS))
        assert info.node_entities_info_seq[0].node_name == "simgate"
        # the GUID, then zeros (as Humble's rmw_cyclonedds fills a GID)
        gid = bytes(info.gid.data)
        assert gid[12:16] == b"\x00\x00\x01\xc1" and gid[16:] == bytes(8)
        writers = info.node_entities_info_seq[0].writer_gid_seq
        assert writers and all(bytes(w.data)[:12] == gid[:12] for w in writers)
        check_bytes(recorder.raw[-1], ros.HumbleParticipantEntitiesInfo,
                    "rmw_dds_common/msg/ParticipantEntitiesInfo",
                    get_typestore(Stores.ROS2_HUMBLE))
    finally:
        recorder.close()


def test_the_shipped_config_passes_the_check():
    command = [simgate_binary(), "check", os.path.join(SOURCE_DIR, "config", "ros2.json")]
    if os.environ.get("SIMGATE_PLUGIN_DIR"):
        command += ["--plugin-path", os.environ["SIMGATE_PLUGIN_DIR"]]
    done = subprocess.run(command, capture_output=True, text=True, timeout=START_TIMEOUT)
    assert done.returncode == 0, done.stdout + done.stderr


# ---- a laser and cameras (config/rover.json's rover) ----

def png_pixels(data):
    """(width, height, bytes of the rows) of a PNG simgate wrote (sim/image_codec.h: no
    interlace, filter None on every row): its IDAT inflated, each row's filter byte checked and
    dropped."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    position, idat = 8, b""
    while position < len(data):
        length, kind = struct.unpack(">I4s", data[position:position + 8])
        body = data[position + 8:position + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
        elif kind == b"IDAT":
            idat += body
        position += 12 + length
    pixel = (3 if colour == 2 else 1) * depth // 8
    raw = zlib.decompress(idat)
    stride = width * pixel + 1
    rows = [raw[y * stride:(y + 1) * stride] for y in range(height)]
    assert all(row[0] == 0 for row in rows)
    return width, height, b"".join(row[1:] for row in rows)


def own_image(client, camera):
    """simgate's own image of `camera` now (get_image: PNG in base64), or the test skipped when
    nothing can render here."""
    try:
        return client.call(camera, "get_image")
    except RuntimeError as e:
        if "cannot render" in str(e):
            pytest.skip(str(e))
        raise


def settled(client, timeout=WAIT):
    """Waits until the rover stands still (it settles on its wheels at the start): two poses
    0.2 s apart agree."""
    deadline = time.monotonic() + timeout
    before = client.call("simulation", "get_object_pose", "rover")
    while time.monotonic() < deadline:
        time.sleep(0.2)  # polling simgate, bounded by the deadline
        now = client.call("simulation", "get_object_pose", "rover")
        if now[0] + now[1] == pytest.approx(before[0] + before[1], abs=1e-6):
            return
        before = now
    pytest.fail("the rover did not settle")


@pytest.fixture(scope="module")
def sensors(sensor_rover, sensors_domain):
    client = sensor_rover.socket()
    settled(client)
    yield client
    client.close()


def test_scan_has_the_lasers_ranges_arc_and_frame(sensor_rover, sensors_domain, sensors):
    """/rover/laser/scan from rover.laser (270° every 1°, 10 m): each hit's range as simgate
    reads it, +inf for a miss (REP 117), the arc of the scanner's options, in its frame."""
    ours = sensors.call("rover.laser", "get_local_data")
    properties = sensors.call("rover.laser", "get_properties")["properties"]
    node = Node(sensors_domain)
    scan = first(node.reader("rt/rover/laser/scan", ros.LaserScan))
    assert scan.header.frame_id == "rover/laser"
    assert len(scan.ranges) == properties["ray_count"] == 271
    assert scan.angle_min == pytest.approx(math.radians(-135), abs=1e-6)
    assert scan.angle_max == pytest.approx(math.radians(135), abs=1e-6)
    assert scan.angle_increment == pytest.approx(math.radians(1), abs=1e-6)
    assert scan.scan_time == pytest.approx(0.1)  # 10 scans a second
    assert scan.time_increment == 0 and scan.range_min == 0 and scan.intensities == []
    misses = [p == [0, 0, 0] for p in ours["point_list"]]
    assert any(misses) and not all(misses)  # the door's gap: rays leave the room
    assert scan.range_max == pytest.approx(properties["laser_range"])
    for i, (got, expected) in enumerate(zip(scan.ranges, ours["range_list"])):
        if misses[i]:
            assert got == math.inf, i
        else:
            assert got == pytest.approx(expected, abs=1e-4), i
    static = first(node.reader("rt/tf_static", ros.TFMessage, LATCHED_QOS))
    frames = {t.child_frame_id for t in static.transforms}
    assert {"rover/laser", "rover/camera", "rover/depth"} <= frames


def matching_info(reader, stamp):
    """The camera_info of the image stamped `stamp`."""
    return take_until(reader, lambda m: (m.header.stamp.sec, m.header.stamp.nanosec) ==
                      (stamp.sec, stamp.nanosec))[-1]


def test_camera_image_is_what_the_camera_sees_with_its_camera_info(sensor_rover, sensors_domain,
                                                                  sensors):
    """/rover/camera/image_raw: rgb8, the pixels get_image shows of the same still scene, in the
    camera's optical frame; /rover/camera/camera_info: the same stamp and frame, K the camera's
    intrinsic matrix, P = [K | 0], R identity, plumb_bob with no distortion."""
    record = own_image(sensors, "rover.camera")
    width, height, pixels = png_pixels(base64.b64decode(record["image"]))
    node = Node(sensors_domain)
    infos = node.reader("rt/rover/camera/camera_info", ros.CameraInfo)
    image = first(node.reader("rt/rover/camera/image_raw", ros.Image))
    assert (image.width, image.height) == (width, height) == (160, 120)
    assert image.encoding == "rgb8" and image.step == 3 * 160 and image.is_bigendian == 0
    assert image.header.frame_id == "rover/camera"
    data = bytes(image.data)
    assert len(data) == image.step * image.height
    assert len(set(data)) > 16  # a scene, not a blank
    # the same still scene: the same pixels (a few may differ by a level or two)
    differing = sum(1 for a, b in zip(data, pixels) if abs(a - b) > 2)
    assert differing <= len(data) // 100, differing
    info = matching_info(infos, image.header.stamp)
    assert info.header.frame_id == "rover/camera"
    assert (info.width, info.height) == (160, 120)
    k = [v for row in record["intrinsic_matrix"] for v in row]
    assert list(info.k) == pytest.approx(k)
    assert list(info.p) == pytest.approx(k[0:3] + [0] + k[3:6] + [0] + k[6:9] + [0])
    assert list(info.r) == [1, 0, 0, 0, 1, 0, 0, 0, 1]
    assert info.distortion_model == "plumb_bob" and list(info.d) == [0.0] * 5


def test_depth_image_is_in_metres_as_the_depth_camera_sees(sensor_rover, sensors_domain, sensors):
    """/rover/depth/image_raw: 32FC1, metres, what get_image's 16-bit PNG says in millimetres."""
    record = own_image(sensors, "rover.depth")
    width, height, millimetres = png_pixels(base64.b64decode(record["image"]))
    expected = struct.unpack(f">{width * height}H", millimetres)
    node = Node(sensors_domain)
    image = first(node.reader("rt/rover/depth/image_raw", ros.Image))
    assert image.encoding == "32FC1" and (image.width, image.height) == (160, 120)
    assert image.step == 4 * image.width and image.header.frame_id == "rover/depth"
    metres = struct.unpack(f"{'>' if image.is_bigendian else '<'}{width * height}f",
                           bytes(image.data))
    close = sum(1 for m, mm in zip(metres, expected) if abs(m * 1000 - mm) <= 1.5)
    assert close >= len(expected) * 99 // 100, close
    assert any(m > 0 for m in metres)
    info = first(node.reader("rt/rover/depth/camera_info", ros.CameraInfo))
    assert info.header.frame_id == "rover/depth" and (info.width, info.height) == (160, 120)


def test_a_camera_renders_only_while_a_ros_reader_reads_it(sensor_rover, sensors_domain,
                                                          sensors):
    """rover.depth is subscribed to (rendered) only while a reader of its image_raw or
    camera_info is matched: none, then one reader of its camera_info, then none again."""
    def subscribers():
        [stats] = [s for s in sensors.call("simulation", "get_stream_statistics")
                   if s["component"] == "rover.depth"]
        return stats["subscribers"]

    def wait_for(count):
        deadline = time.monotonic() + WAIT
        while subscribers() != count:
            assert time.monotonic() < deadline, f"rover.depth: {subscribers()} subscribers"
            time.sleep(0.05)  # polling simgate, bounded by the deadline

    gc.collect()  # other tests' readers gone
    wait_for(0)
    node = Node(sensors_domain)
    reader = node.reader("rt/rover/depth/camera_info", ros.CameraInfo)
    wait_for(1)
    first(reader)
    del reader, node
    gc.collect()
    wait_for(0)


def test_sensor_topics_are_the_nodes_with_ros_types(sensor_rover, sensors_domain):
    """The graph names the cameras' and the laser's writers as /simgate's, with ROS 2's type
    names and its default QoS."""
    node = Node(sensors_domain)
    graph = node.reader("ros_discovery_info", ros.ParticipantEntitiesInfo, LATCHED_QOS)
    info = first(graph)
    participant = bytes(info.gid.data)
    writers = {gid_hex(g) for g in info.node_entities_info_seq[0].writer_gid_seq}
    for name, cls, type_name in [
            ("rt/rover/laser/scan", ros.LaserScan, "sensor_msgs::msg::dds_::LaserScan_"),
            ("rt/rover/camera/image_raw", ros.Image, "sensor_msgs::msg::dds_::Image_"),
            ("rt/rover/camera/camera_info", ros.CameraInfo,
             "sensor_msgs::msg::dds_::CameraInfo_"),
            ("rt/rover/depth/image_raw", ros.Image, "sensor_msgs::msg::dds_::Image_"),
            ("rt/rover/depth/camera_info", ros.CameraInfo, "sensor_msgs::msg::dds_::CameraInfo_")]:
        [writer] = matched(node.reader(name, cls), participant, True)
        assert writer.key.bytes.hex() in writers, name
        assert writer.type_name == type_name, name
        assert isinstance(writer.qos[Policy.Reliability], Policy.Reliability.Reliable), name
        assert writer.qos[Policy.Durability] == Policy.Durability.Volatile, name
        assert writer.qos[Policy.History] == Policy.History.KeepLast(10), name


@pytest.mark.parametrize("topic, cls, ros_type", [
    ("rt/rover/laser/scan", ros.LaserScan, "sensor_msgs/msg/LaserScan"),
    ("rt/rover/camera/image_raw", ros.Image, "sensor_msgs/msg/Image"),
    ("rt/rover/camera/camera_info", ros.CameraInfo, "sensor_msgs/msg/CameraInfo"),
])
def test_sensor_bytes_are_ros2_cdr(sensor_rover, sensors_domain, sensors, topic, cls, ros_type):
    if "camera" in topic:
        own_image(sensors, "rover.camera")  # skipped when nothing renders here
    recorder = RawRecorder(cls)
    try:
        node = Node(sensors_domain)
        first(node.reader(topic, cls))
        check_bytes(recorder.raw[-1], cls, ros_type)
    finally:
        recorder.close()
