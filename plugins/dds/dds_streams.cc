// The data streams over DDS: topic names, the typed samples (one writer function per kind),
// the commands, the simgate_Streams catalog. Design: dds_streams.h, docs/transports/dds.md.
#include "dds_streams.h"

#include <iterator>
#include <stdexcept>
#include <string_view>

#include "dds_support.h"
#include "simgate/core/config.h"
#include "simgate/core/log.h"
#include "simgate_streams.h"

namespace simgate::dds {

namespace {

// Samples a subscription keeps: the DDS thread writes them as soon as it wakes, so a few
// cover its scheduling hiccups; older ones are dropped (counted by the hub), never waited for.
constexpr std::size_t k_subscription_capacity = 8;
// Commands one dds_take returns at most.
constexpr int k_command_take_batch = 16;

void triple(const json& data, const char* key, double (&out)[3]) {
  const json& values = data.at(key);
  for (int i = 0; i < 3; ++i) out[i] = values.at(i).get<double>();
}

// A sample struct with what every one carries: the component, seq and simulated time.
template <class T>
T stamped(const std::string& component, const StreamSample& sample) {
  T out{};
  out.component = const_cast<char*>(component.c_str());
  out.seq = sample.seq();
  out.time = sample.time();
  return out;
}

// A writer function per typed kind: fills the struct from the sample (throws when the sample
// is not of that shape) and writes it. A record sample (a pose's) is read as it is, no JSON.
using WriteFn = dds_return_t (*)(dds_entity_t writer, const std::string& component,
                                 const StreamSample& sample);

dds_return_t write_pose(dds_entity_t writer, const std::string& component,
                        const StreamSample& sample) {
  static constexpr std::string_view k_keys[] = {"x", "y", "z", "roll", "pitch", "yaw"};
  double v[std::size(k_keys)];
  sample.numbers(k_keys, v);
  auto pose = stamped<simgate_stream_Pose>(component, sample);
  pose.x = v[0], pose.y = v[1], pose.z = v[2], pose.roll = v[3], pose.pitch = v[4], pose.yaw = v[5];
  return dds_write(writer, &pose);
}

dds_return_t write_odometry(dds_entity_t writer, const std::string& component,
                            const StreamSample& sample) {
  static constexpr std::string_view k_keys[] = {"x",  "y",  "z",  "roll", "pitch", "yaw",
                                                "vx", "vy", "vz", "wx",   "wy",    "wz"};
  double v[std::size(k_keys)];
  sample.numbers(k_keys, v);
  auto odometry = stamped<simgate_stream_Odometry>(component, sample);
  odometry.x = v[0], odometry.y = v[1], odometry.z = v[2], odometry.roll = v[3],
  odometry.pitch = v[4];
  odometry.yaw = v[5], odometry.vx = v[6], odometry.vy = v[7], odometry.vz = v[8],
  odometry.wx = v[9];
  odometry.wy = v[10], odometry.wz = v[11];
  return dds_write(writer, &odometry);
}

dds_return_t write_imu(dds_entity_t writer, const std::string& component,
                       const StreamSample& sample) {
  const json& d = sample.data();
  auto imu = stamped<simgate_stream_Imu>(component, sample);
  triple(d, "angular_velocity", imu.angular_velocity);
  triple(d, "linear_acceleration", imu.linear_acceleration);
  triple(d, "magnetic_field", imu.magnetic_field);
  return dds_write(writer, &imu);
}

dds_return_t write_joint_state(dds_entity_t writer, const std::string& component,
                               const StreamSample& sample) {
  // armature_pose: {joint: position, ..., "timestamp": t}
  std::vector<char*> names;
  std::vector<double> positions;
  for (const auto& [key, value] : sample.data().items()) {
    if (key == "timestamp") continue;
    names.push_back(const_cast<char*>(key.c_str()));
    positions.push_back(value.get<double>());
  }
  auto state = stamped<simgate_stream_JointState>(component, sample);
  state.names = {static_cast<uint32_t>(names.size()), static_cast<uint32_t>(names.size()),
                 names.data(), false};
  state.positions = {static_cast<uint32_t>(positions.size()),
                     static_cast<uint32_t>(positions.size()), positions.data(), false};
  return dds_write(writer, &state);
}

dds_return_t write_laser_scan(dds_entity_t writer, const std::string& component,
                              const StreamSample& sample) {
  const json& d = sample.data();
  std::vector<double> ranges;
  for (const json& range : d.at("range_list")) ranges.push_back(range.get<double>());
  std::vector<simgate_stream_Point> points;
  for (const json& p : d.at("point_list"))
    points.push_back({p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()});
  auto scan = stamped<simgate_stream_LaserScan>(component, sample);
  scan.ranges = {static_cast<uint32_t>(ranges.size()), static_cast<uint32_t>(ranges.size()),
                 ranges.data(), false};
  scan.points = {static_cast<uint32_t>(points.size()), static_cast<uint32_t>(points.size()),
                 points.data(), false};
  return dds_write(writer, &scan);
}

// A camera's image: the payload's bytes as they are (no PNG, no base64, no JSON).
dds_return_t write_image(dds_entity_t writer, const std::string& component,
                         const StreamSample& sample) {
  const StreamPayload* payload = sample.payload();
  if (!payload) throw std::invalid_argument("the sample carries no image");
  return write_image_payload(writer, component, sample.seq(), sample.time(), *payload);
}

}  // namespace

dds_return_t write_image_payload(dds_entity_t writer, const std::string& component,
                                 std::uint64_t seq, double time, const StreamPayload& source) {
  const StreamPayload* payload = &source;
  if (payload->content != "image") throw std::invalid_argument("the payload is no image");
  const json& d = payload->description;
  const std::string encoding = d.at("encoding").get<std::string>();
  simgate_stream_Image image{};
  image.component = const_cast<char*>(component.c_str());
  image.seq = seq;
  image.time = time;
  image.height = d.at("height").get<std::uint32_t>();
  image.width = d.at("width").get<std::uint32_t>();
  image.encoding = const_cast<char*>(encoding.c_str());
  image.is_bigendian = d.at("is_bigendian").get<bool>();
  image.step = d.at("step").get<std::uint32_t>();
  if (static_cast<std::uint64_t>(image.step) * image.height != payload->bytes.size())
    throw std::invalid_argument("the image has " + std::to_string(payload->bytes.size()) +
                                " bytes, not step x height");
  const json& k = d.at("intrinsic_matrix");
  for (int i = 0; i < 9; ++i) image.K[i] = k.at(i / 3).at(i % 3).get<double>();
  image.data = {static_cast<uint32_t>(payload->bytes.size()),
                static_cast<uint32_t>(payload->bytes.size()),
                const_cast<std::uint8_t*>(payload->bytes.data()), false};
  return dds_write(writer, &image);
}

// The type of an output stream's topic, by its kind. (Not in the anonymous namespace: the
// type of a member of DdsStreams::Output.)
struct OutputType {
  const char* kind;                          // StreamDeclaration::kind
  const dds_topic_descriptor_t* descriptor;  // the IDL type
  WriteFn write;                             // null: JsonSample
  bool small = false;                        // fixed-size and small: may be written directly
};

namespace {

constexpr OutputType k_output_types[] = {
    {"pose", &simgate_stream_Pose_desc, write_pose, true},
    {"odometry", &simgate_stream_Odometry_desc, write_odometry, true},
    {"imu", &simgate_stream_Imu_desc, write_imu, true},
    {"joint_state", &simgate_stream_JointState_desc, write_joint_state},
    {"laser_scan", &simgate_stream_LaserScan_desc, write_laser_scan},
    {"image", &simgate_stream_Image_desc, write_image},
    {"depth_image", &simgate_stream_Image_desc, write_image},
};
constexpr OutputType k_json_output{"", &simgate_stream_JsonSample_desc, nullptr};

const OutputType& output_type(const std::string& kind) {
  for (const OutputType& type : k_output_types)
    if (kind == type.kind) return type;
  return k_json_output;
}

}  // namespace

std::string topic_path(std::string_view component) {
  std::string path = "simgate/";
  for (char c : component) {
    const bool plain =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    path += c == '.' || c == '/' ? '/' : plain ? c : '_';
  }
  return path;
}

struct DdsStreams::Output {
  StreamInfo info;
  std::string topic;                 // its name
  const OutputType* type = nullptr;  // what it writes
  dds_entity_t writer = 0;
  std::shared_ptr<StreamSubscription> subscription;  // to the hub
  bool shape_logged = false;                         // a sample not of the type's shape was logged
};

struct DdsStreams::Input {
  StreamInfo info;
  std::string json_topic;   // JsonCommand
  std::string typed_topic;  // Velocity ("" when its kind has no typed command)
  dds_entity_t json_reader = 0;
  dds_entity_t typed_reader = 0;
  bool bad_logged = false;    // a command that is not a JSON object was logged
  bool limit_logged = false;  // a command beyond max_params or max_depth was logged
};

DdsStreams::DdsStreams(std::shared_ptr<StreamDirectory> hub, std::string transport,
                       dds_entity_t participant, dds_entity_t publisher, dds_entity_t subscriber,
                       dds_entity_t waitset, std::string server_id, bool direct_writes,
                       std::size_t max_command_bytes, std::size_t max_command_depth)
    : hub_(std::move(hub)),
      transport_(std::move(transport)),
      participant_(participant),
      publisher_(publisher),
      subscriber_(subscriber),
      waitset_(waitset),
      server_id_(std::move(server_id)),
      direct_writes_(direct_writes),
      max_command_bytes_(max_command_bytes),
      max_command_depth_(max_command_depth) {
  guard_ = check_created(dds_create_guardcondition(participant_), "guard condition (streams)");
  check_created(dds_waitset_attach(waitset_, guard_, k_token_samples),
                "waitset attachment (streams)");
  // the catalog: the last entry of each topic, kept for late joiners
  QosPtr catalog_qos = make_qos(true, 1, DDS_SECS(1));
  catalog_writer_ = check_created(
      dds_create_writer(publisher_, topic(k_streams_topic, &simgate_stream_StreamEntry_desc),
                        catalog_qos.get(), nullptr),
      "writer simgate_Streams");
}

DdsStreams::~DdsStreams() {
  for (auto& [component, output] : outputs_) hub_->unsubscribe(output->subscription);
}

dds_entity_t DdsStreams::topic(const std::string& name, const dds_topic_descriptor_t* descriptor) {
  return dds::cached_topic(topics_, participant_, name, descriptor);
}

void DdsStreams::sync() {
  std::set<std::string> listed;
  for (const StreamInfo& info : hub_->streams(transport_)) {
    listed.insert(info.component);
    if (outputs_.count(info.component) || inputs_.count(info.component)) continue;
    try {
      if (info.direction == StreamDirection::out)
        add_output(info);
      else
        add_input(info);
    } catch (const std::exception& e) {
      log::error("DDS transport: stream of '", info.component, "' not carried: ", e.what());
    }
  }
  for (auto it = outputs_.begin(); it != outputs_.end();) {
    if (listed.count(it->first) &&
        !(it->second->subscription && it->second->subscription->closed())) {
      ++it;
      continue;
    }
    remove_output(*it->second);
    it = outputs_.erase(it);
  }
  for (auto it = inputs_.begin(); it != inputs_.end();) {
    if (listed.count(it->first)) {
      ++it;
      continue;
    }
    remove_input(*it->second);
    it = inputs_.erase(it);
  }
}

void DdsStreams::add_output(const StreamInfo& info) {
  auto output = std::make_unique<Output>();
  output->info = info;
  output->topic = topic_path(info.component);
  output->type = &output_type(info.kind);
  // sensors: best effort, the latest sample only, volatile (no history for late joiners)
  QosPtr qos = make_qos(false, 1, 0);
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  output->writer =
      check_created(dds_create_writer(publisher_, topic(output->topic, output->type->descriptor),
                                      qos.get(), nullptr),
                    "writer " + output->topic);
  if (info.pushed) {
    // a pushed stream (a camera's) costs its component work while subscribed: subscribed to
    // only while the writer has a matched reader (update_matches)
    check_created(dds_set_status_mask(output->writer, DDS_PUBLICATION_MATCHED_STATUS),
                  "status mask " + output->topic);
    check_created(dds_waitset_attach(waitset_, output->writer, k_token_matched),
                  "waitset attachment " + output->topic);
    write_entry(info, output->topic, output->type->descriptor->m_typename);
    Output& added = *outputs_.emplace(info.component, std::move(output)).first->second;
    dds_publication_matched_status_t status;
    if (dds_get_publication_matched_status(added.writer, &status) == 0 && status.current_count > 0)
      subscribe_output(added);
    return;
  }
  subscribe_output(*output);
  if (!output->subscription) {
    dds_delete(output->writer);
    return;  // gone meanwhile
  }
  write_entry(info, output->topic, output->type->descriptor->m_typename);
  outputs_.emplace(info.component, std::move(output));
}

void DdsStreams::subscribe_output(Output& output) {
  SubscriberOptions options{k_subscription_capacity, "DDS topic " + output.topic, {}, {}};
  if (direct_writes_ && output.type->small && !output.info.pushed) {
    // written by the simulation thread as it is made (see the header); a sample not of the
    // type's shape throws: not sent, counted as dropped, the first logged by the hub
    options.deliver = [writer = output.writer, write = output.type->write,
                       component = output.info.component](const StreamSample& sample) {
      return write(writer, component, sample) >= 0;
    };
  } else {
    const dds_entity_t guard = guard_;
    options.wake = [guard] { dds_set_guardcondition(guard, true); };
  }
  output.subscription = hub_->subscribe(output.info.component, transport_, std::move(options));
}

void DdsStreams::update_matches() {
  for (auto& [component, output] : outputs_) {
    if (!output->info.pushed) continue;
    dds_publication_matched_status_t status;
    if (dds_get_publication_matched_status(output->writer, &status) != 0)
      continue;  // also resets the trigger
    if (status.current_count > 0 && !output->subscription) {
      subscribe_output(*output);
    } else if (status.current_count == 0 && output->subscription) {
      hub_->unsubscribe(output->subscription);
      output->subscription.reset();
    }
  }
}

dds_entity_t DdsStreams::add_reader(const std::string& name,
                                    const dds_topic_descriptor_t* descriptor) {
  // commands: reliable, the latest only (the hub keeps only the latest anyway), volatile
  QosPtr qos = make_qos(false, 1, 0);
  dds_entity_t reader =
      check_created(dds_create_reader(subscriber_, topic(name, descriptor), qos.get(), nullptr),
                    "reader " + name);
  dds_entity_t condition =
      check_created(dds_create_readcondition(reader, DDS_ANY_STATE), "read condition " + name);
  check_created(dds_waitset_attach(waitset_, condition, k_token_commands),
                "waitset attachment " + name);
  return reader;
}

void DdsStreams::add_input(const StreamInfo& info) {
  auto input = std::make_unique<Input>();
  input->info = info;
  const std::string path = topic_path(info.component);
  input->json_topic = path + "/json";
  input->json_reader = add_reader(input->json_topic, &simgate_stream_JsonCommand_desc);
  write_entry(info, input->json_topic, simgate_stream_JsonCommand_desc.m_typename);
  if (info.kind == "velocity") {
    input->typed_topic = path + "/cmd";
    input->typed_reader = add_reader(input->typed_topic, &simgate_stream_Velocity_desc);
    write_entry(info, input->typed_topic, simgate_stream_Velocity_desc.m_typename);
  }
  inputs_.emplace(info.component, std::move(input));
}

void DdsStreams::remove_output(Output& output) {
  hub_->unsubscribe(output.subscription);
  if (output.info.pushed) dds_waitset_detach(waitset_, output.writer);
  dds_delete(output.writer);
  dispose_entry(output.topic);
  log::info("DDS transport: stream topic ", output.topic, " ended (", output.info.component,
            " is gone)");
}

void DdsStreams::remove_input(Input& input) {
  // the read conditions go with their readers (and leave the waitset)
  for (dds_entity_t reader : {input.json_reader, input.typed_reader}) {
    if (reader <= 0) continue;
    dds_entity_t conditions[4];
    dds_return_t n = dds_get_children(reader, conditions, 4);
    for (dds_return_t i = 0; i < std::min<dds_return_t>(n, 4); ++i)
      dds_waitset_detach(waitset_, conditions[i]);
    dds_delete(reader);
  }
  dispose_entry(input.json_topic);
  if (!input.typed_topic.empty()) dispose_entry(input.typed_topic);
  log::info("DDS transport: command topics of ", input.info.component, " ended (it is gone)");
}

void DdsStreams::write_entry(const StreamInfo& info, const std::string& topic,
                             const char* type_name) {
  const std::string fields =
      info.direction == StreamDirection::in ? json(info.fields).dump() : std::string();
  simgate_stream_StreamEntry entry{};
  entry.topic = const_cast<char*>(topic.c_str());
  entry.component = const_cast<char*>(info.component.c_str());
  entry.server = const_cast<char*>(server_id_.c_str());
  entry.direction =
      info.direction == StreamDirection::out ? simgate_stream_DIR_OUT : simgate_stream_DIR_IN;
  entry.kind = const_cast<char*>(info.kind.c_str());
  entry.type_name = const_cast<char*>(type_name);
  entry.frequency = info.frequency;
  entry.fields = const_cast<char*>(fields.c_str());
  dds_return_t rc = dds_write(catalog_writer_, &entry);
  if (rc < 0)
    log::error("DDS transport: stream catalog entry '", topic, "' not written: ", retcode_text(rc));
}

void DdsStreams::dispose_entry(const std::string& topic) {
  simgate_stream_StreamEntry key{};
  key.topic = const_cast<char*>(topic.c_str());
  key.component = key.server = key.kind = key.type_name = key.fields = const_cast<char*>("");
  dds_return_t rc = dds_dispose(catalog_writer_, &key);
  if (rc < 0)
    log::error("DDS transport: stream catalog entry '", topic,
               "' not disposed: ", retcode_text(rc));
}

void DdsStreams::write_samples() {
  bool ignored;
  dds_take_guardcondition(guard_, &ignored);
  bool closed = false;
  for (auto& [component, output] : outputs_) {
    if (!output->subscription) continue;  // a pushed stream nobody reads
    taken_.clear();
    output->subscription->take(taken_);
    closed |= output->subscription->closed();
    for (const SamplePtr& sample : taken_) {
      dds_return_t rc;
      try {
        if (output->type->write) {
          rc = output->type->write(output->writer, component, *sample);
        } else {
          auto json_sample = stamped<simgate_stream_JsonSample>(component, *sample);
          json_sample.kind = const_cast<char*>(output->info.kind.c_str());
          json_sample.json = const_cast<char*>(sample->text().c_str());
          rc = dds_write(output->writer, &json_sample);
        }
      } catch (const std::exception& e) {
        // a component whose samples do not have its kind's shape (a component library's)
        if (!output->shape_logged)
          log::warning("DDS transport: a sample of ", component, " does not fit ",
                       output->type->descriptor->m_typename, " (", e.what(),
                       "); such samples are dropped (logged once)");
        output->shape_logged = true;
        output->subscription->note_dropped(1);
        continue;
      }
      if (rc < 0) output->subscription->note_dropped(1);
    }
  }
  taken_.clear();
  if (closed) sync();
}

void DdsStreams::take_commands() {
  for (auto& [component, input] : inputs_) {
    take(*input, input->json_reader, false);
    if (input->typed_reader > 0) take(*input, input->typed_reader, true);
  }
}

void DdsStreams::take(Input& input, dds_entity_t reader, bool typed) {
  void* samples[k_command_take_batch] = {};
  dds_sample_info_t infos[k_command_take_batch];
  dds_return_t n = dds_take(reader, samples, infos, k_command_take_batch, k_command_take_batch);
  for (dds_return_t i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    json command;
    if (typed) {
      const auto* velocity = static_cast<const simgate_stream_Velocity*>(samples[i]);
      command = {{"v", velocity->v}, {"w", velocity->w}};
    } else {
      const char* raw = static_cast<const simgate_stream_JsonCommand*>(samples[i])->json;
      const std::string_view text = raw ? raw : "";
      // bounded before it is parsed, as a request's params are (max_params, max_depth)
      std::string beyond;
      if (text.size() > max_command_bytes_)
        beyond = "a command of " + std::to_string(text.size()) + " bytes, more than max_params (" +
                 std::to_string(max_command_bytes_) + ")";
      else if (json_nests_deeper_than(text, max_command_depth_))
        beyond =
            "a command nested deeper than max_depth (" + std::to_string(max_command_depth_) + ")";
      if (!beyond.empty()) {
        hub_->note_refused(input.info.component, transport_, beyond);
        if (!input.limit_logged)
          log::warning("DDS transport: ", input.json_topic, " got ", beyond,
                       ": refused unread (logged once per reader; simulation get_stream_statistics "
                       "counts them)");
        input.limit_logged = true;
        continue;
      }
      command = json::parse(text, nullptr, false);
      if (!command.is_object()) {
        // never reaches the component, but is a refused command of the stream all the same
        const std::string reason = (command.is_discarded() ? "not JSON: " : "not a JSON object: ") +
                                   log::quoted_prefix(text);
        hub_->note_refused(input.info.component, transport_, reason);
        if (!input.bad_logged)
          log::warning("DDS transport: a command on ", input.json_topic, " is ", reason,
                       "; such commands are ignored (logged once; simulation get_stream_statistics "
                       "counts them)");
        input.bad_logged = true;
        continue;
      }
    }
    // a refusal is counted and logged by the hub (get_stream_statistics)
    hub_->publish(input.info.component, transport_, std::move(command));
  }
  if (n > 0) dds_return_loan(reader, samples, n);
}

}  // namespace simgate::dds
