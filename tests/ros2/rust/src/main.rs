//! simgate_ros2_rust_probe: a ROS 2 node written with crates.io's ros2-client (Atostek's pure
//! Rust ROS 2 on RustDDS, no ROS 2 installed), used by tests/ros2/test_ros2_rust_client.py to
//! read simgate's ros2 transport as a third-party ROS 2 client would (docs/transports/ros2.md).
//!
//! It subscribes to /clock and /tf, waits for one sample of each, then calls the
//! simulation_interfaces services with rmw_cyclonedds' service mapping
//! (ServiceMapping::Cyclone): /get_simulation_state, /set_simulation_state (paused),
//! /step_simulation, /get_simulation_state, /get_entities; and prints one JSON object on
//! stdout with what it got. Every wait is bounded: on a timeout it says what it waited for on
//! stderr and exits with status 3.
//!
//!   simgate_ros2_rust_probe --domain N [--timeout S] [--call-timeout S] [--steps N] [--gate]
//!
//! --gate: once the simulation is paused, print "simgate_ros2_rust_probe: paused" on stderr
//! and wait (bounded by --timeout) for a line on stdin before stepping, so that a test can read
//! the simulated time between the pause and the step.
//!
//! The message and service types below are declared by hand from the published .msg/.srv
//! definitions (builtin_interfaces, rosgraph_msgs, std_msgs, geometry_msgs, tf2_msgs,
//! ros-simulation/simulation_interfaces 2.1): fields in the definitions' order, as ROS 2's CDR
//! has them. Constants are not on the wire.

use std::future::Future;
use std::io::{BufRead, Write};
use std::net::{IpAddr, Ipv4Addr};
use std::pin::pin;
use std::process::exit;
use std::sync::mpsc;
use std::task::Context as TaskContext;
use std::thread;
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::qos::History;
use ros2_client::{
  Client, Context, Message, MessageTypeName, Name, Node, NodeName, NodeOptions, QosProfile,
  ServiceMapping, ServiceTypeName, Subscription,
};
use serde::{Deserialize, Serialize};

// ---- message types, from the .msg definitions

/// builtin_interfaces/msg/Time
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
struct Time {
  sec: i32,
  nanosec: u32,
}

impl Time {
  fn seconds(&self) -> f64 {
    self.sec as f64 + self.nanosec as f64 * 1e-9
  }
}

/// rosgraph_msgs/msg/Clock
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Clock {
  clock: Time,
}
impl Message for Clock {}

/// std_msgs/msg/Header
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct Header {
  stamp: Time,
  frame_id: String,
}

/// geometry_msgs/msg/Vector3
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct Vector3 {
  x: f64,
  y: f64,
  z: f64,
}

/// geometry_msgs/msg/Quaternion
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct Quaternion {
  x: f64,
  y: f64,
  z: f64,
  w: f64,
}

/// geometry_msgs/msg/Transform
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct Transform {
  translation: Vector3,
  rotation: Quaternion,
}

/// geometry_msgs/msg/TransformStamped
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct TransformStamped {
  header: Header,
  child_frame_id: String,
  transform: Transform,
}

/// tf2_msgs/msg/TFMessage
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct TfMessage {
  transforms: Vec<TransformStamped>,
}
impl Message for TfMessage {}

/// simulation_interfaces/msg/Result
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct SimResult {
  result: u8,
  error_message: String,
}

/// simulation_interfaces/msg/SimulationState
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct SimulationState {
  state: u8,
}
const STATE_PAUSED: u8 = 2;

/// simulation_interfaces/msg/EntityCategory
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct EntityCategory {
  category: u8,
}

/// simulation_interfaces/msg/TagsFilter
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct TagsFilter {
  tags: Vec<String>,
  filter_mode: u8,
}

/// simulation_interfaces/msg/Bounds (its field `type` is `kind` here: a Rust keyword)
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct Bounds {
  kind: u8,
  points: Vec<Vector3>,
}

/// simulation_interfaces/msg/EntityFilters
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct EntityFilters {
  filter: String,
  categories: Vec<EntityCategory>,
  tags: TagsFilter,
  bounds: Bounds,
}

// ---- service types, from the .srv definitions (ROS 2 gives an empty request one uint8)

/// simulation_interfaces/srv/GetSimulationState
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct GetSimulationStateRequest {
  structure_needs_at_least_one_member: u8,
}
impl Message for GetSimulationStateRequest {}
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct GetSimulationStateResponse {
  state: SimulationState,
  result: SimResult,
}
impl Message for GetSimulationStateResponse {}

/// simulation_interfaces/srv/SetSimulationState
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct SetSimulationStateRequest {
  state: SimulationState,
}
impl Message for SetSimulationStateRequest {}
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct SetSimulationStateResponse {
  result: SimResult,
}
impl Message for SetSimulationStateResponse {}

/// simulation_interfaces/srv/StepSimulation
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct StepSimulationRequest {
  steps: u64,
}
impl Message for StepSimulationRequest {}
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct StepSimulationResponse {
  result: SimResult,
}
impl Message for StepSimulationResponse {}

/// simulation_interfaces/srv/GetEntities
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct GetEntitiesRequest {
  filters: EntityFilters,
}
impl Message for GetEntitiesRequest {}
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct GetEntitiesResponse {
  result: SimResult,
  entities: Vec<String>,
}
impl Message for GetEntitiesResponse {}

// ---- a small JSON writer for the one object printed

enum Json {
  Null,
  Bool(bool),
  Int(i64),
  Num(f64),
  Str(String),
  Arr(Vec<Json>),
  Obj(Vec<(String, Json)>),
}

impl Json {
  fn obj(fields: Vec<(&str, Json)>) -> Json {
    Json::Obj(fields.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
  }

  fn write(&self, out: &mut String) {
    match self {
      Json::Null => out.push_str("null"),
      Json::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
      Json::Int(i) => out.push_str(&i.to_string()),
      Json::Num(x) if x.is_finite() => out.push_str(&format!("{x:?}")),
      Json::Num(_) => out.push_str("null"),
      Json::Str(s) => write_json_string(s, out),
      Json::Arr(items) => {
        out.push('[');
        for (i, item) in items.iter().enumerate() {
          if i > 0 {
            out.push_str(", ");
          }
          item.write(out);
        }
        out.push(']');
      }
      Json::Obj(fields) => {
        out.push('{');
        for (i, (key, value)) in fields.iter().enumerate() {
          if i > 0 {
            out.push_str(", ");
          }
          write_json_string(key, out);
          out.push_str(": ");
          value.write(out);
        }
        out.push('}');
      }
    }
  }
}

fn write_json_string(s: &str, out: &mut String) {
  out.push('"');
  for c in s.chars() {
    match c {
      '"' => out.push_str("\\\""),
      '\\' => out.push_str("\\\\"),
      '\n' => out.push_str("\\n"),
      '\r' => out.push_str("\\r"),
      '\t' => out.push_str("\\t"),
      c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
      c => out.push(c),
    }
  }
  out.push('"');
}

fn time_json(t: &Time) -> Json {
  Json::obj(vec![
    ("sec", Json::Int(t.sec as i64)),
    ("nanosec", Json::Int(t.nanosec as i64)),
    ("seconds", Json::Num(t.seconds())),
  ])
}

fn result_json(r: &SimResult) -> Vec<(&'static str, Json)> {
  vec![
    ("result", Json::Int(r.result as i64)),
    ("error_message", Json::Str(r.error_message.clone())),
  ]
}

// ---- bounded waits

const PROGRAM: &str = "simgate_ros2_rust_probe";
const POLL: Duration = Duration::from_millis(10);

fn fail(status: i32, message: &str) -> ! {
  eprintln!("{PROGRAM}: {message}");
  let _ = std::io::stderr().flush();
  exit(status)
}

fn timed_out(what: &str, seconds: f64) -> ! {
  fail(3, &format!("timeout: {what} (waited {seconds:.1} s)"))
}

/// Polls a future made anew each time by `make` until it is ready or `timeout` passes: the
/// futures it is used with check the node's state when polled, so no waker is needed.
fn ready_within<F: Future<Output = ()>>(mut make: impl FnMut() -> F, timeout: Duration) -> bool {
  let deadline = Instant::now() + timeout;
  let mut cx = TaskContext::from_waker(futures::task::noop_waker_ref());
  loop {
    if pin!(make()).poll(&mut cx).is_ready() {
      return true;
    }
    if Instant::now() >= deadline {
      return false;
    }
    thread::sleep(POLL); // polling, bounded by the deadline
  }
}

/// The next sample of `sub`, waiting at most until `deadline`.
fn take_before<M: Message + 'static>(sub: &Subscription<M>, deadline: Instant) -> Option<M> {
  loop {
    match sub.take() {
      Ok(Some((message, _info))) => return Some(message),
      Ok(None) => {}
      Err(e) => fail(4, &format!("reading a sample: {e:?}")),
    }
    if Instant::now() >= deadline {
      return None;
    }
    thread::sleep(POLL); // polling the reader, bounded by the deadline
  }
}

/// A service client of one simulation_interfaces service, rmw_cyclonedds' mapping.
struct Service<Req: Message, Resp: Message> {
  name: &'static str,
  client: Client<Req, Resp>,
}

impl<Req: Message + Clone + 'static, Resp: Message + 'static> Service<Req, Resp> {
  fn new(node: &mut Node, name: &'static str, type_name: &str) -> Self {
    // rmw's default service QoS: reliable, volatile, keep-last 10
    let qos = QosProfile::publisher_default().history(History::KeepLast { depth: 10 });
    let client = node
      .create_client::<Req, Resp>(
        ServiceMapping::Cyclone,
        &Name::new("/", name).unwrap_or_else(|e| fail(4, &format!("service name {name}: {e:?}"))),
        &ServiceTypeName::new("simulation_interfaces", type_name),
        qos.clone(),
        qos,
      )
      .unwrap_or_else(|e| fail(4, &format!("creating the client of /{name}: {e:?}")));
    Service { name, client }
  }

  /// Waits for the service (a reader of our requests, a writer of replies), sends `request`
  /// and waits for its reply.
  fn call(&self, node: &Node, request: Req, timeout: Duration) -> Resp {
    let start = Instant::now();
    if !ready_within(|| self.client.wait_for_service(node), timeout) {
      timed_out(&format!("service /{} not available", self.name), timeout.as_secs_f64());
    }
    let id = self
      .client
      .send_request(request)
      .unwrap_or_else(|e| fail(4, &format!("sending the request of /{}: {e:?}", self.name)));
    let deadline = start + timeout;
    loop {
      match self.client.receive_response() {
        Ok(Some((reply_id, reply))) if reply_id == id => return reply,
        Ok(Some((reply_id, _))) => {
          eprintln!(
            "{PROGRAM}: /{}: a reply to another request ({reply_id:?}), not ours ({id:?})",
            self.name
          )
        }
        Ok(None) => {}
        Err(e) => fail(4, &format!("reading the reply of /{}: {e:?}", self.name)),
      }
      if Instant::now() >= deadline {
        timed_out(
          &format!("no reply from /{} (request {:?} sent)", self.name, id),
          timeout.as_secs_f64(),
        );
      }
      thread::sleep(POLL); // polling the reply reader, bounded by the deadline
    }
  }
}

// ---- the program

struct Options {
  domain: u16,
  timeout: Duration,
  call_timeout: Duration,
  steps: u64,
  gate: bool,
}

fn usage(message: &str) -> ! {
  fail(
    2,
    &format!(
      "{message}\nusage: {PROGRAM} --domain N [--timeout SECONDS] [--call-timeout SECONDS] [--steps N] [--gate]"
    ),
  )
}

fn parse_options() -> Options {
  let mut options = Options {
    domain: u16::MAX,
    timeout: Duration::from_secs(30),
    call_timeout: Duration::from_secs(15),
    steps: 50,
    gate: false,
  };
  let mut args = std::env::args().skip(1);
  while let Some(arg) = args.next() {
    let mut value =
      |name: &str| args.next().unwrap_or_else(|| usage(&format!("{name} needs a value")));
    let seconds = |text: String, name: &str| match text.parse::<f64>() {
      Ok(s) if s > 0.0 && s <= 3600.0 => Duration::from_secs_f64(s),
      _ => usage(&format!("{name}: expected seconds in (0, 3600], found {text:?}")),
    };
    match arg.as_str() {
      "--domain" => {
        let text = value("--domain");
        options.domain = match text.parse::<u16>() {
          Ok(d) if d <= 232 => d,
          _ => usage(&format!("--domain: expected a DDS domain id 0..232, found {text:?}")),
        }
      }
      "--timeout" => options.timeout = seconds(value("--timeout"), "--timeout"),
      "--call-timeout" => options.call_timeout = seconds(value("--call-timeout"), "--call-timeout"),
      "--steps" => {
        let text = value("--steps");
        options.steps = text
          .parse::<u64>()
          .unwrap_or_else(|_| usage(&format!("--steps: expected a count, found {text:?}")))
      }
      "--gate" => options.gate = true,
      "-h" | "--help" => usage("a ROS 2 client of simgate's ros2 transport, on ros2-client"),
      other => usage(&format!("unknown argument {other:?}")),
    }
  }
  if options.domain == u16::MAX {
    usage("--domain is required");
  }
  options
}

/// Waits for a line on stdin, at most `timeout`.
fn wait_for_stdin_line(timeout: Duration) -> bool {
  let (sender, receiver) = mpsc::channel();
  thread::spawn(move || {
    let mut line = String::new();
    let got = std::io::stdin().lock().read_line(&mut line).map(|n| n > 0).unwrap_or(false);
    let _ = sender.send(got);
  });
  matches!(receiver.recv_timeout(timeout), Ok(true))
}

fn main() {
  let options = parse_options();

  // Loopback only, as simgate's Cyclone is configured (config/dds/loopback.xml): locators on
  // 127.0.0.1; RustDDS also announces itself to 127.0.0.1's discovery ports (its default
  // same_host_loopback), which is how a Cyclone with multicast off hears of it.
  let participant = DomainParticipantBuilder::new(options.domain)
    .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
    .build()
    .unwrap_or_else(|e| fail(4, &format!("creating the DDS participant: {e:?}")));
  let context = Context::from_domain_participant(participant)
    .unwrap_or_else(|e| fail(4, &format!("creating the ROS 2 context: {e:?}")));
  let mut node = context
    .new_node(
      NodeName::new("/", "simgate_rust_probe").unwrap_or_else(|e| fail(4, &format!("{e:?}"))),
      NodeOptions::new().enable_rosout(false).start_parameter_services(false),
    )
    .unwrap_or_else(|e| fail(4, &format!("creating the node: {e:?}")));

  // ROS 2's default profile for /clock (reliable, keep-last 10); keep-last 100 as tf2 for /tf
  let reliable = |depth| QosProfile::publisher_default().history(History::KeepLast { depth });
  let topic = |name: &str, package: &str, type_name: &str, depth| {
    node
      .create_topic(
        &Name::new("/", name).unwrap_or_else(|e| fail(4, &format!("{e:?}"))),
        MessageTypeName::new(package, type_name),
        &reliable(depth),
      )
      .unwrap_or_else(|e| fail(4, &format!("creating the topic /{name}: {e:?}")))
  };
  let clock_topic = topic("clock", "rosgraph_msgs", "Clock", 10);
  let tf_topic = topic("tf", "tf2_msgs", "TFMessage", 100);
  let clock = node
    .create_subscription::<Clock>(&clock_topic, Some(reliable(10)))
    .unwrap_or_else(|e| fail(4, &format!("subscribing to /clock: {e:?}")));
  let tf = node
    .create_subscription::<TfMessage>(&tf_topic, Some(reliable(100)))
    .unwrap_or_else(|e| fail(4, &format!("subscribing to /tf: {e:?}")));

  let get_state: Service<GetSimulationStateRequest, GetSimulationStateResponse> =
    Service::new(&mut node, "get_simulation_state", "GetSimulationState");
  let set_state: Service<SetSimulationStateRequest, SetSimulationStateResponse> =
    Service::new(&mut node, "set_simulation_state", "SetSimulationState");
  let step: Service<StepSimulationRequest, StepSimulationResponse> =
    Service::new(&mut node, "step_simulation", "StepSimulation");
  let get_entities: Service<GetEntitiesRequest, GetEntitiesResponse> =
    Service::new(&mut node, "get_entities", "GetEntities");

  // The spinner keeps the node's view of the graph (which of our endpoints matched whom),
  // which wait_for_service reads; it runs until the process exits.
  let spinner = node.spinner().unwrap_or_else(|e| fail(4, &format!("the node's spinner: {e:?}")));
  thread::spawn(move || {
    if let Err(e) = futures::executor::block_on(spinner.spin()) {
      eprintln!("{PROGRAM}: the spinner stopped: {e:?}");
    }
  });

  // one sample of /clock and one of /tf
  let started = Instant::now();
  let deadline = started + options.timeout;
  let first_clock = take_before(&clock, deadline)
    .unwrap_or_else(|| timed_out("no sample on /clock", options.timeout.as_secs_f64()));
  let first_tf = take_before(&tf, deadline)
    .unwrap_or_else(|| timed_out("no sample on /tf", options.timeout.as_secs_f64()));
  let topics_seconds = started.elapsed().as_secs_f64();

  let call_timeout = options.call_timeout;
  let state_before = get_state.call(&node, GetSimulationStateRequest::default(), call_timeout);
  let paused = set_state.call(
    &node,
    SetSimulationStateRequest { state: SimulationState { state: STATE_PAUSED } },
    call_timeout,
  );
  if options.gate {
    eprintln!("{PROGRAM}: paused");
    let _ = std::io::stderr().flush();
    if !wait_for_stdin_line(options.timeout) {
      timed_out("no line on stdin after the pause (--gate)", options.timeout.as_secs_f64());
    }
  }
  let stepped = step.call(&node, StepSimulationRequest { steps: options.steps }, call_timeout);
  let state_after = get_state.call(&node, GetSimulationStateRequest::default(), call_timeout);
  // /clock once the steps are done: simgate writes it once a second while time stands still;
  // the last value taken in the next 1.5 s (none: null)
  let clock_deadline = Instant::now() + Duration::from_millis(1500);
  let mut clock_after_step = None;
  while let Some(sample) = take_before(&clock, clock_deadline) {
    clock_after_step = Some(sample.clock);
  }
  let entities = get_entities.call(&node, GetEntitiesRequest::default(), call_timeout);

  let tf_frames: Vec<Json> =
    first_tf.transforms.iter().map(|t| Json::Str(t.child_frame_id.clone())).collect();
  let tf_parents: Vec<(String, Json)> = first_tf
    .transforms
    .iter()
    .map(|t| (t.child_frame_id.clone(), Json::Str(t.header.frame_id.clone())))
    .collect();
  let state_json = |r: &GetSimulationStateResponse| {
    let mut fields = vec![("state", Json::Int(r.state.state as i64))];
    fields.extend(result_json(&r.result));
    Json::obj(fields)
  };
  let mut set_fields = vec![("state", Json::Int(STATE_PAUSED as i64))];
  set_fields.extend(result_json(&paused.result));
  let mut step_fields = vec![("steps", Json::Int(options.steps as i64))];
  step_fields.extend(result_json(&stepped.result));
  let mut entities_fields = result_json(&entities.result);
  entities_fields.push((
    "entities",
    Json::Arr(entities.entities.iter().map(|e| Json::Str(e.clone())).collect()),
  ));

  let report = Json::obj(vec![
    ("client", Json::Str("ros2-client".into())),
    ("domain", Json::Int(options.domain as i64)),
    ("topics_seconds", Json::Num(topics_seconds)),
    ("clock", time_json(&first_clock.clock)),
    ("tf_frames", Json::Arr(tf_frames)),
    ("tf_parents", Json::Obj(tf_parents)),
    ("get_simulation_state", state_json(&state_before)),
    ("set_simulation_state", Json::obj(set_fields)),
    ("step_simulation", Json::obj(step_fields)),
    ("get_simulation_state_after", state_json(&state_after)),
    ("clock_after_step", clock_after_step.as_ref().map(time_json).unwrap_or(Json::Null)),
    ("get_entities", Json::obj(entities_fields)),
    ("gated", Json::Bool(options.gate)),
  ]);
  let mut out = String::new();
  report.write(&mut out);
  out.push('\n');
  let mut stdout = std::io::stdout().lock();
  if stdout.write_all(out.as_bytes()).and_then(|_| stdout.flush()).is_err() {
    fail(4, "cannot write to stdout");
  }
  // the spinner thread and RustDDS's threads end with the process
  exit(0);
}
