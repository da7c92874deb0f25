// The per-client reply writers of the DDS transport (DDS thread only): clients appear with
// their request writers and get a reply writer of their own, in "<partition>/<id>", counted
// as reachable once a reader announcing their id matches it; outcomes become replies
// (write_finished) written at once, or parked while the reader is missing or the writer is
// full, retried with backoff, dropped after park_timeout_ms (logged, rate-limited); a client
// that leaves has its async calls cancelled, and its writer is retired once its replies are
// acknowledged. A client's first call asking for progress gives it a progress writer (best
// effort, beside its reply writer), which carries its calls' reports, written before the
// replies delivered with them. A client with a reader on simgate_ReplyImage gets the images of
// its replies there, raw, beside them (send_images); its calls are made raw (Call::
// raw_attachments: the camera makes no PNG), and an image that cannot go raw after all gets
// its PNG from its pixels (with_png). Options, entities, the DDS thread: dds_request_manager.cc;
// requests: dds_requests.cc.
#include <algorithm>
#include <cstring>
#include <set>
#include <utility>
#include <vector>

#include "dds_request_manager.h"
#include "simgate/core/log.h"
#include "simgate/core/streams.h"

namespace simgate::dds {

namespace {

// A client whose reply writer is full is retried after 5 ms, then 10, 20... up to 320 ms
// while its reader takes nothing (after 5 ms again once it took something).
constexpr std::chrono::milliseconds k_min_retry_delay{5};
constexpr std::chrono::milliseconds k_max_retry_delay{320};
// At most one "dropped" log line per client per interval (with the count meanwhile).
constexpr std::chrono::seconds k_drop_log_interval{10};

// The records a result's attachments are the pixels of: the result, or the items of its list.
std::vector<json*> image_records(json& value) {
  std::vector<json*> records;
  if (value.is_object()) {
    records.push_back(&value);
  } else if (value.is_array()) {
    for (json& record : value) records.push_back(&record);
  }
  return records;
}

// A record that does not go raw keeps (or gets) its PNG: one the service left out, its caller
// having been expected to take the pixels raw (Call::raw_attachments), is made now from the
// pixels (the payload's to_json: the plugin knows no codec). DDS thread; only in this fallback.
void with_png(json& record, const StreamPayload* pixels, std::uint64_t seq) {
  if (!pixels || !pixels->to_json || !record.is_object() || record.contains("image")) return;
  const auto format = record.find("format");
  if (format == record.end() || *format != "raw") return;
  try {
    record = pixels->to_json(*pixels);
  } catch (const std::exception& e) {
    log::warning("DDS transport: an image of reply ", seq,
                 " could not be encoded as a PNG: ", e.what());
  }
}

}  // namespace

void DdsRequestManager::write_finished() {
  // a call's reports were delivered before its outcome: written first
  if (!progress_.empty()) write_progress();
  if (finished_.empty()) return;
  // swapped, not moved: both vectors keep their capacity
  draining_.swap(finished_);
  write_finished(draining_, false);
}

void DdsRequestManager::write_finished(std::vector<std::pair<RequestId, Outcome>>& batch,
                                       bool final_flush) {
  for (auto& [id, outcome] : batch) {
    auto p = pending_.find(id);
    if (p == pending_.end()) continue;
    Pending pending = p->second;
    pending_.erase(p);
    // its seq is free again once this, its final reply, is written
    auto c = clients_.find(pending.client);
    if (c != clients_.end()) {
      c->second.calls.erase(pending.seq);
      if (c->second.gone) {
        if (c->second.calls.empty()) forget_client(pending.client);
        continue;
      }
    }
    if (pending.cancel_answer) {
      // the answer to a cancel: whether the call was still running
      const bool found = outcome.value && outcome.value->is_boolean() && outcome.value->get<bool>();
      ReplyData answer;
      answer.seq = pending.seq;
      answer.result = found ? "true" : "false";
      if (!found) answer.message = "the call had already finished";
      send_reply(pending.client, std::move(answer), final_flush);
      continue;
    }
    // a completed call
    // a result with images: its text is written when it goes (prepare_images)
    std::shared_ptr<Outcome> images;
    if (!outcome.attachments.empty() && outcome.status == Status::success && outcome.value) {
      images = std::make_shared<Outcome>();
      images->value = std::move(outcome.value);
      images->attachments = std::move(outcome.attachments);
      outcome.value.reset();
    }
    ReplyData reply = to_reply(pending.seq, outcome);
    reply.images = std::move(images);
    send_reply(pending.client, std::move(reply), final_flush);
  }
  batch.clear();
}

void DdsRequestManager::write_progress() {
  for (auto& [id, value] : progress_) {
    auto p = pending_.find(id);
    if (p == pending_.end() || p->second.cancel_answer) continue;
    auto c = clients_.find(p->second.client);
    if (c == clients_.end() || c->second.gone || c->second.progress_writer <= 0) continue;
    progress_text_ = value.dump(-1, ' ', false, json::error_handler_t::replace);
    simgate_Reply sample{};
    std::memcpy(sample.client, p->second.client.data(), p->second.client.size());
    sample.seq = p->second.seq;
    sample.status = simgate_ST_RUNNING;
    sample.failure = simgate_FL_NONE;
    sample.last = false;
    sample.result = progress_text_.data();
    sample.message = const_cast<char*>("");
    sample.data = const_cast<char*>("");
    // best effort: a report that cannot go now is lost, as the client may lose any
    if (dds_return_t rc = dds_write(c->second.progress_writer, &sample); rc < 0)
      log::debug("DDS transport: a progress report of request ", sample.seq, " to client ",
                 to_hex(p->second.client), " not written: ", retcode_text(rc));
  }
  progress_.clear();
}

bool DdsRequestManager::send_images(const ClientId& id, ClientState& client, ReplyData& reply) {
  if (client.image_writer <= 0 || !announced_reader_matched(client.image_writer, id)) return true;
  Outcome& outcome = *reply.images;
  std::vector<json*> records = image_records(*outcome.value);
  if (records.size() != outcome.attachments.size()) return true;
  for (; reply.images_done < records.size(); ++reply.images_done) {
    const StreamPayload* pixels = outcome.attachments[reply.images_done].get();
    json& record = *records[reply.images_done];
    if (!pixels || pixels->content != "image" || !record.is_object()) continue;
    const json& d = pixels->description;
    dds_return_t rc;
    try {
      rc = write_image_payload(client.image_writer, d.value("component", std::string()), reply.seq,
                               d.value("timestamp", 0.0), *pixels);
    } catch (const std::exception& e) {
      log::warning("DDS transport: an image of reply ", reply.seq, " to client ", to_hex(id),
                   " not written: ", e.what());
      with_png(record, pixels, reply.seq);
      continue;
    }
    // its writer full (the images before it not acknowledged yet): this one and the rest later
    if (rc == DDS_RETCODE_TIMEOUT) return false;
    if (rc < 0) {
      log::warning("DDS transport: an image of reply ", reply.seq, " to client ", to_hex(id),
                   " stays a PNG: ", retcode_text(rc));
      with_png(record, pixels, reply.seq);
      continue;
    }
    record.erase("image");
    record["format"] = "raw";
  }
  return true;
}

bool DdsRequestManager::prepare_images(const ClientId& id, ClientState& client, ReplyData& reply,
                                       bool give_up) {
  if (!reply.images) return true;
  // images raw on the client's image topic, when it reads it; else (or given up) the PNGs stay
  if (!give_up && !send_images(id, client, reply)) return false;
  // the images not written raw: PNGs in their records (made now where the service left them out)
  Outcome& outcome = *reply.images;
  std::vector<json*> records = image_records(*outcome.value);
  if (records.size() == outcome.attachments.size())
    for (std::size_t i = reply.images_done; i < records.size(); ++i)
      with_png(*records[i], outcome.attachments[i].get(), reply.seq);
  reply.result = reply.images->value->dump(-1, ' ', false, json::error_handler_t::replace);
  reply.images.reset();
  return true;
}

bool DdsRequestManager::takes_images_raw(const ClientId& id, ClientState& client) {
  if (client.image_writer <= 0) return false;
  // asked at every call: the matched readers' QoS are read again only when the set of
  // matches changed (a match moves the total, an unmatch the current count)
  dds_publication_matched_status_t status{};
  if (dds_get_publication_matched_status(client.image_writer, &status) < 0) return false;
  if (status.total_count != client.image_matches_total ||
      status.current_count != client.image_matches_current) {
    client.image_matches_total = status.total_count;
    client.image_matches_current = status.current_count;
    client.images_raw =
        status.current_count > 0 && announced_reader_matched(client.image_writer, id);
  }
  return client.images_raw;
}

bool DdsRequestManager::announced_reader_matched(dds_entity_t writer, const ClientId& id) {
  dds_publication_matched_status_t status{};
  if (dds_get_publication_matched_status(writer, &status) < 0 || status.current_count == 0)
    return false;
  // a reader in the client's partition that announces its id: one that does not (or an
  // eavesdropper's, see docs) does not count
  std::vector<dds_instance_handle_t> handles(status.current_count + 4);
  dds_return_t n = dds_get_matched_subscriptions(writer, handles.data(), handles.size());
  for (dds_return_t i = 0; i < std::min<dds_return_t>(n, static_cast<dds_return_t>(handles.size()));
       ++i) {
    if (dds_builtintopic_endpoint_t* ep = dds_get_matched_subscription_data(writer, handles[i])) {
      const bool announced = client_id_from_userdata(ep->qos) == id;
      dds_builtintopic_free_endpoint(ep);
      if (announced) return true;
    }
  }
  return false;
}

bool DdsRequestManager::ensure_progress_writer(const ClientId& id, ClientState& client) {
  if (client.progress_writer > 0) return true;
  if (client.progress_writer < 0) return false;  // failed before: not tried for every call
  client.progress_writer =
      dds_create_writer(client.reply_publisher, progress_topic_, progress_qos_.get(), nullptr);
  if (client.progress_writer < 0) {
    log::error(
        "DDS transport: client ", to_hex(id),
        " gets no progress reports: no progress writer: ", retcode_text(client.progress_writer));
    return false;
  }
  return true;
}

void DdsRequestManager::send_reply(const ClientId& client_id, ReplyData reply, bool final_flush) {
  auto c = clients_.find(client_id);
  if (c == clients_.end() || c->second.gone) {
    log::debug("DDS transport: reply ", reply.seq, " to client ", to_hex(client_id),
               " dropped: the client left");
    return;
  }
  ClientState& client = c->second;
  // at stop(): one attempt, nothing parked (the PNGs stay, or are made)
  if (final_flush) {
    prepare_images(client_id, client, reply, true);
    write_reply(client_id, client, reply);
    return;
  }
  // written at once when its reader is matched and nothing waits before it
  if (client.parked.empty() && client.reader_matched) {
    const bool images_ready = prepare_images(client_id, client, reply, false);
    if (images_ready && write_reply(client_id, client, reply) != DDS_RETCODE_TIMEOUT) return;
    // its writer (or its image writer) is full: the reader has not acknowledged what came
    // before; retried with backoff
    client.stalled = true;
    client.images_stalled = !images_ready;
    client.retry_delay = k_min_retry_delay;
    client.retry_at = std::chrono::steady_clock::now() + client.retry_delay;
    log::debug("DDS transport: the reply writer of client ", to_hex(client_id), " is full; reply ",
               reply.seq, " parked");
  } else if (!client.reader_matched) {
    log::debug("DDS transport: reply ", reply.seq, " to client ", to_hex(client_id),
               " parked until its reply reader matches");
  }
  // otherwise parked behind the others (bounded in count and time)
  const auto deadline = std::chrono::steady_clock::now() + options_.park_timeout;
  if (reply.seq_end != 0 && !client.parked.empty()) {
    // an Overloaded refusal right after another's run (the next seq): the run grows by one
    ReplyData& back = client.parked.back();
    if (back.seq_end != 0 && back.seq_end + 1 == reply.seq) {
      back.seq_end = reply.seq;
      back.deadline = deadline;
      return;
    }
  }
  // (with max_in_flight at most max_samples / 3, a client whose seqs follow one another
  // never gets here: its parked finals, acknowledgements and runs of refusals stay below)
  if (client.parked.size() >= static_cast<std::size_t>(options_.max_samples)) {
    drop_reply(client_id, client, reply);
    return;
  }
  reply.deadline = deadline;
  client.parked_finals += counted(reply);
  client.parked.push_back(std::move(reply));
  ++parked_count_;
}

dds_return_t DdsRequestManager::write_reply(const ClientId& client_id, const ClientState& client,
                                            ReplyData& reply) {
  simgate_Reply sample{};
  std::memcpy(sample.client, client_id.data(), client_id.size());
  sample.seq = reply.seq;
  sample.status = reply.status;
  sample.failure = reply.failure;
  sample.last = reply.last;
  sample.result = const_cast<char*>(reply.result.c_str());
  sample.message = const_cast<char*>(reply.message.c_str());
  sample.data = const_cast<char*>(reply.data.c_str());
  dds_return_t rc = dds_write(client.reply_writer, &sample);
  // a run of Overloaded refusals: one sample per seq, as far as the writer takes them
  while (rc >= 0 && reply.seq_end > reply.seq) {
    sample.seq = ++reply.seq;
    rc = dds_write(client.reply_writer, &sample);
  }
  if (rc < 0 && rc != DDS_RETCODE_TIMEOUT)
    log::warning("DDS transport: reply ", reply.seq, " to client ", to_hex(client_id),
                 " not written: ", retcode_text(rc));
  return rc;
}

void DdsRequestManager::drop_reply(const ClientId& client_id, ClientState& client,
                                   const ReplyData& reply) {
  // one line at once, then at most one per interval with the count: a client that never
  // reads must not flood the log either
  client.dropped += reply.seq_end > reply.seq ? reply.seq_end - reply.seq + 1 : 1;
  auto now = std::chrono::steady_clock::now();
  if (client.logged_at != std::chrono::steady_clock::time_point{} &&
      now - client.logged_at < k_drop_log_interval)
    return;
  if (client.stalled)
    log::warning("DDS transport: client ", to_hex(client_id),
                 " does not take its replies (its reply reader acknowledges nothing): ",
                 client.dropped, " reply(ies) dropped, the latest to request ", reply.seq,
                 "; other clients are not held up");
  else
    log::warning("DDS transport: client ", to_hex(client_id),
                 " has no reply reader matched: ", client.dropped,
                 " reply(ies) dropped, the latest to request ", reply.seq);
  client.logged_at = now;
  client.dropped = 0;
}

void DdsRequestManager::flush_parked(const ClientId& id, ClientState& client,
                                     std::chrono::steady_clock::time_point now) {
  while (!client.parked.empty()) {
    ReplyData& reply = client.parked.front();
    const bool expired = parked_expiry(client, reply) <= now;
    const std::uint64_t first_seq = reply.seq;  // a run of refusals advances as it is written
    // waiting for its reader (after park_timeout_ms it is written anyway, for readers that
    // do not announce simgate.id), or for its writer to have room again; one whose images
    // waited in vain goes with their PNGs at its deadline, not at the next retry of a backoff
    // that may end after it (it was dropped then)
    const bool images_given_up = expired && client.images_stalled;
    bool attempt = (client.reader_matched || expired) &&
                   (images_given_up || !(client.stalled && now < client.retry_at));
    if (attempt) {
      // (past its deadline, the images left go as PNGs in the reply)
      const bool images_ready = prepare_images(id, client, reply, expired);
      const dds_return_t rc = images_ready ? write_reply(id, client, reply) : DDS_RETCODE_TIMEOUT;
      const bool was_images = std::exchange(client.images_stalled, !images_ready);
      if (rc != DDS_RETCODE_TIMEOUT || reply.seq != first_seq) client.progressed_at = now;
      if (rc != DDS_RETCODE_TIMEOUT) {
        if (client.stalled && (was_images && client.dropped == 0)) {
          // only its image writer was full a moment: nothing to report
          client.stalled = false;
        } else if (client.stalled) {
          // (with the drops not reported yet)
          log::info("DDS transport: client ", to_hex(id), " takes its replies again",
                    client.dropped > 0
                        ? "; reply(ies) dropped meanwhile: " + std::to_string(client.dropped)
                        : "");
          client.stalled = false;
          client.dropped = 0;
        }
      } else {
        // full again: the backoff doubles only while the reader takes nothing; one that
        // took some of what was written (a client reading thousands of replies at once)
        // is retried soon, or its writer would idle most of the time and its replies expire
        client.stalled = true;
        client.retry_delay =
            client.progressed_at == now
                ? k_min_retry_delay
                : std::min(std::max(client.retry_delay * 2, k_min_retry_delay), k_max_retry_delay);
        client.retry_at = now + client.retry_delay;
        attempt = false;
      }
    }
    if (!attempt) {
      if (!expired) return;
      drop_reply(id, client, reply);  // waited park_timeout_ms for room (or a reader) in vain
    }
    client.parked_finals -= counted(client.parked.front());
    client.parked.pop_front();
    --parked_count_;
  }
}

std::chrono::steady_clock::time_point DdsRequestManager::flush_all_parked() {
  auto now = std::chrono::steady_clock::now();
  auto next = std::chrono::steady_clock::time_point::max();
  for (auto& [id, client] : clients_) {
    if (client.parked.empty()) continue;
    flush_parked(id, client, now);
    if (client.parked.empty()) continue;
    // what it waits for: its writer's next attempt, or its oldest reply's deadline
    next = std::min(next, parked_expiry(client, client.parked.front()));
    if (client.stalled && client.reader_matched) next = std::min(next, client.retry_at);
  }
  return next;
}

void DdsRequestManager::refresh_reader_match(const ClientId& id, ClientState& client) {
  // reading the status resets it (the waitset trigger)
  const bool matched = announced_reader_matched(client.reply_writer, id);
  client.reader_matched = matched;
  // what was parked for it goes now
  if (matched && !client.parked.empty()) flush_parked(id, client, std::chrono::steady_clock::now());
}

void DdsRequestManager::sweep_clients() {
  // the request writers matched now
  std::vector<dds_instance_handle_t> handles(writers_.size() + 16);
  dds_return_t n;
  while ((n = dds_get_matched_publications(request_reader_, handles.data(), handles.size())) >
         static_cast<dds_return_t>(handles.size()))
    handles.resize(static_cast<std::size_t>(n) + 16);
  if (n < 0) {
    log::error("DDS transport: matched request writers unknown: ", retcode_text(n));
    return;
  }
  dds_subscription_matched_status_t status;
  dds_get_subscription_matched_status(request_reader_, &status);  // resets the trigger
  client_count_.store(static_cast<std::size_t>(n), std::memory_order_relaxed);
  std::set<dds_instance_handle_t> live(handles.begin(), handles.begin() + n);
  // new writers are new clients
  for (dds_instance_handle_t writer : live)
    if (!writers_.count(writer)) add_client(writer);
  // every client whose writer left is gone
  std::vector<ClientId> gone;
  for (const auto& [id, client] : clients_)
    if (!client.gone && !live.count(client.writer)) gone.push_back(id);
  for (const ClientId& id : gone) client_gone(id, clients_.at(id));
  // their cancels, here if the simulation lock is free
  run_batch();
}

void DdsRequestManager::add_client(dds_instance_handle_t writer) {
  // its id: its request writer's GUID
  dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(request_reader_, writer);
  if (!ep) return;  // already left
  const ClientId id = to_client_id(ep->key);
  dds_builtintopic_free_endpoint(ep);
  if (clients_.count(id)) return;
  // its reply writer, alone in its partition
  const std::string partition = options_.partition + "/" + to_hex(id);
  QosPtr qos(dds_create_qos());
  dds_qset_partition1(qos.get(), partition.c_str());
  dds_entity_t publisher = dds_create_publisher(participant_->handle(), qos.get(), nullptr);
  dds_entity_t reply_writer =
      publisher < 0 ? publisher
                    : dds_create_writer(publisher, reply_topic_, reply_qos_.get(), nullptr);
  if (reply_writer < 0 || dds_set_status_mask(reply_writer, DDS_PUBLICATION_MATCHED_STATUS) < 0 ||
      dds_waitset_attach(waitset_, reply_writer, static_cast<dds_attach_t>(reply_writer)) < 0) {
    log::error("DDS transport: client ", to_hex(id),
               " cannot be served: no reply writer in partition '", partition,
               "': ", retcode_text(reply_writer < 0 ? reply_writer : DDS_RETCODE_ERROR));
    if (publisher > 0) dds_delete(publisher);
    return;
  }
  ClientState& client = clients_[id];
  client_arrived(client_number(id));
  client.writer = writer;
  client.reply_publisher = publisher;
  client.reply_writer = reply_writer;
  // its images' writer (deleted with the publisher); without it its replies keep their PNGs
  client.image_writer = dds_create_writer(publisher, image_topic_, image_qos_.get(), nullptr);
  if (client.image_writer < 0)
    log::warning(
        "DDS transport: client ", to_hex(id),
        " gets its images as PNGs only: no image writer: ", retcode_text(client.image_writer));
  writers_[writer] = id;
  reply_writers_[reply_writer] = id;
  log::debug("DDS transport: client ", to_hex(id), " appeared (", clients_.size(), " known)");
  refresh_reader_match(id, client);
}

void DdsRequestManager::client_gone(const ClientId& id, ClientState& client) {
  client.gone = true;
  client_left(client_number(id));
  parked_count_ -= client.parked.size();
  client.parked.clear();
  client.parked_finals = 0;
  // its async calls are cancelled (on_disconnect "cancel", or run on: "let_run"); sync ones
  // finish; the replies of all are dropped
  std::size_t cancelled = 0;
  for (const auto& [seq, request] : client.calls) {
    auto p = pending_.find(request);
    if (options_.cancel_on_disconnect && p != pending_.end() && p->second.is_async) {
      cancel(request);
      ++cancelled;
    }
  }
  if (cancelled > 0) run_pending_ = true;
  log::info("DDS transport: client ", to_hex(id), " disappeared; ", cancelled,
            " async call(s) cancelled",
            options_.cancel_on_disconnect ? "" : " (on_disconnect: let_run)");
  if (client.calls.empty()) forget_client(id);
}

void DdsRequestManager::forget_client(const ClientId& id) {
  auto c = clients_.find(id);
  if (c == clients_.end()) return;
  // its publisher and reply writer go with it
  if (c->second.reply_publisher > 0)
    retire(c->second.reply_publisher, c->second.reply_writer,
           std::max<dds_entity_t>(c->second.image_writer, 0));
  writers_.erase(c->second.writer);
  reply_writers_.erase(c->second.reply_writer);
  clients_.erase(c);
  log::debug("DDS transport: client ", to_hex(id), " forgotten (", clients_.size(), " known)");
}

void DdsRequestManager::retire(dds_entity_t publisher, dds_entity_t writer,
                               dds_entity_t image_writer) {
  dds_waitset_detach(waitset_, writer);
  // all acknowledged (or no reader left), replies and images: deleted at once, without lingering
  const Retiring entry{publisher, writer, image_writer};
  auto acknowledged = [](const Retiring& e) {
    return dds_wait_for_acks(e.writer, 0) == DDS_RETCODE_OK &&
           (e.image_writer <= 0 || dds_wait_for_acks(e.image_writer, 0) == DDS_RETCODE_OK);
  };
  if (acknowledged(entry)) {
    dds_delete(publisher);
    return;
  }
  log::debug(
      "DDS transport: a reply writer with unacknowledged replies (or images) is deleted once they "
      "are "
      "acknowledged or their reader left");
  retiring_.push_back(entry);
}

void DdsRequestManager::retire_pending() {
  std::erase_if(retiring_, [](const Retiring& e) {
    if (dds_wait_for_acks(e.writer, 0) != DDS_RETCODE_OK) return false;
    if (e.image_writer > 0 && dds_wait_for_acks(e.image_writer, 0) != DDS_RETCODE_OK) return false;
    dds_delete(e.publisher);
    return true;
  });
}

}  // namespace simgate::dds
