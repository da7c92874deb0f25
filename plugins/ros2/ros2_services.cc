// The ros2 transport's services as rmw_cyclonedds offers a service: the endpoints, the requests
// taken, the replies written or parked. The services themselves: ros2_sim_services.cc and
// ros2_entity_services.cc. Design: ros2_services.h, docs/transports/ros2.md.
#include "ros2_services.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <type_traits>

#include "dds_support.h"
#include "ros2_mapping.h"
#include "ros2_srvs.h"
#include "ros2_types.h"
#include "simgate/core/log.h"

namespace simgate::ros2 {

namespace {

// Every request begins with these (ros2_srvs.idl).
struct RequestHeader {
  std::uint64_t client_guid;
  std::int64_t sequence;
};
static_assert(offsetof(simulation_interfaces_srv_dds__StepSimulation_Request_, steps) ==
              sizeof(RequestHeader));

// Requests taken per dds_take.
constexpr std::uint32_t k_take_batch = 16;
// Shortest time between two logs of dropped replies.
constexpr auto k_drop_log_interval = std::chrono::seconds(10);

}  // namespace

struct Ros2Services::Endpoint {
  std::string name;  // the ROS service name
  const dds_topic_descriptor_t* request_type = nullptr;
  const dds_topic_descriptor_t* reply_type = nullptr;
  Handler handler;
  dds_entity_t reader = 0;
  dds_entity_t writer = 0;
  dds_entity_t read_condition = 0;
  // what discovery said of the clients (reading it costs a copy of each endpoint's QoS),
  // read again when the matches change
  std::map<dds_instance_handle_t, std::string> request_writers;  // -> their clientid
  std::set<std::string> reply_readers;                           // the clientids matched
  bool readers_known = false;
};

namespace {
// The clientid of a matched endpoint's USER_DATA ("" when none).
std::string client_id_of(const dds_builtintopic_endpoint_t& endpoint) {
  void* value = nullptr;
  std::size_t size = 0;
  std::string id;
  if (dds_qget_userdata(endpoint.qos, &value, &size) && value) {
    id = user_data_value(std::string_view(static_cast<const char*>(value), size), "clientid")
             .value_or("");
    dds_free(value);
  }
  return id;
}
}  // namespace

void Ros2Services::SampleDeleter::operator()(void* sample) const {
  if (sample) dds_sample_free(sample, type, DDS_FREE_ALL);
}

Ros2Services::Ros2Services(Settings settings, dds_entity_t participant, dds_entity_t waitset,
                           Caller caller, std::function<double()> sim_time)
    : settings_(std::move(settings)),
      participant_(participant),
      waitset_(waitset),
      caller_(std::move(caller)),
      sim_time_(std::move(sim_time)) {
  add_simulation_services();
}

Ros2Services::~Ros2Services() = default;  // the entities go with the participant

void Ros2Services::add(const char* name, const dds_topic_descriptor_t& request,
                       const dds_topic_descriptor_t& reply, Member handler) {
  add(name, request, reply,
      [this, handler](const void* sample, const ReplyTo& to) { (this->*handler)(sample, to); });
}

void Ros2Services::add(const std::string& name, const dds_topic_descriptor_t& request,
                       const dds_topic_descriptor_t& reply, Handler handler) {
  auto endpoint = std::make_unique<Endpoint>();
  endpoint->name = full_name(name);
  endpoint->request_type = &request;
  endpoint->reply_type = &reply;
  endpoint->handler = std::move(handler);
  // the same serviceid on both halves: a ROS client pairs them by it
  dds_guid_t guid{};
  dds_get_guid(participant_, &guid);
  std::array<std::uint8_t, 16> participant_guid{};
  std::copy(std::begin(guid.v), std::end(guid.v), participant_guid.begin());
  const std::string user_data = service_user_data(participant_guid, next_service_id_++);
  // ROS 2's services profile: reliable, volatile, keep-last 10 (the reader keeps more: a
  // burst of requests waits for the DDS thread)
  dds::QosPtr reader_qos = dds::make_qos(false, 64, 0);
  dds::QosPtr writer_qos = dds::make_qos(false, 10, 0);
  dds_qset_userdata(reader_qos.get(), user_data.data(), user_data.size());
  dds_qset_userdata(writer_qos.get(), user_data.data(), user_data.size());
  const std::string request_topic = service_request_topic(endpoint->name);
  const std::string reply_topic = service_reply_topic(endpoint->name);
  endpoint->reader = dds::check_created(
      dds_create_reader(participant_,
                        dds::cached_topic(topics_, participant_, request_topic, name_only(request)),
                        reader_qos.get(), nullptr),
      "reader " + request_topic);
  endpoint->writer = dds::check_created(
      dds_create_writer(participant_,
                        dds::cached_topic(topics_, participant_, reply_topic, name_only(reply)),
                        writer_qos.get(), nullptr),
      "writer " + reply_topic);
  endpoint->read_condition = dds::check_created(
      dds_create_readcondition(endpoint->reader, DDS_ANY_STATE), "read condition " + request_topic);
  dds::check_created(dds_waitset_attach(waitset_, endpoint->read_condition, k_token_requests),
                     "waitset attachment");
  // a client's reply reader matching: parked replies may go
  dds_set_status_mask(endpoint->writer, DDS_PUBLICATION_MATCHED_STATUS);
  dds::check_created(dds_waitset_attach(waitset_, endpoint->writer, k_token_matched),
                     "waitset attachment");
  endpoints_.push_back(std::move(endpoint));
}

void Ros2Services::endpoints(std::vector<dds_entity_t>& writers,
                             std::vector<dds_entity_t>& readers) const {
  for (const auto& endpoint : endpoints_) {
    writers.push_back(endpoint->writer);
    readers.push_back(endpoint->reader);
  }
}

std::vector<std::string> Ros2Services::names() const {
  std::vector<std::string> out;
  for (const auto& endpoint : endpoints_) out.push_back(endpoint->name);
  return out;
}

void Ros2Services::take_requests() {
  void* samples[k_take_batch];
  dds_sample_info_t infos[k_take_batch];
  for (std::size_t index = 0; index < endpoints_.size(); ++index) {
    Endpoint& endpoint = *endpoints_[index];
    for (;;) {
      std::fill(std::begin(samples), std::end(samples), nullptr);
      const dds_return_t n = dds_take(endpoint.reader, samples, infos, k_take_batch, k_take_batch);
      if (n <= 0) {
        if (n < 0)
          log::debug("ros2 transport: ", endpoint.name, ": take failed: ", dds::retcode_text(n));
        break;
      }
      for (dds_return_t i = 0; i < n; ++i) {
        if (!infos[i].valid_data) continue;
        ReplyTo to;
        to.endpoint = index;
        const auto* header = static_cast<const RequestHeader*>(samples[i]);
        to.client_guid = header->client_guid;
        to.sequence = header->sequence;
        to.client_writer = infos[i].publication_handle;
        to.client_id = client_of(endpoint, to.client_writer);
        try {
          endpoint.handler(samples[i], to);
        } catch (const std::exception& e) {
          log::error("ros2 transport: ", endpoint.name, ": ", e.what());
        }
      }
      dds_return_loan(endpoint.reader, samples, n);
      if (n < static_cast<dds_return_t>(k_take_batch)) break;
    }
  }
}

Ros2Services::Sample Ros2Services::new_sample(const ReplyTo& to, std::size_t size) const {
  void* sample = dds_alloc(size);
  std::memset(sample, 0, size);
  return Sample(sample, SampleDeleter{endpoints_[to.endpoint]->reply_type});
}

const std::string& Ros2Services::client_of(Endpoint& endpoint, dds_instance_handle_t writer) {
  dds_subscription_matched_status_t status;
  if (dds_get_subscription_matched_status(endpoint.reader, &status) == DDS_RETCODE_OK &&
      (status.total_count_change != 0 || status.current_count_change != 0))
    endpoint.request_writers.clear();  // writers came or went: asked again
  auto it = endpoint.request_writers.find(writer);
  if (it == endpoint.request_writers.end()) {
    std::string id;
    if (dds_builtintopic_endpoint_t* data =
            dds_get_matched_publication_data(endpoint.reader, writer)) {
      id = client_id_of(*data);
      dds_builtintopic_free_endpoint(data);
    }
    it = endpoint.request_writers.emplace(writer, std::move(id)).first;
  }
  return it->second;
}

bool Ros2Services::reader_matched(Endpoint& endpoint, const std::string& client_id) {
  if (!endpoint.readers_known) {
    endpoint.reply_readers.clear();
    std::vector<dds_instance_handle_t> handles(16);
    dds_return_t n;
    while ((n = dds_get_matched_subscriptions(endpoint.writer, handles.data(), handles.size())) >
           static_cast<dds_return_t>(handles.size()))
      handles.resize(static_cast<std::size_t>(n));
    for (dds_return_t i = 0; i < n; ++i) {
      if (dds_builtintopic_endpoint_t* reader =
              dds_get_matched_subscription_data(endpoint.writer, handles[i])) {
        endpoint.reply_readers.insert(client_id_of(*reader));
        dds_builtintopic_free_endpoint(reader);
      }
    }
    endpoint.readers_known = true;
  }
  return endpoint.reply_readers.count(client_id) > 0;
}

void Ros2Services::write(const Endpoint& endpoint, const Sample& reply) {
  if (dds_return_t rc = dds_write(endpoint.writer, reply.get()); rc < 0) {
    ++dropped_;
    log::debug("ros2 transport: ", endpoint.name, ": reply not written: ", dds::retcode_text(rc));
    return;
  }
  ++written_;
}

void Ros2Services::send(const ReplyTo& to, Sample reply) {
  Endpoint& endpoint = *endpoints_[to.endpoint];
  if (to.client_id.empty() || reader_matched(endpoint, to.client_id)) {
    write(endpoint, reply);
    return;
  }
  parked_.push_back({to.endpoint, to.client_writer, to.client_id, std::move(reply),
                     std::chrono::steady_clock::now() + settings_.park_timeout});
}

void Ros2Services::matches_changed() {
  for (const auto& endpoint : endpoints_) {
    dds_publication_matched_status_t status;
    // resets the status (the waitset's trigger); its counts say whether anything changed
    if (dds_get_publication_matched_status(endpoint->writer, &status) == DDS_RETCODE_OK &&
        (status.total_count_change != 0 || status.current_count_change != 0))
      endpoint->readers_known = false;
  }
  if (has_parked()) flush_parked();
}

void Ros2Services::flush_parked() {
  const auto now = std::chrono::steady_clock::now();
  std::size_t expired = 0;
  for (auto it = parked_.begin(); it != parked_.end();) {
    Endpoint& endpoint = *endpoints_[it->endpoint];
    if (reader_matched(endpoint, it->client_id)) {
      write(endpoint, it->reply);
    } else if (dds_builtintopic_endpoint_t* writer =
                   dds_get_matched_publication_data(endpoint.reader, it->client_writer)) {
      dds_builtintopic_free_endpoint(writer);
      if (now < it->deadline) {
        ++it;
        continue;
      }
      ++expired;
      ++dropped_;
    } else {
      ++dropped_;  // the client left: nobody to tell
    }
    it = parked_.erase(it);
  }
  if (expired > 0 && now - drop_logged_at_ >= k_drop_log_interval) {
    drop_logged_at_ = now;
    log::warning("ros2 transport: ", expired,
                 " service replies dropped: their client's reply reader did not match within ",
                 settings_.park_timeout.count(), " ms");
  }
}

}  // namespace simgate::ros2
