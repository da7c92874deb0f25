// dds_client_impl.h — DdsClient's state (DdsClient::Impl), internal to the DDS client
// (clients/dds): its DDS entities, the status thread and the table of calls waiting for their
// replies; and the helpers its files share. dds_client.cc: the options, the facade and
// list_simgates; dds_client_impl.cc: the entities, the status thread, calls sent and the
// catalog read; dds_client_replies.cc: replies and their images taken and waited for.
#ifndef SIMGATE_CLIENTS_DDS_DDS_CLIENT_IMPL_H_
#define SIMGATE_CLIENTS_DDS_DDS_CLIENT_IMPL_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "dds_catalog.h"
#include "dds_support.h"
#include "simgate/client/dds_client.h"
#include "simgate/core/streams.h"

namespace simgate::client {

namespace dds_detail {

// Why a simulation may be invisible: the network settings both sides must share.
std::string network_hint(const std::string& config);
// A participant of the options' domain, with their network settings (ClientError when Cyclone
// refuses them).
std::unique_ptr<dds::Participant> join_domain(const DdsClientOptions& options);

}  // namespace dds_detail

class DdsClient::Impl {
 public:
  // The state of one call (or cancel) until its final reply is consumed.
  struct Slot {
    bool accepted = false;           // ST_ACCEPTED seen (or final reply)
    std::optional<Outcome> outcome;  // the final reply
    std::size_t raw = 0;             // how many of its records say "format": "raw"
    std::vector<std::shared_ptr<const StreamPayload>> images;  // simgate_ReplyImage of its
                                                               // seq, in arrival (= record) order
    std::string error;                                         // the server went away

    // The final reply and every image it announces are here.
    bool complete() const { return outcome && images.size() >= raw; }
  };

  explicit Impl(DdsClientOptions options);
  ~Impl();

  bool wait_for_server(std::chrono::milliseconds timeout);
  // Waits up to `discovery` for a server, then writes the request; returns its seq.
  CallId send(simgate_Op op, const std::string& component, const std::string& service,
              const json& params, CallId target, std::chrono::milliseconds discovery);
  bool wait_accepted(CallId id, std::chrono::milliseconds timeout);
  // `whole`: the caller's whole timeout when part of it went into finding a server (for
  // the message); 0 = `timeout`.
  Outcome wait(CallId id, std::chrono::milliseconds timeout, std::chrono::milliseconds whole = {});
  json list_services(std::chrono::milliseconds timeout);

  // Caller's thread, with `lock` (on mutex_) held: returns true once done() holds, false at
  // the deadline. The first waiter without a reader becomes the reader: it waits on the
  // reply reader itself and takes every reply (its own and the other callers'); the others
  // wait on changed_ until their reply is in their slot or the reader role is free.
  template <class Done>
  bool await(std::unique_lock<std::mutex>& lock, std::chrono::steady_clock::time_point deadline,
             Done done);

  DdsClientOptions options_;                       // as given
  std::unique_ptr<dds::Participant> participant_;  // owns every entity
  dds::ClientId client_id_{};                      // our request writer's GUID
  std::string id_hex_;                             // the same, hex
  dds_entity_t publisher_ = 0;                     // in the partition
  dds_entity_t reply_subscriber_ = 0;              // in "<partition>/<id_hex_>"
  dds_entity_t request_writer_ = 0;                // simgate_Request
  dds_entity_t reply_reader_ = 0;                  // simgate_Reply, filtered on client_id_
  dds_entity_t image_reader_ = 0;                  // simgate_ReplyImage (raw_images only)
  dds_entity_t waitset_ = 0, guard_ = 0;           // the status thread's waitset and its stop guard
  dds_entity_t reader_waitset_ = 0;                // the reading caller's waitset
  dds_entity_t read_condition_ = 0;                // replies available (on reader_waitset_)
  dds_entity_t image_condition_ = 0;               // images available (on reader_waitset_)
  dds_entity_t reader_guard_ = 0;                  // wakes the reading caller (match change, stop)
  std::atomic<CallId> next_seq_{1};                // call numbering

  std::mutex take_images_mutex_;            // one take_images() at a time (taken before
                                            // mutex_): a call's images stay in order
  std::mutex mutex_;                        // guards everything below
  std::condition_variable changed_;         // a reply, a match, or stop
  std::unordered_map<CallId, Slot> slots_;  // calls not yet consumed
  int server_readers_ = 0;                  // matched request readers
  int server_writers_ = 0;                  // matched reply writers
  bool reading_ = false;                    // a caller is the reader (see await)
  bool stopping_ = false;                   // the status thread must leave
  std::mutex catalog_mutex_;                // one list_services at a time
  std::unique_ptr<dds_catalog::CatalogReader> catalog_;  // created by the first list_services

  std::thread thread_;  // the status thread

 private:
  void run();
  void take_replies();
  void take_images();
  void update_matches();
};

}  // namespace simgate::client

#endif  // SIMGATE_CLIENTS_DDS_DDS_CLIENT_IMPL_H_
