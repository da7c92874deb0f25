"""ROS 2 message types as ROS 2 puts them on DDS, declared by hand for the cyclonedds Python
binding from the published .msg definitions (no simgate code, no generated code): each
IdlStruct carries the type name rmw_cyclonedds gives it (<pkg>::msg::dds_::<Msg>_), so that
a reader of these types is what a ROS 2 node's reader is to simgate."""

from dataclasses import dataclass, field

from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32 = 0
    nanosec: t.uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0
    w: t.float64 = 1.0


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: t.sequence[TransformStamped] = field(default_factory=list)


@dataclass
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time = field(default_factory=Time)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose = field(default_factory=Pose)
    covariance: t.array[t.float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist = field(default_factory=Twist)
    covariance: t.array[t.float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class Imu(IdlStruct, typename="sensor_msgs::msg::dds_::Imu_"):
    header: Header = field(default_factory=Header)
    orientation: Quaternion = field(default_factory=Quaternion)
    orientation_covariance: t.array[t.float64, 9] = field(default_factory=lambda: [0.0] * 9)
    angular_velocity: Vector3 = field(default_factory=Vector3)
    angular_velocity_covariance: t.array[t.float64, 9] = field(default_factory=lambda: [0.0] * 9)
    linear_acceleration: Vector3 = field(default_factory=Vector3)
    linear_acceleration_covariance: t.array[t.float64, 9] = field(default_factory=lambda: [0.0] * 9)


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = field(default_factory=Header)
    name: t.sequence[str] = field(default_factory=list)
    position: t.sequence[t.float64] = field(default_factory=list)
    velocity: t.sequence[t.float64] = field(default_factory=list)
    effort: t.sequence[t.float64] = field(default_factory=list)


@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header = field(default_factory=Header)
    height: t.uint32 = 0
    width: t.uint32 = 0
    encoding: str = ""
    is_bigendian: t.uint8 = 0
    step: t.uint32 = 0
    data: t.sequence[t.uint8] = field(default_factory=list)


@dataclass
class RegionOfInterest(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
    x_offset: t.uint32 = 0
    y_offset: t.uint32 = 0
    height: t.uint32 = 0
    width: t.uint32 = 0
    do_rectify: bool = False


@dataclass
class CameraInfo(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
    header: Header = field(default_factory=Header)
    height: t.uint32 = 0
    width: t.uint32 = 0
    distortion_model: str = ""
    d: t.sequence[t.float64] = field(default_factory=list)
    k: t.array[t.float64, 9] = field(default_factory=lambda: [0.0] * 9)
    r: t.array[t.float64, 9] = field(default_factory=lambda: [0.0] * 9)
    p: t.array[t.float64, 12] = field(default_factory=lambda: [0.0] * 12)
    binning_x: t.uint32 = 0
    binning_y: t.uint32 = 0
    roi: RegionOfInterest = field(default_factory=RegionOfInterest)


@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header = field(default_factory=Header)
    angle_min: t.float32 = 0.0
    angle_max: t.float32 = 0.0
    angle_increment: t.float32 = 0.0
    time_increment: t.float32 = 0.0
    scan_time: t.float32 = 0.0
    range_min: t.float32 = 0.0
    range_max: t.float32 = 0.0
    ranges: t.sequence[t.float32] = field(default_factory=list)
    intensities: t.sequence[t.float32] = field(default_factory=list)


@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: t.array[t.uint8, 16] = field(default_factory=lambda: [0] * 16)


@dataclass
class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: t.bounded_str[256] = ""
    node_name: t.bounded_str[256] = ""
    reader_gid_seq: t.sequence[Gid] = field(default_factory=list)
    writer_gid_seq: t.sequence[Gid] = field(default_factory=list)


@dataclass
class ParticipantEntitiesInfo(
    IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"
):
    gid: Gid = field(default_factory=Gid)
    node_entities_info_seq: t.sequence[NodeEntitiesInfo] = field(default_factory=list)


# ROS 2 Humble's graph types: the same names, a Gid of 24 bytes (char[24] in Humble's
# rmw_dds_common/msg/Gid.msg; 16 from Iron on)
@dataclass
class HumbleGid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: t.array[t.uint8, 24] = field(default_factory=lambda: [0] * 24)


@dataclass
class HumbleNodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: t.bounded_str[256] = ""
    node_name: t.bounded_str[256] = ""
    reader_gid_seq: t.sequence[HumbleGid] = field(default_factory=list)
    writer_gid_seq: t.sequence[HumbleGid] = field(default_factory=list)


@dataclass
class HumbleParticipantEntitiesInfo(
    IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"
):
    gid: HumbleGid = field(default_factory=HumbleGid)
    node_entities_info_seq: t.sequence[HumbleNodeEntitiesInfo] = field(default_factory=list)


# ---- services: ros-simulation/simulation_interfaces 2.1 and simgate_interfaces/srv/Call ----
# A service's request and reply types as rmw_cyclonedds puts them on DDS: the type names of the
# request and response messages (<pkg>::srv::dds_::<Srv>_Request_ / _Response_), each sample
# beginning with rmw_cyclonedds' header (the client's id, the request's sequence number).

@dataclass
class Accel(IdlStruct, typename="geometry_msgs::msg::dds_::Accel_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass
class Result(IdlStruct, typename="simulation_interfaces::msg::dds_::Result_"):
    result: t.uint8 = 0
    error_message: str = ""


@dataclass
class SimulationState(IdlStruct, typename="simulation_interfaces::msg::dds_::SimulationState_"):
    state: t.uint8 = 0


@dataclass
class SimulatorFeatures(IdlStruct, typename="simulation_interfaces::msg::dds_::SimulatorFeatures_"):
    features: t.sequence[t.uint16] = field(default_factory=list)
    spawn_formats: t.sequence[str] = field(default_factory=list)
    custom_info: str = ""


@dataclass
class EntityState(IdlStruct, typename="simulation_interfaces::msg::dds_::EntityState_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)
    twist: Twist = field(default_factory=Twist)
    acceleration: Accel = field(default_factory=Accel)


@dataclass
class EntityCategory(IdlStruct, typename="simulation_interfaces::msg::dds_::EntityCategory_"):
    category: t.uint8 = 0


@dataclass
class EntityInfo(IdlStruct, typename="simulation_interfaces::msg::dds_::EntityInfo_"):
    category: EntityCategory = field(default_factory=EntityCategory)
    description: str = ""
    tags: t.sequence[str] = field(default_factory=list)


@dataclass
class TagsFilter(IdlStruct, typename="simulation_interfaces::msg::dds_::TagsFilter_"):
    tags: t.sequence[str] = field(default_factory=list)
    filter_mode: t.uint8 = 0


@dataclass
class Bounds(IdlStruct, typename="simulation_interfaces::msg::dds_::Bounds_"):
    type: t.uint8 = 0
    points: t.sequence[Vector3] = field(default_factory=list)


@dataclass
class EntityFilters(IdlStruct, typename="simulation_interfaces::msg::dds_::EntityFilters_"):
    filter: str = ""
    categories: t.sequence[EntityCategory] = field(default_factory=list)
    tags: TagsFilter = field(default_factory=TagsFilter)
    bounds: Bounds = field(default_factory=Bounds)


@dataclass
class Resource(IdlStruct, typename="simulation_interfaces::msg::dds_::Resource_"):
    uri: str = ""
    resource_string: str = ""


def _srv(name):
    return f"simulation_interfaces::srv::dds_::{name}"


@dataclass
class GetSimulatorFeaturesRequest(IdlStruct, typename=_srv("GetSimulatorFeatures_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    structure_needs_at_least_one_member: t.uint8 = 0  # ROS 2's member of an empty message


@dataclass
class GetSimulatorFeaturesResponse(IdlStruct, typename=_srv("GetSimulatorFeatures_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    features: SimulatorFeatures = field(default_factory=SimulatorFeatures)


@dataclass
class GetSimulationStateRequest(IdlStruct, typename=_srv("GetSimulationState_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    structure_needs_at_least_one_member: t.uint8 = 0


@dataclass
class GetSimulationStateResponse(IdlStruct, typename=_srv("GetSimulationState_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    state: SimulationState = field(default_factory=SimulationState)
    result: Result = field(default_factory=Result)


@dataclass
class SetSimulationStateRequest(IdlStruct, typename=_srv("SetSimulationState_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    state: SimulationState = field(default_factory=SimulationState)


@dataclass
class SetSimulationStateResponse(IdlStruct, typename=_srv("SetSimulationState_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)


@dataclass
class StepSimulationRequest(IdlStruct, typename=_srv("StepSimulation_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    steps: t.uint64 = 1


@dataclass
class StepSimulationResponse(IdlStruct, typename=_srv("StepSimulation_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)


@dataclass
class ResetSimulationRequest(IdlStruct, typename=_srv("ResetSimulation_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    scope: t.uint8 = 0


@dataclass
class ResetSimulationResponse(IdlStruct, typename=_srv("ResetSimulation_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)


@dataclass
class GetEntitiesRequest(IdlStruct, typename=_srv("GetEntities_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    filters: EntityFilters = field(default_factory=EntityFilters)


@dataclass
class GetEntitiesResponse(IdlStruct, typename=_srv("GetEntities_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)
    entities: t.sequence[str] = field(default_factory=list)


@dataclass
class GetEntitiesStatesRequest(IdlStruct, typename=_srv("GetEntitiesStates_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    filters: EntityFilters = field(default_factory=EntityFilters)


@dataclass
class GetEntitiesStatesResponse(IdlStruct, typename=_srv("GetEntitiesStates_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)
    entities: t.sequence[str] = field(default_factory=list)
    states: t.sequence[EntityState] = field(default_factory=list)


@dataclass
class GetEntityStateRequest(IdlStruct, typename=_srv("GetEntityState_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    entity: str = ""


@dataclass
class GetEntityStateResponse(IdlStruct, typename=_srv("GetEntityState_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)
    state: EntityState = field(default_factory=EntityState)


@dataclass
class SetEntityStateRequest(IdlStruct, typename=_srv("SetEntityState_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    entity: str = ""
    state: EntityState = field(default_factory=EntityState)
    set_pose: bool = False
    set_twist: bool = False
    set_acceleration: bool = False


@dataclass
class SetEntityStateResponse(IdlStruct, typename=_srv("SetEntityState_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)


@dataclass
class GetEntityInfoRequest(IdlStruct, typename=_srv("GetEntityInfo_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    entity: str = ""


@dataclass
class GetEntityInfoResponse(IdlStruct, typename=_srv("GetEntityInfo_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)
    info: EntityInfo = field(default_factory=EntityInfo)


@dataclass
class GetEntityBoundsRequest(IdlStruct, typename=_srv("GetEntityBounds_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    entity: str = ""


@dataclass
class GetEntityBoundsResponse(IdlStruct, typename=_srv("GetEntityBounds_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)
    bounds: Bounds = field(default_factory=Bounds)


@dataclass
class SpawnEntityRequest(IdlStruct, typename=_srv("SpawnEntity_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    name: str = ""
    allow_renaming: bool = False
    entity_resource: Resource = field(default_factory=Resource)
    entity_namespace: str = ""
    initial_pose: PoseStamped = field(default_factory=PoseStamped)


@dataclass
class SpawnEntityResponse(IdlStruct, typename=_srv("SpawnEntity_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)
    entity_name: str = ""


@dataclass
class DeleteEntityRequest(IdlStruct, typename=_srv("DeleteEntity_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    entity: str = ""


@dataclass
class DeleteEntityResponse(IdlStruct, typename=_srv("DeleteEntity_Response_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    result: Result = field(default_factory=Result)


@dataclass
class CallRequest(IdlStruct, typename="simgate_interfaces::srv::dds_::Call_Request_"):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    component: str = ""
    service: str = ""
    arguments: str = ""
    timeout_ms: t.uint32 = 0


@dataclass
class CallResponse(IdlStruct, typename="simgate_interfaces::srv::dds_::Call_Response_"):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    status: str = ""
    message: str = ""
    result: str = ""


# ---- the SimulateSteps action (simulation_interfaces 2.1) as rcl_action puts an action on DDS:
# ros2/unique_identifier_msgs' UUID, ros2/rcl_interfaces' action_msgs, and the types ROS 2's IDL
# generator derives from action/SimulateSteps.action (<A>_Goal, _Result, _Feedback, the services
# <A>_SendGoal and <A>_GetResult, the message <A>_FeedbackMessage, in <pkg>::action::dds_) ----

@dataclass
class UUID(IdlStruct, typename="unique_identifier_msgs::msg::dds_::UUID_"):
    uuid: t.array[t.uint8, 16] = field(default_factory=lambda: [0] * 16)


@dataclass
class GoalInfo(IdlStruct, typename="action_msgs::msg::dds_::GoalInfo_"):
    goal_id: UUID = field(default_factory=UUID)
    stamp: Time = field(default_factory=Time)


@dataclass
class GoalStatus(IdlStruct, typename="action_msgs::msg::dds_::GoalStatus_"):
    goal_info: GoalInfo = field(default_factory=GoalInfo)
    status: t.int8 = 0


@dataclass
class GoalStatusArray(IdlStruct, typename="action_msgs::msg::dds_::GoalStatusArray_"):
    status_list: t.sequence[GoalStatus] = field(default_factory=list)


@dataclass
class CancelGoalRequest(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Request_"):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    goal_info: GoalInfo = field(default_factory=GoalInfo)


@dataclass
class CancelGoalResponse(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Response_"):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    return_code: t.int8 = 0
    goals_canceling: t.sequence[GoalInfo] = field(default_factory=list)


def _action(name):
    return f"simulation_interfaces::action::dds_::{name}"


@dataclass
class SimulateStepsGoal(IdlStruct, typename=_action("SimulateSteps_Goal_")):
    steps: t.uint64 = 0


@dataclass
class SimulateStepsResult(IdlStruct, typename=_action("SimulateSteps_Result_")):
    result: Result = field(default_factory=Result)


@dataclass
class SimulateStepsFeedback(IdlStruct, typename=_action("SimulateSteps_Feedback_")):
    completed_steps: t.uint64 = 0
    remaining_steps: t.uint64 = 0


@dataclass
class SimulateStepsSendGoalRequest(IdlStruct, typename=_action("SimulateSteps_SendGoal_Request_")):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    goal_id: UUID = field(default_factory=UUID)
    goal: SimulateStepsGoal = field(default_factory=SimulateStepsGoal)


@dataclass
class SimulateStepsSendGoalResponse(
    IdlStruct, typename=_action("SimulateSteps_SendGoal_Response_")
):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    accepted: bool = False
    stamp: Time = field(default_factory=Time)


@dataclass
class SimulateStepsGetResultRequest(
    IdlStruct, typename=_action("SimulateSteps_GetResult_Request_")
):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    goal_id: UUID = field(default_factory=UUID)


@dataclass
class SimulateStepsGetResultResponse(
    IdlStruct, typename=_action("SimulateSteps_GetResult_Response_")
):
    client_guid: t.uint64 = 0
    sequence: t.int64 = 0
    status: t.int8 = 0
    result: SimulateStepsResult = field(default_factory=SimulateStepsResult)


@dataclass
class SimulateStepsFeedbackMessage(IdlStruct, typename=_action("SimulateSteps_FeedbackMessage_")):
    goal_id: UUID = field(default_factory=UUID)
    feedback: SimulateStepsFeedback = field(default_factory=SimulateStepsFeedback)
