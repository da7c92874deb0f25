#include "dds_catalog.h"

#include <algorithm>
#include <tuple>
#include <vector>

#include "dds_support.h"
#include "simgate/client/client.h"

namespace simgate::client::dds_catalog {

dds_entity_t check(dds_entity_t rc, const std::string& what) {
  if (rc < 0) throw ClientError("DDS client: cannot create " + what + ": " + dds::retcode_text(rc));
  return rc;
}

CatalogReader::CatalogReader(dds_entity_t participant, const std::string& partition) {
  dds::QosPtr partition_qos(dds_create_qos());
  dds_qset_partition1(partition_qos.get(), partition.c_str());
  subscriber_ =
      check(dds_create_subscriber(participant, partition_qos.get(), nullptr), "catalog subscriber");
  topic_ = check(dds_create_topic(participant, &simgate_CatalogEntry_desc, dds::k_catalog_topic,
                                  nullptr, nullptr),
                 "topic simgate_Catalog");
  // transient-local: it receives what was published before it; KEEP_ALL: the servers it
  // matches write the same instances (the key is the component), none may hide another's
  dds::QosPtr qos = dds::make_qos(true, 0, DDS_SECS(1));
  reader_ = check(dds_create_reader(subscriber_, topic_, qos.get(), nullptr), "catalog reader");
  waitset_ = check(dds_create_waitset(participant), "catalog waitset");
  dds_set_status_mask(reader_, DDS_SUBSCRIPTION_MATCHED_STATUS);
  check(dds_waitset_attach(waitset_, reader_, 0), "catalog waitset attachment");
  check(dds_waitset_attach(waitset_,
                           check(dds_create_readcondition(reader_, DDS_ANY_STATE), "condition"), 0),
        "catalog waitset attachment");
}

CatalogReader::~CatalogReader() {
  dds_delete(waitset_);
  dds_delete(subscriber_);  // and the reader, its condition
  dds_delete(topic_);
}

std::string CatalogReader::partition_of(dds_instance_handle_t handle) const {
  dds_builtintopic_endpoint_t* endpoint = dds_get_matched_publication_data(reader_, handle);
  if (!endpoint) return "";  // it left meanwhile
  std::string partition;
  uint32_t n = 0;
  char** names = nullptr;
  if (endpoint->qos && dds_qget_partition(endpoint->qos, &n, &names)) {
    // a simgate's writer has one partition; another writer's are joined as Cyclone lists them
    for (uint32_t i = 0; i < n; ++i) {
      partition += (i ? "," : "") + std::string(names[i]);
      dds_free(names[i]);
    }
    dds_free(names);
  }
  dds_builtintopic_free_endpoint(endpoint);
  return partition;
}

CatalogReader::Writer& CatalogReader::writer(dds_instance_handle_t handle) {
  auto [it, added] = writers_.try_emplace(handle);
  if (added) {
    it->second.catalog.partition = partition_of(handle);
    matched_changed_ = true;
  }
  return it->second;
}

void CatalogReader::update_matched() {
  dds_subscription_matched_status_t status;
  dds_get_subscription_matched_status(reader_, &status);  // resets it (it woke the waitset)
  std::vector<dds_instance_handle_t> handles(status.current_count + 8);
  for (;;) {
    // how many there are, even beyond the room given
    const dds_return_t n = dds_get_matched_publications(reader_, handles.data(), handles.size());
    const std::size_t matched = n > 0 ? static_cast<std::size_t>(n) : 0;
    if (matched <= handles.size()) {
      handles.resize(matched);
      break;
    }
    handles.resize(matched + 8);
  }
  for (dds_instance_handle_t handle : handles) writer(handle);
  std::erase_if(writers_, [&](const auto& w) {
    bool gone = std::find(handles.begin(), handles.end(), w.first) == handles.end();
    matched_changed_ |= gone;
    return gone;
  });
}

void CatalogReader::take() {
  constexpr int batch = 64;
  void* samples[batch];
  dds_sample_info_t infos[batch];
  for (;;) {
    samples[0] = nullptr;
    dds_return_t n = dds_take(reader_, samples, infos, batch, batch);
    if (n <= 0) return;
    for (dds_return_t i = 0; i < n; ++i) {
      const auto& entry = *static_cast<const simgate_CatalogEntry*>(samples[i]);
      const std::string component = entry.component ? entry.component : "";
      if (!infos[i].valid_data) {
        // a component its server disposed: served no more
        auto it = writers_.find(infos[i].publication_handle);
        if (it != writers_.end() && infos[i].instance_state == DDS_IST_NOT_ALIVE_DISPOSED)
          it->second.catalog.services.erase(component);
        continue;
      }
      Writer& w = writer(infos[i].publication_handle);
      // a later revision replaces the whole catalog: what it lacks is gone, even when the
      // dispose has not come (a reader joining while the catalog changes gets a gone
      // component's last entry before it)
      if (entry.revision < w.revision) continue;
      if (entry.revision > w.revision) {
        w.catalog.services.clear();
        w.revision = entry.revision;
      }
      json services = json::parse(entry.services ? entry.services : "", nullptr, false);
      if (!services.is_array()) continue;
      w.count = entry.count;
      w.catalog.server = entry.server ? entry.server : "";
      w.catalog.services[component] = std::move(services);
    }
    dds_return_loan(reader_, samples, n);
    if (n < batch) return;
  }
}

std::vector<ServerCatalog> CatalogReader::read(std::chrono::steady_clock::time_point deadline,
                                               std::chrono::milliseconds settle) {
  auto quiet_since = std::chrono::steady_clock::now();  // no writer matched or left since
  for (;;) {
    matched_changed_ = false;
    take();
    update_matched();  // after take(): forgets a writer that left, whatever it sent last
    auto now = std::chrono::steady_clock::now();
    if (matched_changed_) quiet_since = now;
    for (auto& [handle, w] : writers_)
      w.catalog.whole = w.count > 0 && w.catalog.services.size() >= w.count;
    const bool whole =
        !writers_.empty() && std::all_of(writers_.begin(), writers_.end(),
                                         [](const auto& w) { return w.second.catalog.whole; });
    if (now >= deadline || (whole && now >= quiet_since + settle)) break;
    auto until = whole ? std::min(deadline, quiet_since + settle) : deadline;
    dds_waitset_wait(waitset_, nullptr, 0,
                     std::chrono::duration_cast<std::chrono::nanoseconds>(until - now).count());
  }
  std::vector<ServerCatalog> out;
  for (const auto& [handle, w] : writers_)
    if (!w.catalog.services.empty()) out.push_back(w.catalog);
  std::sort(out.begin(), out.end(), [](const ServerCatalog& a, const ServerCatalog& b) {
    return std::tie(a.partition, a.server) < std::tie(b.partition, b.server);
  });
  return out;
}

}  // namespace simgate::client::dds_catalog
