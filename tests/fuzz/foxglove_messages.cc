// Fuzz target foxglove_messages: what a Foxglove client's messages go through
// (protocols/foxglove: read_text for text messages, read_binary for binary ones), then the
// server's answers built from what was read (status, serviceCallFailure). The first byte
// says which kind the rest is (even: text, odd: binary), as the WebSocket frame would.
//
// Also read_command on a client message's payload (a command for a velocity stream).
//
// Properties: nothing throws; a refusal has a reason, and the status message carrying it is
// JSON without a control character of the client's; a subscribe read has as many entries as
// the message's "subscriptions" array, with the ids and channels nlohmann reads there; a
// service call request's encoding and payload are the message's bytes after its 13-byte
// head, in order, all of them; a client message's payload is the bytes after its 5-byte head;
// a playback control request's id is a view of its bytes after the 19-byte head, echoed by
// the playback state that answers it.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_support.h"
#include "simgate/foxglove/protocol.h"

namespace simgate::fuzz {
namespace {

void check_refusal(const foxglove::Malformed& m) {
  FUZZ_CHECK(!m.reason.empty(), "a refusal says why");
  const std::string text = foxglove::status(foxglove::Level::error, m.reason);
  const json parsed = json::parse(text, nullptr, false);
  FUZZ_CHECK(!parsed.is_discarded() && parsed["op"] == "status", "the status message is JSON");
  for (char c : parsed["message"].get<std::string>())
    FUZZ_CHECK(static_cast<unsigned char>(c) >= 0x20 && c != 0x7f,
               "no control character of the client's reaches its status message");
}

void text(std::string_view message) {
  const foxglove::ClientText read = foxglove::read_text(message);
  if (const auto* m = std::get_if<foxglove::Malformed>(&read)) return check_refusal(*m);
  const json parsed = json::parse(message, nullptr, false);
  FUZZ_CHECK(parsed.is_object() && parsed["op"].is_string(),
             "what was read is an object with an op");
  if (const auto* s = std::get_if<foxglove::Subscribe>(&read)) {
    const json& list = parsed["subscriptions"];
    FUZZ_CHECK(list.size() == s->subscriptions.size(), "every subscription is read");
    for (std::size_t i = 0; i < list.size(); ++i) {
      FUZZ_CHECK(list[i]["id"].get<std::uint64_t>() == s->subscriptions[i].first, "the id read");
      FUZZ_CHECK(list[i]["channelId"].get<std::uint64_t>() == s->subscriptions[i].second,
                 "the channel read");
    }
  } else if (const auto* u = std::get_if<foxglove::Unsubscribe>(&read)) {
    FUZZ_CHECK(parsed["subscriptionIds"].size() == u->subscription_ids.size(),
               "every subscription id is read");
  } else if (const auto* a = std::get_if<foxglove::ClientAdvertise>(&read)) {
    const json& list = parsed["channels"];
    FUZZ_CHECK(list.size() == a->channels.size(), "every client channel is read");
    for (std::size_t i = 0; i < list.size(); ++i) {
      FUZZ_CHECK(list[i]["id"].get<std::uint64_t>() == a->channels[i].id, "its id");
      FUZZ_CHECK(list[i]["topic"].get<std::string>() == a->channels[i].topic, "its topic");
    }
  } else if (const auto* ua = std::get_if<foxglove::ClientUnadvertise>(&read)) {
    FUZZ_CHECK(parsed["channelIds"].size() == ua->channel_ids.size(), "every channel id is read");
  } else if (const auto* set = std::get_if<foxglove::SetParameters>(&read)) {
    FUZZ_CHECK(parsed["parameters"].size() == set->parameters.size(), "every parameter is read");
    const json values = json::parse(foxglove::parameter_values(set->parameters, set->id));
    FUZZ_CHECK(values["parameters"].size() == set->parameters.size(), "and written back");
  } else if (std::holds_alternative<foxglove::GetParameters>(read) ||
             std::holds_alternative<foxglove::SubscribeParameterUpdates>(read) ||
             std::holds_alternative<foxglove::UnsubscribeParameterUpdates>(read)) {
    FUZZ_CHECK(parsed["op"].get<std::string>().find("arameter") != std::string::npos,
               "a parameters op");
  } else {
    const auto& other = std::get<foxglove::OtherOp>(read);
    FUZZ_CHECK(other.op == parsed["op"].get<std::string>(), "the op is the message's");
    for (const char* served :
         {"subscribe", "unsubscribe", "advertise", "unadvertise", "getParameters", "setParameters",
          "subscribeParameterUpdates", "unsubscribeParameterUpdates"})
      FUZZ_CHECK(other.op != served, "the ops served are read");
  }
}

void binary(std::string_view message) {
  const foxglove::ClientBinary read = foxglove::read_binary(message);
  if (const auto* m = std::get_if<foxglove::Malformed>(&read)) return check_refusal(*m);
  if (const auto* call = std::get_if<foxglove::ServiceCallRequest>(&read)) {
    FUZZ_CHECK(message[0] == 2, "a service call request has opcode 2");
    FUZZ_CHECK(call->encoding.data() == message.data() + 13, "the encoding follows the head");
    FUZZ_CHECK(call->payload.data() == call->encoding.data() + call->encoding.size(),
               "the payload follows the encoding");
    FUZZ_CHECK(13 + call->encoding.size() + call->payload.size() == message.size(),
               "the payload runs to the message's end");
    const json failure =
        json::parse(foxglove::service_call_failure(call->service_id, call->call_id, call->encoding),
                    nullptr, false);
    FUZZ_CHECK(!failure.is_discarded(), "a failure naming the encoding is JSON");
  } else if (const auto* playback = std::get_if<foxglove::PlaybackControlRequest>(&read)) {
    FUZZ_CHECK(message[0] == 3, "a playback control request has opcode 3");
    FUZZ_CHECK(playback->request_id.data() == message.data() + 19,
               "the request id follows the 19-byte head");
    FUZZ_CHECK(19 + playback->request_id.size() <= message.size(), "within the message");
    FUZZ_CHECK(playback->seek_ns.has_value() == (message[6] != 0), "a seek when it says so");
    // the state answering it echoes its id after a 19-byte head
    const std::string state = foxglove::playback_state(
        foxglove::PlaybackStatus::paused, 0, playback->speed, false, playback->request_id);
    FUZZ_CHECK(state.size() == 19 + playback->request_id.size() &&
                   state.substr(19) == playback->request_id,
               "the playback state carries the request's id");
  } else {
    const auto& data = std::get<foxglove::ClientMessageData>(read);
    FUZZ_CHECK(message[0] == 1, "client message data has opcode 1");
    FUZZ_CHECK(
        data.payload.size() + 5 == message.size() && data.payload.data() == message.data() + 5,
        "the payload is what follows the 5-byte head");
    // as a velocity command: an object, or nothing
    const auto command = foxglove::read_command(data.payload, {"v", "w"});
    FUZZ_CHECK(!command || command->is_object(), "a command read is an object");
  }
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string_view message(reinterpret_cast<const char*>(data + 1), size - 1);
  if (data[0] % 2 == 0)
    simgate::fuzz::text(message);
  else
    simgate::fuzz::binary(message);
  return 0;
}
