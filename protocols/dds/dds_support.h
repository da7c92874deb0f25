// simgate/dds support — what the DDS server (plugins/dds) and client (clients/dds) share.
//
// Terms:
//  - Domain: a Cyclone domain created with dds_create_domain(id, xml) so that the XML
//    settings (by default: loopback only, multicast off) apply to every participant of it
//    in this process. Several simgate objects of one process may share a domain; the last
//    one to leave deletes it.
//  - ClientId: the 16 bytes that name a client on the wire (Reply.client, Request id.client):
//    the GUID of its request writer (the server refuses any other), shown as 32 lowercase
//    hex digits; the partition of its replies is "<partition>/<hex>", and its reply reader
//    announces "simgate.id=<hex>" in its USER_DATA so the server can tell when it matched.
//  - Topics: simgate_Request, simgate_Reply, simgate_Catalog, simgate_Progress (see
//    simgate_dds.idl).
//
// Everything here is thread-safe except where noted; nothing blocks for long.
#ifndef SIMGATE_PLUGINS_DDS_DDS_SUPPORT_H_
#define SIMGATE_PLUGINS_DDS_DDS_SUPPORT_H_

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <dds/dds.h>

#include "simgate/core/status.h"
#include "simgate_dds.h"

namespace simgate::dds {

inline constexpr const char* k_request_topic = "simgate_Request";
inline constexpr const char* k_reply_topic = "simgate_Reply";
inline constexpr const char* k_catalog_topic = "simgate_Catalog";
inline constexpr const char* k_progress_topic = "simgate_Progress";
// The raw pixels of replies' images (simgate::stream::Image, in a client's reply partition).
inline constexpr const char* k_reply_image_topic = "simgate_ReplyImage";
// USER_DATA prefix of a client's reply reader.
inline constexpr std::string_view k_userdata_id_prefix = "simgate.id=";

// The content of config/dds/loopback.xml, compiled in: Cyclone on "lo", multicast off,
// unicast discovery to 127.0.0.1.
extern const char* const k_loopback_xml;

using ClientId = std::array<std::uint8_t, 16>;

std::string to_hex(const ClientId& id);
std::optional<ClientId> client_id_from_hex(std::string_view hex);
ClientId to_client_id(const dds_guid_t& guid);

// "simgate.id=<hex>" read from an endpoint's USER_DATA (nullopt if absent or malformed).
std::optional<ClientId> client_id_from_userdata(const dds_qos_t* qos);

// "DDS_RETCODE_TIMEOUT (-10)".
std::string retcode_text(dds_return_t rc);

// `rc`, an entity Cyclone created; throws std::runtime_error ("DDS transport: cannot create
// <what>: <retcode>") when it is an error instead.
dds_entity_t check_created(dds_entity_t rc, const std::string& what);

// The topic `name` of type `descriptor` on `participant`, created the first time it is asked
// for and kept in `topics` (by name) for the next (check_created's error otherwise).
dds_entity_t cached_topic(std::map<std::string, dds_entity_t>& topics, dds_entity_t participant,
                          const std::string& name, const dds_topic_descriptor_t* descriptor);

// Resolves the "config" option: "" -> the loopback XML; "env" -> the value of CYCLONEDDS_URI,
// or "" (Cyclone's defaults) when it is not set; anything else (XML text or file:// URI) is
// passed through. (dds_create_domain() itself never reads CYCLONEDDS_URI: given nothing, it
// applies Cyclone's defaults.)
const char* resolve_config(const std::string& config);

// What Cyclone did with a domain created only to see whether it accepts settings.
struct DomainTrial {
  dds_entity_t result = 0;          // > 0: created (and already deleted); else Cyclone's error
  std::vector<std::string> errors;  // the error (and fatal) lines Cyclone logged meanwhile
};
// Creates domain `domain` from the Cyclone settings `config`, with no participant, and
// deletes it at once; Cyclone's log and trace go nowhere meanwhile (its errors are
// returned). DDS_RETCODE_PRECONDITION_NOT_MET: this process already has the domain. Use
// settings that cannot get as far as opening sockets (check_cyclone_config's are made to
// fail at the interface lookup). Serialised with Participant's domain creation.
DomainTrial trial_domain(uint32_t domain, const char* config);

struct QosDeleter {
  void operator()(dds_qos_t* q) const { dds_delete_qos(q); }
};
using QosPtr = std::unique_ptr<dds_qos_t, QosDeleter>;
// Reliable (max_blocking_time), the given history depth (0 = KEEP_ALL) and durability.
QosPtr make_qos(bool transient_local, int32_t keep_last, dds_duration_t max_blocking);

// A participant on a domain created from XML settings. Owns the participant (and the domain
// when it is the last user). Not copyable; destroy on any thread once nobody uses it.
class Participant {
 public:
  // `what` names the owner in errors ("DDS transport", "DDS client"). Throws
  // std::runtime_error naming the domain and Cyclone's reason.
  Participant(uint32_t domain, const char* config, const std::string& what);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  dds_entity_t handle() const { return participant_; }
  uint32_t domain() const { return domain_; }

 private:
  uint32_t domain_;                 // DDS domain id
  dds_entity_t domain_entity_ = 0;  // the domain (parent of the participant)
  dds_entity_t participant_ = 0;    // ours
};

// Wire <-> core conversions.
simgate_Failure to_wire(Failure failure);
Failure from_wire(simgate_Failure failure);

}  // namespace simgate::dds

#endif  // SIMGATE_PLUGINS_DDS_DDS_SUPPORT_H_
