// simgate/dds streams — the simulation's data streams as DDS topics (issue #21): each output
// stream the DDS transport carries is written on a topic of its own, typed by its kind
// (simgate_streams.idl: Pose, Odometry, Imu, JointState, LaserScan; JsonSample for any other
// kind); each input stream is read from a JsonCommand topic (and a typed Velocity topic for
// kind "velocity") and its commands handed to the StreamHub; a transient-local catalog,
// simgate_Streams, names every topic with its component, kind, type and frequency.
//
// Terms:
//  - topic path: "simgate/" + the component's name with '.' as '/' (topic_path()).
//  - output: one StreamSubscription to the hub (a few samples deep) and one writer, best
//    effort, keep-last 1, volatile: a reader that falls behind loses samples and slows down
//    nobody; the subscription's queue is latest-N too, so the DDS thread never slows the
//    simulation either.
//  - direct output: a small fixed-size typed sample (pose, odometry, imu) is written by the
//    simulation thread the moment it is made (a direct subscriber, SubscriberOptions::deliver):
//    a best-effort write of a few dozen bytes never waits for a reader, and skipping the
//    queue and the DDS thread's wake-up is what lets a stream keep up with a raw Cyclone
//    writer (docs/performance.md, "Data streams"). Option "stream_writes": "thread" turns it off.
//  - input: readers reliable, keep-last 1, volatile (Cyclone holds at most one command per
//    reader, the latest); a command goes to StreamHub::publish (applied at once when the
//    simulation lock is free, else the latest waits for the next turn; refusals are counted
//    and logged by the hub). A JsonCommand's text is bounded as a request's params are, by
//    the transport's max_params (bytes) and max_depth (nesting), both checked before it is
//    parsed (issue #35: a 20 MB command was parsed, 0.5 GB at its peak): beyond, it is
//    refused, counted by the hub as a refused command of its stream (note_refused) and
//    logged once per reader.
//
// Life cycle: the DdsRequestManager creates it in start() (host thread, once the hub is set),
// before the DDS thread runs; sync() on the DDS thread creates the endpoints of the streams
// the hub lists, and later those of streams that came and goes those of streams that went
// (a component deleted at run time: its writer or readers are deleted, its catalog entries
// disposed). Destroyed after the DDS thread has been joined: it unsubscribes; its entities
// go with the participant.
//
// Threads: everything on the DDS thread, except the subscriptions' wake (the simulation
// thread, under its lock), which only raises a guard condition of the DDS thread's waitset.
#ifndef SIMGATE_PLUGINS_DDS_DDS_STREAMS_H_
#define SIMGATE_PLUGINS_DDS_DDS_STREAMS_H_

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <dds/dds.h>

#include "simgate/core/streams.h"

namespace simgate::dds {

inline constexpr const char* k_streams_topic = "simgate_Streams";

// "rover.pose" -> "simgate/rover/pose", a world's "w1/rover.pose" -> "simgate/w1/rover/pose"
// (DDS topic names take letters, digits, '_' and '/').
std::string topic_path(std::string_view component);

// Writes an image payload (StreamPayload content "image": its pixels raw and their
// description) as a simgate::stream::Image with `component`, `seq` and `time`, on `writer`
// (of that type): a stream sample, or a reply's image (simgate_ReplyImage). Throws
// std::invalid_argument when the payload is no image of that shape; else dds_write's code.
dds_return_t write_image_payload(dds_entity_t writer, const std::string& component,
                                 std::uint64_t seq, double time, const StreamPayload& payload);

class DdsStreams {
 public:
  // Waitset tokens (see DdsRequestManager::run): samples are waiting; commands are waiting.
  static constexpr dds_attach_t k_token_samples = -4;
  static constexpr dds_attach_t k_token_commands = -5;
  // the match of a pushed stream's writer changed (a reader came or went)
  static constexpr dds_attach_t k_token_matched = -6;

  // Host thread, before the DDS thread starts: creates the catalog writer and the guard
  // condition, attached to `waitset`. Throws std::runtime_error when DDS fails.
  // `max_command_bytes`, `max_command_depth`: the longest JsonCommand text, in bytes, and its
  // deepest [/{ nesting, accepted (the transport's max_params and max_depth).
  DdsStreams(std::shared_ptr<StreamDirectory> hub, std::string transport, dds_entity_t participant,
             dds_entity_t publisher, dds_entity_t subscriber, dds_entity_t waitset,
             std::string server_id, bool direct_writes, std::size_t max_command_bytes,
             std::size_t max_command_depth);
  ~DdsStreams();
  DdsStreams(const DdsStreams&) = delete;
  DdsStreams& operator=(const DdsStreams&) = delete;

  // ---- DDS thread ----
  // Endpoints for the streams the hub lists now; those of streams it no longer lists go.
  void sync();
  // Writes the samples queued by every subscription; ends those whose stream closed.
  void write_samples();
  // Takes the commands of every input reader and publishes them to the hub.
  void take_commands();
  // Pushed streams (a camera's: it renders only while subscribed): subscribes to those whose
  // writer has a matched reader now, unsubscribes from those whose writer has none.
  void update_matches();

 private:
  struct Output;
  struct Input;

  dds_entity_t topic(const std::string& name, const dds_topic_descriptor_t* descriptor);
  void add_output(const StreamInfo& info);
  void add_input(const StreamInfo& info);
  void remove_output(Output& output);
  void subscribe_output(Output& output);
  void remove_input(Input& input);
  dds_entity_t add_reader(const std::string& name, const dds_topic_descriptor_t* descriptor);
  void write_entry(const StreamInfo& info, const std::string& topic, const char* type_name);
  void dispose_entry(const std::string& topic);
  // Takes what `reader` holds and publishes the commands of `input` (JSON or Velocity).
  void take(Input& input, dds_entity_t reader, bool typed);

  std::shared_ptr<StreamDirectory> hub_;
  const std::string transport_;  // our name in the configuration
  const dds_entity_t participant_;
  const dds_entity_t publisher_;         // in our partition
  const dds_entity_t subscriber_;        // in our partition
  const dds_entity_t waitset_;           // the DDS thread's
  const std::string server_id_;          // our participant GUID, hex (catalog entries)
  const bool direct_writes_;             // small typed samples written by the simulation thread
  const std::size_t max_command_bytes_;  // longest JsonCommand text accepted (max_params)
  const std::size_t max_command_depth_;  // deepest nesting of it accepted (max_depth)
  dds_entity_t guard_ = 0;               // samples are waiting (raised by the wake)
  dds_entity_t catalog_writer_ = 0;      // simgate_Streams
  std::map<std::string, dds_entity_t> topics_;              // by name: created once
  std::map<std::string, std::unique_ptr<Output>> outputs_;  // by component
  std::map<std::string, std::unique_ptr<Input>> inputs_;    // by component
  std::vector<SamplePtr> taken_;                            // write_samples' buffer
};

}  // namespace simgate::dds

#endif  // SIMGATE_PLUGINS_DDS_DDS_STREAMS_H_
