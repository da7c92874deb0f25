// dds_catalog.h — reading simgate_Catalog, internal to the DDS client (clients/dds): what
// DdsClient::list_services (one partition) and list_simgates (a partition pattern) share.
//
// Terms: a *server* is one simgate's DDS transport, seen through its catalog writer; its
// *partition* is that writer's partition QoS (from discovery, as Cyclone matched it), so a
// reader in a pattern such as "*" tells the servers apart without anything on the wire
// beyond what every server already sends. The CatalogEntry key is the component alone: two
// servers seen through one reader write the same instances ("robot.motion" on each host),
// so the reader keeps every sample (KEEP_ALL), takes them, and files them by writer.
#ifndef SIMGATE_CLIENTS_DDS_DDS_CATALOG_H_
#define SIMGATE_CLIENTS_DDS_DDS_CATALOG_H_

#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <dds/dds.h>

#include "simgate/core/status.h"

namespace simgate::client::dds_catalog {

// `rc`, an entity Cyclone created; throws ClientError ("DDS client: cannot create <what>:
// <retcode>") when it is an error instead.
dds_entity_t check(dds_entity_t rc, const std::string& what);

// One server's catalog, as read.
struct ServerCatalog {
  std::string partition;                 // its catalog writer's partition
  std::string server;                    // CatalogEntry.server: its participant's GUID (hex)
  bool whole = false;                    // every entry of its latest revision is here
  std::map<std::string, json> services;  // by component: the entry's descriptors (an array)
};

// A transient-local reader of simgate_Catalog in `partition` (a name, or a pattern with
// Cyclone's wildcards), on `participant`. Not thread-safe: one read() at a time.
class CatalogReader {
 public:
  // Throws ClientError when Cyclone refuses an entity.
  CatalogReader(dds_entity_t participant, const std::string& partition);
  ~CatalogReader();
  CatalogReader(const CatalogReader&) = delete;
  CatalogReader& operator=(const CatalogReader&) = delete;

  // The catalogs of the servers matched now, by partition then server. Returns once at least
  // one server is matched, every matched server's catalog is whole and no server matched or
  // left for `settle`; or at `deadline`, with what is there then (entries of a server's
  // latest revision; empty when nothing came).
  std::vector<ServerCatalog> read(std::chrono::steady_clock::time_point deadline,
                                  std::chrono::milliseconds settle);

 private:
  struct Writer {
    ServerCatalog catalog;       // what it wrote, its latest revision only
    std::uint32_t revision = 0;  // that revision
    std::uint32_t count = 0;     // how many entries it has (CatalogEntry.count)
  };

  // The writers matched now (added with their partition); forgets those that left.
  void update_matched();
  // Files every sample there is under its writer.
  void take();
  // Writer `handle`, added (with its partition) if it is new.
  Writer& writer(dds_instance_handle_t handle);
  // Writer `handle`'s partition, from its discovery data ("" once it left).
  std::string partition_of(dds_instance_handle_t handle) const;

  dds_entity_t subscriber_ = 0;                      // in the partition (owns the reader)
  dds_entity_t topic_ = 0;                           // simgate_Catalog
  dds_entity_t reader_ = 0;                          // reliable, transient-local, KEEP_ALL; taken
  dds_entity_t waitset_ = 0;                         // samples, or a writer matched or left
  std::map<dds_instance_handle_t, Writer> writers_;  // by writer, those matched
  bool matched_changed_ = false;  // a writer was added or forgotten (read() resets it)
};

}  // namespace simgate::client::dds_catalog

#endif  // SIMGATE_CLIENTS_DDS_DDS_CATALOG_H_
