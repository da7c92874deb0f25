// DdsClient::Impl, the DDS side of the DDS client: its entities (the request writer, whose
// GUID is its id; the reply reader in its own partition, filtered on its id; the raw image
// reader), the status thread that follows the server's matches (a server gone fails the calls
// in flight), requests written, and the catalog read for list_services. Replies taken and
// waited for: dds_client_replies.cc.
#include <cstring>
#include <map>

#include "dds_catalog.h"
#include "dds_client_impl.h"
#include "dds_support.h"
#include "simgate_streams.h"

namespace simgate::client {

using dds::retcode_text;
using dds_catalog::check;

namespace {

constexpr dds_attach_t k_token_guard = 2;
constexpr dds_attach_t k_token_status = 3;

// our partition) never reach our reader.
bool is_ours(const void* sample, void* arg) {
  return std::memcmp(static_cast<const simgate_Reply*>(sample)->client, arg, 16) == 0;
}

}  // namespace

DdsClient::Impl::Impl(DdsClientOptions options) : options_(std::move(options)) {
  if (is_partition_pattern(options_.partition))
    throw ClientError("DDS client: partition '" + options_.partition +
                      "' is a pattern: a client calls one simgate, in the partition it names "
                      "(list_simgates, `simgate list --partition PATTERN`, lists those a "
                      "pattern matches)");
  participant_ = dds_detail::join_domain(options_);
  dds_entity_t pp = participant_->handle();
  dds::QosPtr partition_qos(dds_create_qos());
  dds_qset_partition1(partition_qos.get(), options_.partition.c_str());
  publisher_ = check(dds_create_publisher(pp, partition_qos.get(), nullptr), "publisher");

  // the request writer; its GUID is our id
  dds_entity_t request_topic =
      check(dds_create_topic(pp, &simgate_Request_desc, dds::k_request_topic, nullptr, nullptr),
            "topic simgate_Request");
  dds::QosPtr request_qos = dds::make_qos(false, 0, DDS_SECS(1));
  request_writer_ = check(dds_create_writer(publisher_, request_topic, request_qos.get(), nullptr),
                          "request writer");
  dds_guid_t guid;
  check(dds_get_guid(request_writer_, &guid), "client id");
  client_id_ = dds::to_client_id(guid);
  id_hex_ = dds::to_hex(client_id_);

  // the reply reader: in our own partition, where the server writes our replies with a writer
  // of ours alone; only our instance; announced so the server knows when it matched
  dds::QosPtr reply_partition_qos(dds_create_qos());
  const std::string reply_partition = options_.partition + "/" + id_hex_;
  dds_qset_partition1(reply_partition_qos.get(), reply_partition.c_str());
  reply_subscriber_ =
      check(dds_create_subscriber(pp, reply_partition_qos.get(), nullptr), "reply subscriber");
  dds_entity_t reply_topic =
      check(dds_create_topic(pp, &simgate_Reply_desc, dds::k_reply_topic, nullptr, nullptr),
            "topic simgate_Reply");
  dds_topic_filter filter{};
  filter.mode = DDS_TOPIC_FILTER_SAMPLE_ARG;
  filter.f.sample_arg = &is_ours;
  filter.arg = client_id_.data();
  check(dds_set_topic_filter_extended(reply_topic, &filter), "reply filter");
  dds::QosPtr reply_qos = dds::make_qos(false, 0, DDS_SECS(1));
  std::string userdata = "simgate.role=client;simgate.v=2;simgate.id=" + id_hex_;
  dds_qset_userdata(reply_qos.get(), userdata.data(), userdata.size());
  // raw images: their reader first, announced as the reply reader is (the server discovers a
  // participant's endpoints in the order they were created: when it has matched our reply
  // reader, it knows this one, and the images of our first call already come raw)
  if (options_.raw_images) {
    dds_entity_t image_topic = check(dds_create_topic(pp, &simgate_stream_Image_desc,
                                                      dds::k_reply_image_topic, nullptr, nullptr),
                                     "topic simgate_ReplyImage");
    image_reader_ =
        check(dds_create_reader(reply_subscriber_, image_topic, reply_qos.get(), nullptr),
              "image reader");
  }
  reply_reader_ = check(dds_create_reader(reply_subscriber_, reply_topic, reply_qos.get(), nullptr),
                        "reply reader");

  // callers wait for replies themselves (one at a time is the reader: see await)
  reader_waitset_ = check(dds_create_waitset(pp), "reply waitset");
  read_condition_ = check(dds_create_readcondition(reply_reader_, DDS_ANY_STATE), "read condition");
  reader_guard_ = check(dds_create_guardcondition(pp), "reply guard condition");
  check(dds_waitset_attach(reader_waitset_, read_condition_, 0), "waitset attachment");
  check(dds_waitset_attach(reader_waitset_, reader_guard_, 0), "waitset attachment");
  if (image_reader_ > 0) {
    image_condition_ =
        check(dds_create_readcondition(image_reader_, DDS_ANY_STATE), "image read condition");
    check(dds_waitset_attach(reader_waitset_, image_condition_, 0), "waitset attachment");
  }

  // the status thread waits for match changes and stop
  waitset_ = check(dds_create_waitset(pp), "waitset");
  guard_ = check(dds_create_guardcondition(pp), "guard condition");
  dds_set_status_mask(reply_reader_, DDS_SUBSCRIPTION_MATCHED_STATUS);
  dds_set_status_mask(request_writer_, DDS_PUBLICATION_MATCHED_STATUS);
  check(dds_waitset_attach(waitset_, guard_, k_token_guard), "waitset attachment");
  check(dds_waitset_attach(waitset_, reply_reader_, k_token_status), "waitset attachment");
  check(dds_waitset_attach(waitset_, request_writer_, k_token_status), "waitset attachment");
  thread_ = std::thread([this] { run(); });
}

DdsClient::Impl::~Impl() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  if (guard_ > 0) dds_set_guardcondition(guard_, true);
  if (thread_.joinable()) thread_.join();
  catalog_.reset();
  participant_.reset();
}

void DdsClient::Impl::run() {
  update_matches();
  dds_attach_t triggered[8];
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
    }
    dds_return_t n = dds_waitset_wait(waitset_, triggered, 8, DDS_SECS(1));
    if (n < 0) return;
    bool status = false;
    for (dds_return_t i = 0; i < std::min<dds_return_t>(n, 8); ++i)
      status |= triggered[i] == k_token_status;
    if (status) update_matches();
  }
}

void DdsClient::Impl::update_matches() {
  // reading the statuses resets them
  dds_publication_matched_status_t pub{};
  dds_subscription_matched_status_t sub{};
  dds_get_publication_matched_status(request_writer_, &pub);
  dds_get_subscription_matched_status(reply_reader_, &sub);
  // replies (and images) already received are outcomes, not losses
  take_images();
  take_replies();
  std::lock_guard lock(mutex_);
  server_readers_ = static_cast<int>(pub.current_count);
  server_writers_ = static_cast<int>(sub.current_count);
  // no server left: nobody will answer the calls in flight
  if (server_writers_ == 0 || server_readers_ == 0) {
    for (auto& [id, slot] : slots_)
      if (!slot.complete() && slot.error.empty())
        slot.error =
            "DDS client: the server of partition '" + options_.partition + "' (domain " +
            std::to_string(options_.domain) + ") went away before answering call " +
            std::to_string(id) +
            (slot.outcome ? " (its reply came, " + std::to_string(slot.images.size()) + " of its " +
                                std::to_string(slot.raw) + " raw images did not)"
                          : std::string());
  }
  changed_.notify_all();
  // the reading caller waits on DDS, not on changed_
  if (reading_) dds_set_guardcondition(reader_guard_, true);
}

bool DdsClient::Impl::wait_for_server(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout,
                           [&] { return server_readers_ > 0 && server_writers_ > 0; });
}

DdsClient::CallId DdsClient::Impl::send(simgate_Op op, const std::string& component,
                                        const std::string& service, const json& params,
                                        CallId target, std::chrono::milliseconds discovery) {
  if (!wait_for_server(discovery)) {
    std::string found;
    {
      std::lock_guard lock(mutex_);
      found = server_readers_ > 0   ? "found its request reader only"
              : server_writers_ > 0 ? "found its reply writer only"
                                    : "found neither";
    }
    throw ClientError(
        "DDS client: no simgate simulation in domain " + std::to_string(options_.domain) +
        ", partition '" + options_.partition + "' within " + std::to_string(discovery.count()) +
        " ms: waited for a simulation's request reader and reply writer to match this client (" +
        found + "). " + dds_detail::network_hint(options_.config));
  }
  CallId seq = next_seq_++;
  {
    std::lock_guard lock(mutex_);
    slots_.emplace(seq, Slot{});
  }
  std::string params_text = params.is_null()
                                ? std::string()
                                : params.dump(-1, ' ', false, json::error_handler_t::replace);
  simgate_Request request{};
  std::memcpy(request.id.client, client_id_.data(), client_id_.size());
  request.id.seq = seq;
  request.op = op;
  request.component = const_cast<char*>(component.c_str());
  request.service = const_cast<char*>(service.c_str());
  request.params = const_cast<char*>(params_text.c_str());
  request.target = target;
  dds_return_t rc = dds_write(request_writer_, &request);
  if (rc < 0) {
    std::lock_guard lock(mutex_);
    slots_.erase(seq);
    throw ClientError("DDS client: request " + component + "." + service +
                      " not sent: " + retcode_text(rc));
  }
  return seq;
}

json DdsClient::Impl::list_services(std::chrono::milliseconds timeout) {
  std::lock_guard lock(catalog_mutex_);
  // created once: transient-local, so it receives what was published before
  if (!catalog_)
    catalog_ =
        std::make_unique<dds_catalog::CatalogReader>(participant_->handle(), options_.partition);
  const auto catalogs =
      catalog_->read(std::chrono::steady_clock::now() + timeout, std::chrono::milliseconds(0));
  if (catalogs.empty())
    throw ClientError("DDS client: no simgate simulation in domain " +
                      std::to_string(options_.domain) + ", partition '" + options_.partition +
                      "' within " + std::to_string(timeout.count()) +
                      " ms: waited for a simulation's catalog of services. " +
                      dds_detail::network_hint(options_.config));
  // one server per partition is the rule; were there more, a component listed once
  std::map<std::string, json> by_component;
  for (const auto& catalog : catalogs)
    for (const auto& [component, services] : catalog.services) by_component[component] = services;
  json out = json::array();
  for (auto& [component, services] : by_component)
    for (auto& service : services) out.push_back(std::move(service));
  return out;
}

}  // namespace simgate::client
