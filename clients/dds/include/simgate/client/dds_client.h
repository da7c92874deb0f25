// simgate/client/dds_client.h — a C++ client of simgate's DDS transport.
//
// Terms (see docs/transports/dds.md and protocols/dds/simgate_dds.idl):
//  - A DdsClient joins a DDS domain and partition (those of the simulation it talks to) with
//    its own participant, a request writer and a reply reader. Its id is the GUID of its
//    request writer (the server refuses any other); its reply reader lives in the partition
//    "<partition>/<hex id>", where the server writes this client's replies with a writer of
//    its own, announces the id in USER_DATA ("simgate.id=<hex>") and only takes replies
//    that carry it.
//  - A call is numbered (CallId = the request's seq). start() sends it; wait() returns its
//    final Outcome; async services are acknowledged first (wait_accepted()); cancel()
//    cancels the client's own pending call.
//  - list_services() reads the transient-local catalog: every component's descriptors.
//  - A client talks to one simgate: its partition is a name, never a pattern. Several
//    simgates (one per partition: by convention, one per host) are listed together by
//    list_simgates() with a partition pattern, and called through one client each.
//  - Raw images (opt-in, DdsClientOptions::raw_images): the client also reads
//    simgate_ReplyImage in its reply partition, with a reader created before its reply
//    reader and announcing the same id, so the server sends the images of its camera replies
//    (get_image, capture, get_local_data) there as simgate::stream::Image, raw, and their
//    records in the reply say "format": "raw" instead of carrying a base64 PNG. The result is
//    the JSON as the server sent it; Outcome::attachments holds one entry per record (the
//    result, or each item of a capture's list), in record order: the image (content "image",
//    description {component, width, height, encoding, step, is_bigendian, intrinsic_matrix,
//    timestamp}, the bytes; no to_json) for a record that says "format": "raw", null for one
//    that kept its PNG (the server could not send it in time). Empty when no record is raw.
//    Images are matched to their call by seq (Image.seq = the call's seq). A call's images
//    are written before its reply, but the two topics are not ordered at the reader: wait()
//    returns once the final reply is in and as many images of its seq as its records say
//    are raw, within the same timeout; a reply whose images do not all come within it is an
//    error (ClientError naming how many came), as is a server that leaves meanwhile.
//
// Life cycle: the constructor creates the DDS entities and a status thread; the destructor
// stops the thread and leaves the domain (the server then cancels this client's pending
// async calls). Cyclone stays on loopback unless `config` says otherwise.
//
// Threads: every method is thread-safe; call/wait/wait_accepted/cancel/list block the
// calling thread up to their timeout. A caller waiting for a reply takes it from the reply
// reader itself (no receive thread between Cyclone and the caller): the first waiting
// caller becomes the reader, waits on the reader's read condition, and takes every reply
// that arrived (with raw_images: and every image, one taker at a time so that a call's
// images keep their order) — its own and those of other callers, which it files in their
// slots and wakes them; when it has its reply it leaves the role to another waiting caller. Replies
// that arrive while nobody waits stay in the reader until someone does. The client's own
// status thread only watches matches (a server appearing or going away) and wakes the
// waiters; nothing runs on Cyclone's threads.
#ifndef SIMGATE_CLIENT_DDS_CLIENT_H_
#define SIMGATE_CLIENT_DDS_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/client/client.h"

namespace simgate::client {

// How long list_simgates() waits, once the simgates it found are complete, for others.
inline constexpr std::chrono::milliseconds k_simgates_settle{1000};

struct DdsClientOptions {
  std::uint32_t domain = 0;           // DDS domain id of the simulation
  std::string partition = "simgate";  // its partition (list_simgates: a name or a pattern)
  std::string config;                 // Cyclone XML or file:// URI; "" = loopback; "env"
  // how long start() waits for a server (call(), cancel() and list_services() wait their timeout)
  std::chrono::milliseconds discovery_timeout{10000};
  // Read camera replies' images raw (Outcome::attachments, records "format": "raw") instead
  // of as PNGs in the records. Off by default: the reply is then the same JSON as on every
  // other transport (what `simgate call` prints).
  bool raw_images = false;

  // From {"domain", "partition", "config", "discovery_timeout_ms", "raw_images"}; throws
  // ClientError.
  static DdsClientOptions from_json(const json& options);
};

class DdsClient final : public Client {
 public:
  using CallId = std::uint64_t;

  // Throws ClientError when DDS cannot be set up (bad XML, domain id...) and for a
  // partition pattern (a client calls one simgate: list_simgates lists those it matches).
  explicit DdsClient(DdsClientOptions options = {});
  ~DdsClient() override;
  DdsClient(const DdsClient&) = delete;
  DdsClient& operator=(const DdsClient&) = delete;

  // Waits until a server's request reader and reply writer are matched. False on timeout.
  bool wait_for_server(std::chrono::milliseconds timeout);

  // Sends component.service(params) (array, object or null) and returns its id at once.
  // Waits up to discovery_timeout for a server first; throws ClientError if there is none.
  CallId start(const std::string& component, const std::string& service, const json& params);
  // True once the server acknowledged the call (ST_ACCEPTED, async services) or finished it.
  // False on timeout.
  bool wait_accepted(CallId id, std::chrono::milliseconds timeout);
  // The call's final outcome (with raw_images: and the images its reply announces, as
  // attachments). Throws ClientError on timeout or when the server goes away. Each call's
  // outcome can be waited for once.
  Outcome wait(CallId id, std::chrono::milliseconds timeout);
  // Cancels a pending call of this client. True if the server found it running (it then
  // ends PREEMPTED, Failure::cancelled). Throws ClientError on timeout (which bounds finding
  // the server too).
  bool cancel(CallId id, std::chrono::milliseconds timeout);

  // Client interface: start() + wait(), `timeout` bounding both (finding a server included).
  // A ClientError for no server names the domain, the partition, what was missing and the
  // network settings in use.
  Outcome call(const std::string& component, const std::string& service, const json& params,
               std::chrono::milliseconds timeout) override;
  // The catalog: a JSON array of ServiceDescriptor::to_json() objects, by component name.
  // Throws ClientError when no complete catalog arrives within `timeout`.
  json list_services(std::chrono::milliseconds timeout) override;
  // Throws ClientError: the DDS transport has no token authentication (its network is
  // restricted with Cyclone's settings or DDS Security instead).
  void login(const std::string& token, std::chrono::milliseconds timeout) override;

  // This client's id on the wire (32 hex digits).
  const std::string& id() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;  // DDS entities, the status thread and the call table
};

// Whether `partition` is a pattern of partitions: it holds Cyclone's wildcards, `*` (any
// characters, "/" included) or `?` (one character).
bool is_partition_pattern(std::string_view partition);

// A simgate found in the DDS catalog: its DDS transport.
struct DdsSimgate {
  std::string partition;            // its partition: by convention, its host
  std::string server;               // its DDS participant's GUID (32 hex digits)
  std::vector<std::string> worlds;  // the worlds its catalog names: "w0", "w1", ... in order
  json services;                    // its catalog: ServiceDescriptor::to_json() objects, by
                                    // component (a world's as "w<k>/<component>")
  bool whole = true;                // false: its catalog was still arriving at the timeout

  json to_json() const;  // {"partition", "server", "worlds", "services"} (+ "whole": false)
};

// Every simgate of options.domain whose partition matches options.partition (a name, or a
// pattern: "*" for all, "lab-*"), by partition. Reads the catalog only (a participant of its
// own, which sends no request), with options.config's network settings.
// Returns once it found one and each one's catalog is whole, and no other appeared for
// `settle` (discovery is not a census: a simgate that answers later than that is missed);
// at `timeout`, with what it found. Throws ClientError naming the domain, the partition
// pattern and the time waited when it found none.
std::vector<DdsSimgate> list_simgates(const DdsClientOptions& options,
                                      std::chrono::milliseconds timeout,
                                      std::chrono::milliseconds settle = k_simgates_settle);

}  // namespace simgate::client

#endif  // SIMGATE_CLIENT_DDS_CLIENT_H_
