// dds_raw_client.h — the raw DDS client of simgate_bench_dds_attack (dds_attack.cc, the DDS
// side of bench/attacks): a Cyclone client speaking simgate's wire types
// (protocols/dds/simgate_dds.idl) with no DdsClient in between, so that it can send what a
// well-behaved client never sends: another client's id or a zero id, any seq, any params, and
// a reply reader that never takes. Replies come back as Reply, whose JSON form (to_json) is
// what the attacks print, with messages cut to a preview (never a 10 MB echo on stdout).
//
// Cyclone stays on loopback (the compiled-in config/dds/loopback.xml). Every wait is bounded
// by g_timeout (the program's --timeout, default 20 s).
//
// Threads: a RawClient is used by one thread.
#ifndef SIMGATE_BENCH_DDS_RAW_CLIENT_H_
#define SIMGATE_BENCH_DDS_RAW_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "bench_util.h"
#include "dds_support.h"

namespace simgate::bench {

namespace sd = simgate::dds;

// The bound of every wait (a server, a reply): the program's --timeout.
inline std::chrono::milliseconds g_timeout{20000};

inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

inline const char* status_name(simgate_ReplyStatus s) {
  switch (s) {
    case simgate_ST_ACCEPTED: return "ACCEPTED";
    case simgate_ST_SUCCESS: return "SUCCESS";
    case simgate_ST_FAILED: return "FAILED";
    case simgate_ST_PREEMPTED: return "PREEMPTED";
    case simgate_ST_REFUSED: return "REFUSED";
    case simgate_ST_RUNNING: return "RUNNING";
  }
  return "?";
}

inline const char* failure_name(simgate_Failure f) {
  switch (f) {
    case simgate_FL_NONE: return "none";
    case simgate_FL_UNKNOWN_SERVICE: return "unknown_service";
    case simgate_FL_BAD_ARGUMENTS: return "bad_arguments";
    case simgate_FL_BUSY: return "busy";
    case simgate_FL_SERVICE_ERROR: return "service_error";
    case simgate_FL_INTERNAL: return "internal";
    case simgate_FL_PREEMPTED: return "preempted";
    case simgate_FL_CANCELLED: return "cancelled";
    case simgate_FL_SHUTDOWN: return "shutdown";
    case simgate_FL_BAD_REQUEST: return "bad_request";
    case simgate_FL_TIMEOUT: return "timeout";
  }
  return "?";
}

inline bool valid_utf8(const std::string& s) {
  std::size_t i = 0;
  while (i < s.size()) {
    auto c = static_cast<unsigned char>(s[i]);
    std::size_t n = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
    if (n == 0 || i + n > s.size()) return false;
    for (std::size_t k = 1; k < n; ++k)
      if ((static_cast<unsigned char>(s[i + k]) >> 6) != 2) return false;
    i += n;
  }
  return true;
}

// At most `n` bytes of a message, for the report (never a 10 MB echo on stdout).
inline std::string preview(const std::string& s, std::size_t n = 400) {
  if (s.size() <= n) return s;
  while (n > 0 && (static_cast<unsigned char>(s[n]) >> 6) == 2) --n;
  return s.substr(0, n) + "...";
}

struct Reply {
  std::uint64_t seq = 0;
  simgate_ReplyStatus status = simgate_ST_SUCCESS;
  simgate_Failure failure = simgate_FL_NONE;
  bool last = false;
  std::string result, message;
  double ms = 0;  // since the request was written

  json to_json() const {
    return {{"seq", seq},
            {"status", status_name(status)},
            {"failure", failure_name(failure)},
            {"last", last},
            {"result", preview(result)},
            {"message", preview(message)},
            {"message_bytes", message.size()},
            {"message_utf8", valid_utf8(message)},
            {"ms", ms}};
  }
};

// A client on the wire types: its own participant, a request writer in the partition and,
// when asked, a reply reader in "<partition>/<its id>" announcing the id in USER_DATA.
class RawClient {
 public:
  RawClient(std::uint32_t domain, const std::string& partition)
      : participant_(domain, sd::k_loopback_xml, "attack client"), partition_(partition) {
    dds_entity_t pp = participant_.handle();
    sd::QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), partition.c_str());
    dds_entity_t publisher = dds_create_publisher(pp, partition_qos.get(), nullptr);
    dds_entity_t topic =
        dds_create_topic(pp, &simgate_Request_desc, sd::k_request_topic, nullptr, nullptr);
    sd::QosPtr qos = sd::make_qos(false, 0, DDS_SECS(1));
    writer_ = dds_create_writer(publisher, topic, qos.get(), nullptr);
    if (writer_ < 0) throw std::runtime_error("request writer: " + sd::retcode_text(writer_));
    dds_guid_t guid;
    dds_get_guid(writer_, &guid);
    id_ = sd::to_client_id(guid);
  }

  // max_samples: how many replies the reader holds (one that never takes then stops
  // acknowledging)
  void create_reply_reader(int32_t max_samples = DDS_LENGTH_UNLIMITED) {
    dds_entity_t pp = participant_.handle();
    sd::QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), (partition_ + "/" + sd::to_hex(id_)).c_str());
    dds_entity_t subscriber = dds_create_subscriber(pp, partition_qos.get(), nullptr);
    dds_entity_t topic =
        dds_create_topic(pp, &simgate_Reply_desc, sd::k_reply_topic, nullptr, nullptr);
    sd::QosPtr qos = sd::make_qos(false, 0, DDS_SECS(1));
    dds_qset_resource_limits(qos.get(), max_samples, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
    std::string userdata = std::string(sd::k_userdata_id_prefix) + sd::to_hex(id_);
    dds_qset_userdata(qos.get(), userdata.data(), userdata.size());
    reader_ = dds_create_reader(subscriber, topic, qos.get(), nullptr);
    if (reader_ < 0) throw std::runtime_error("reply reader: " + sd::retcode_text(reader_));
  }

  // The server's request reader matched our writer (and, with a reply reader, its reply
  // writer for us matched the reader).
  bool wait_matched() {
    const auto deadline = Clock::now() + g_timeout;
    while (Clock::now() < deadline) {
      dds_publication_matched_status_t pub;
      dds_get_publication_matched_status(writer_, &pub);
      bool ok = pub.current_count > 0;
      if (ok && reader_ > 0) {
        dds_subscription_matched_status_t sub;
        dds_get_subscription_matched_status(reader_, &sub);
        ok = sub.current_count > 0;
      }
      if (ok) return true;
      dds_sleepfor(DDS_MSECS(2));
    }
    return false;
  }

  // as: write with that id instead of ours (a spoofer)
  void write(std::uint64_t seq, simgate_Op op, const std::string& component,
             const std::string& service, const std::string& params, std::uint64_t target = 0,
             const sd::ClientId* as = nullptr) {
    simgate_Request rq{};
    std::memcpy(rq.id.client, (as ? *as : id_).data(), 16);
    rq.id.seq = seq;
    rq.op = op;
    rq.component = const_cast<char*>(component.c_str());
    rq.service = const_cast<char*>(service.c_str());
    rq.params = const_cast<char*>(params.c_str());
    rq.target = target;
    written_ = Clock::now();
    dds_return_t rc = dds_write(writer_, &rq);
    if (rc < 0) throw std::runtime_error("dds_write: " + sd::retcode_text(rc));
  }

  // The next reply for us, or nullopt after `timeout`.
  std::optional<Reply> next(std::chrono::milliseconds timeout = g_timeout) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      while (dds_take(reader_, samples, &info, 1, 1) == 1) {
        const auto& r = *static_cast<const simgate_Reply*>(samples[0]);
        std::optional<Reply> out;
        if (info.valid_data && std::memcmp(r.client, id_.data(), 16) == 0)
          out = Reply{r.seq,
                      r.status,
                      r.failure,
                      r.last,
                      r.result ? r.result : "",
                      r.message ? r.message : "",
                      ms_since(written_)};
        dds_return_loan(reader_, samples, 1);
        if (out) return out;
        samples[0] = nullptr;
      }
      dds_sleepfor(DDS_MSECS(1));
    }
    return std::nullopt;
  }

  // The final reply (last = true) for `seq`, skipping others; nullopt after `timeout`.
  std::optional<Reply> final_reply(std::uint64_t seq,
                                   std::chrono::milliseconds timeout = g_timeout) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      auto r = next(left);
      if (!r) return std::nullopt;
      if (r->seq == seq && r->last) return r;
    }
    return std::nullopt;
  }

  // Takes and drops every reply until none came for 200 ms (at most `timeout`). A reader at
  // its resource limit keeps Cyclone's receive thread retrying the delivery, and deleting
  // the participant then waits for it: a stuck client drains before it leaves.
  void drain(std::chrono::milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    auto quiet_since = Clock::now();
    while (Clock::now() < deadline && Clock::now() - quiet_since < std::chrono::milliseconds(200)) {
      void* samples[16] = {};
      dds_sample_info_t infos[16];
      dds_return_t n = dds_take(reader_, samples, infos, 16, 16);
      if (n > 0) {
        dds_return_loan(reader_, samples, n);
        quiet_since = Clock::now();
      } else {
        dds_sleepfor(DDS_MSECS(5));
      }
    }
  }

  const sd::ClientId& id() const { return id_; }

 private:
  sd::Participant participant_;
  std::string partition_;
  dds_entity_t writer_ = 0, reader_ = 0;
  sd::ClientId id_{};
  Clock::time_point written_ = Clock::now();
};

inline json reply_json(const std::optional<Reply>& r) { return r ? r->to_json() : json(nullptr); }

// A client with a reply reader, matched; throws if no server matched in time.
inline std::unique_ptr<RawClient> ready_client(std::uint32_t domain, const std::string& partition) {
  auto c = std::make_unique<RawClient>(domain, partition);
  c->create_reply_reader();
  if (!c->wait_matched())
    throw std::runtime_error("no simgate DDS server matched in partition '" + partition + "'");
  return c;
}

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_DDS_RAW_CLIENT_H_
