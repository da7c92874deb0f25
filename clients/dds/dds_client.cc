// The DDS client (simgate::client::DdsClient): its options, the calls it offers (each handed
// to its Impl, dds_client_impl.h) and list_simgates, which reads the catalogs of every simgate
// in the partitions a pattern matches. The client's DDS entities and calls sent:
// dds_client_impl.cc; replies taken and waited for: dds_client_replies.cc.
#include "simgate/client/dds_client.h"

#include <algorithm>
#include <cstdlib>
#include <set>

#include "dds_catalog.h"
#include "dds_client_impl.h"
#include "dds_support.h"
#include "simgate/core/config.h"
#include "simgate/core/request_manager.h"

namespace simgate::client {

namespace dds_detail {

// Why a simulation may be invisible: the network settings both sides must share.
std::string network_hint(const std::string& config) {
  std::string mine;
  if (config.empty()) {
    mine = "simgate's loopback-only settings (the default)";
  } else if (config == "env") {
    const char* uri = std::getenv("CYCLONEDDS_URI");
    mine = uri && *uri ? "CYCLONEDDS_URI=" + std::string(uri)
                       : "Cyclone's default network settings (CYCLONEDDS_URI is not set)";
  } else if (config.find('<') == std::string::npos) {
    mine = "the settings of " + config;
  } else {
    mine = "the Cyclone XML it was given";
  }
  return "The simulation and this client must share the domain, the partition and the Cyclone "
         "network settings: "
         "this client uses " +
         mine +
         "; a simulation's dds transport uses loopback only unless its \"config\" "
         "option says otherwise (simgate call --dds-config: XML, a file:// URI, or env for "
         "CYCLONEDDS_URI).";
}

// A participant of the options' domain, with their network settings (ClientError when Cyclone
// refuses them).
std::unique_ptr<dds::Participant> join_domain(const DdsClientOptions& options) {
  try {
    return std::make_unique<dds::Participant>(
        options.domain, dds::resolve_config(options.config),
        "DDS client (domain " + std::to_string(options.domain) + ")");
  } catch (const std::runtime_error& e) {
    throw ClientError(e.what());
  }
}

}  // namespace dds_detail

DdsClientOptions DdsClientOptions::from_json(const json& options) {
  try {
    ConfigObject config(options.is_null() ? json::object() : options, "dds client");
    DdsClientOptions out;
    out.domain = static_cast<std::uint32_t>(config.get_int("domain", 0, 0, 230));
    out.partition = config.get_string("partition", out.partition);
    out.config = config.get_string("config", "");
    out.discovery_timeout = std::chrono::milliseconds(
        config.get_int("discovery_timeout_ms", out.discovery_timeout.count(), 0, 3'600'000));
    out.raw_images = config.get_bool("raw_images", out.raw_images);
    config.finish();
    return out;
  } catch (const ConfigError& e) {
    throw ClientError(e.what());
  }
}

DdsClient::DdsClient(DdsClientOptions options)
    : impl_(std::make_unique<Impl>(std::move(options))) {}
DdsClient::~DdsClient() = default;

bool DdsClient::wait_for_server(std::chrono::milliseconds timeout) {
  return impl_->wait_for_server(timeout);
}

DdsClient::CallId DdsClient::start(const std::string& component, const std::string& service,
                                   const json& params) {
  return impl_->send(simgate_OP_CALL, component, service, params, 0,
                     impl_->options_.discovery_timeout);
}

bool DdsClient::wait_accepted(CallId id, std::chrono::milliseconds timeout) {
  return impl_->wait_accepted(id, timeout);
}

Outcome DdsClient::wait(CallId id, std::chrono::milliseconds timeout) {
  return impl_->wait(id, timeout);
}

namespace {

// What is left of `timeout` since `started` (zero at least).
std::chrono::milliseconds left_of(std::chrono::milliseconds timeout,
                                  std::chrono::steady_clock::time_point started) {
  auto spent = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::steady_clock::now() - started);
  return std::max(timeout - spent, std::chrono::milliseconds(0));
}

}  // namespace

bool DdsClient::cancel(CallId id, std::chrono::milliseconds timeout) {
  // the timeout bounds the whole cancel, finding the server included
  auto started = std::chrono::steady_clock::now();
  CallId seq = impl_->send(simgate_OP_CANCEL, "", "", nullptr, id, timeout);
  Outcome answer = impl_->wait(seq, left_of(timeout, started), timeout);
  return answer.value && answer.value->is_boolean() && answer.value->get<bool>();
}

Outcome DdsClient::call(const std::string& component, const std::string& service,
                        const json& params, std::chrono::milliseconds timeout) {
  // the timeout bounds the whole call, finding the server included (not discovery_timeout)
  auto started = std::chrono::steady_clock::now();
  CallId seq = impl_->send(simgate_OP_CALL, component, service, params, 0, timeout);
  return impl_->wait(seq, left_of(timeout, started), timeout);
}

json DdsClient::list_services(std::chrono::milliseconds timeout) {
  return impl_->list_services(timeout);
}

void DdsClient::login(const std::string&, std::chrono::milliseconds) {
  throw ClientError("dds client: " + std::string(k_dds_has_no_token));
}

const std::string& DdsClient::id() const { return impl_->id_hex_; }

bool is_partition_pattern(std::string_view partition) {
  return partition.find_first_of("*?") != std::string_view::npos;
}

json DdsSimgate::to_json() const {
  json out = {
      {"partition", partition}, {"server", server}, {"worlds", worlds}, {"services", services}};
  if (!whole) out["whole"] = false;
  return out;
}

std::vector<DdsSimgate> list_simgates(const DdsClientOptions& options,
                                      std::chrono::milliseconds timeout,
                                      std::chrono::milliseconds settle) {
  const std::unique_ptr<dds::Participant> participant = dds_detail::join_domain(options);
  std::vector<dds_catalog::ServerCatalog> catalogs;
  {
    dds_catalog::CatalogReader reader(participant->handle(), options.partition);
    catalogs = reader.read(std::chrono::steady_clock::now() + timeout, settle);
  }
  if (catalogs.empty())
    throw ClientError("DDS client: no simgate in domain " + std::to_string(options.domain) +
                      " whose partition matches '" + options.partition + "' within " +
                      std::to_string(timeout.count()) +
                      " ms: waited for catalogs (simgate_Catalog) in the partitions it "
                      "matches. " +
                      dds_detail::network_hint(options.config));
  std::vector<DdsSimgate> out;
  for (auto& catalog : catalogs) {
    DdsSimgate simgate{catalog.partition, catalog.server, {}, json::array(), catalog.whole};
    std::set<unsigned> worlds;
    for (auto& [component, services] : catalog.services) {
      auto address = RequestManager::world_address(component);
      worlds.insert(address ? address->first : 0);
      for (auto& service : services) simgate.services.push_back(std::move(service));
    }
    for (unsigned world : worlds) simgate.worlds.push_back("w" + std::to_string(world));
    out.push_back(std::move(simgate));
  }
  return out;
}

std::unique_ptr<Client> make_dds_client(const json& options) {
  return std::make_unique<DdsClient>(DdsClientOptions::from_json(options));
}

}  // namespace simgate::client
