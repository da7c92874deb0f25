#include "dds_support.h"

#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "simgate/core/text.h"

namespace simgate::dds {

namespace {
// Serialises domain creation and deletion within this library.
std::mutex& domain_mutex() {
  static std::mutex m;
  return m;
}
}  // namespace

std::string to_hex(const ClientId& id) {
  std::string out;
  out.reserve(2 * id.size());
  append_hex(out, id.data(), id.size());
  return out;
}

std::optional<ClientId> client_id_from_hex(std::string_view hex) {
  if (hex.size() != 32) return std::nullopt;
  auto nibble = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  ClientId id{};
  for (std::size_t i = 0; i < id.size(); ++i) {
    int hi = nibble(hex[2 * i]), lo = nibble(hex[2 * i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    id[i] = static_cast<std::uint8_t>(hi << 4 | lo);
  }
  return id;
}

ClientId to_client_id(const dds_guid_t& guid) {
  ClientId id;
  std::memcpy(id.data(), guid.v, id.size());
  return id;
}

std::optional<ClientId> client_id_from_userdata(const dds_qos_t* qos) {
  void* value = nullptr;
  size_t size = 0;
  if (!qos || !dds_qget_userdata(qos, &value, &size) || !value) return std::nullopt;
  std::string text(static_cast<const char*>(value), size);
  dds_free(value);
  // "simgate.id=<hex>" possibly followed by ";other=..."
  auto at = text.find(k_userdata_id_prefix);
  if (at == std::string::npos) return std::nullopt;
  return client_id_from_hex(std::string_view(text).substr(at + k_userdata_id_prefix.size(), 32));
}

std::string retcode_text(dds_return_t rc) {
  return std::string(dds_strretcode(rc)) + " (" + std::to_string(rc) + ")";
}

dds_entity_t check_created(dds_entity_t rc, const std::string& what) {
  if (rc < 0)
    throw std::runtime_error("DDS transport: cannot create " + what + ": " + retcode_text(rc));
  return rc;
}

dds_entity_t cached_topic(std::map<std::string, dds_entity_t>& topics, dds_entity_t participant,
                          const std::string& name, const dds_topic_descriptor_t* descriptor) {
  if (auto it = topics.find(name); it != topics.end()) return it->second;
  const dds_entity_t created = check_created(
      dds_create_topic(participant, descriptor, name.c_str(), nullptr, nullptr), "topic " + name);
  topics.emplace(name, created);
  return created;
}

const char* resolve_config(const std::string& config) {
  if (config.empty()) return k_loopback_xml;
  if (config == "env") {
    const char* uri = std::getenv("CYCLONEDDS_URI");
    return uri ? uri : "";
  }
  return config.c_str();
}

namespace {
// The error lines Cyclone logs while a trial domain is created (see trial_domain).
void capture_errors(void* arg, const dds_log_data_t* data) {
  if (!(data->priority & (DDS_LC_ERROR | DDS_LC_FATAL))) return;
  auto& lines = *static_cast<std::vector<std::string>*>(arg);
  std::string line(data->message, data->size);
  while (!line.empty() && (line.back() == '\n' || line.back() == ' ')) line.pop_back();
  if (!line.empty()) lines.push_back(std::move(line));
}
void drop_trace(void*, const dds_log_data_t*) {}
}  // namespace

DomainTrial trial_domain(uint32_t domain, const char* config) {
  std::lock_guard lock(domain_mutex());
  DomainTrial trial;
  // the sinks are Cyclone's, for the whole process: ours only while the domain is created
  dds_set_log_sink(&capture_errors, &trial.errors);
  dds_set_trace_sink(&drop_trace, nullptr);
  trial.result = dds_create_domain(domain, config);
  dds_set_trace_sink(nullptr, nullptr);
  dds_set_log_sink(nullptr, nullptr);
  if (trial.result > 0) dds_delete(trial.result);
  return trial;
}

QosPtr make_qos(bool transient_local, int32_t keep_last, dds_duration_t max_blocking) {
  QosPtr qos(dds_create_qos());
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, max_blocking);
  if (keep_last > 0)
    dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, keep_last);
  else
    dds_qset_history(qos.get(), DDS_HISTORY_KEEP_ALL, 0);
  dds_qset_durability(qos.get(),
                      transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
  return qos;
}

Participant::Participant(uint32_t domain, const char* config, const std::string& what)
    : domain_(domain) {
  std::lock_guard lock(domain_mutex());
  // create the domain with our settings, unless this process already has it
  dds_entity_t created = dds_create_domain(domain, config);
  if (created < 0 && created != DDS_RETCODE_PRECONDITION_NOT_MET)
    throw std::runtime_error(what + ": cannot create DDS domain " + std::to_string(domain) +
                             " from its Cyclone settings: " + retcode_text(created) +
                             " (check the \"config\" XML or file:// URI)");
  participant_ = dds_create_participant(domain, nullptr, nullptr);
  if (participant_ < 0) {
    dds_return_t rc = participant_;
    participant_ = 0;
    if (created > 0) dds_delete(created);
    throw std::runtime_error(what + ": cannot create a DDS participant on domain " +
                             std::to_string(domain) + ": " + retcode_text(rc));
  }
  domain_entity_ = dds_get_parent(participant_);
}

Participant::~Participant() {
  std::lock_guard lock(domain_mutex());
  if (participant_ > 0) dds_delete(participant_);
  // the last participant of the domain deletes it (whoever created it)
  if (domain_entity_ > 0 && dds_get_children(domain_entity_, nullptr, 0) == 0)
    dds_delete(domain_entity_);
}

simgate_Failure to_wire(Failure failure) {
  switch (failure) {
    case Failure::none: return simgate_FL_NONE;
    case Failure::unknown_service: return simgate_FL_UNKNOWN_SERVICE;
    case Failure::bad_arguments: return simgate_FL_BAD_ARGUMENTS;
    case Failure::busy: return simgate_FL_BUSY;
    case Failure::service_error: return simgate_FL_SERVICE_ERROR;
    case Failure::internal: return simgate_FL_INTERNAL;
    case Failure::preempted: return simgate_FL_PREEMPTED;
    case Failure::cancelled: return simgate_FL_CANCELLED;
    case Failure::shutdown: return simgate_FL_SHUTDOWN;
    case Failure::timeout: return simgate_FL_TIMEOUT;
  }
  return simgate_FL_INTERNAL;
}

Failure from_wire(simgate_Failure failure) {
  switch (failure) {
    case simgate_FL_NONE: return Failure::none;
    case simgate_FL_UNKNOWN_SERVICE: return Failure::unknown_service;
    case simgate_FL_BAD_ARGUMENTS: return Failure::bad_arguments;
    case simgate_FL_BUSY: return Failure::busy;
    case simgate_FL_SERVICE_ERROR: return Failure::service_error;
    case simgate_FL_INTERNAL: return Failure::internal;
    case simgate_FL_PREEMPTED: return Failure::preempted;
    case simgate_FL_CANCELLED: return Failure::cancelled;
    case simgate_FL_SHUTDOWN: return Failure::shutdown;
    case simgate_FL_BAD_REQUEST: return Failure::bad_arguments;
    case simgate_FL_TIMEOUT: return Failure::timeout;
  }
  return Failure::internal;
}

}  // namespace simgate::dds
