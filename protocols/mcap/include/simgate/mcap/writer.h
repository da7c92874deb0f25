// simgate/mcap/writer.h — an MCAP file writer (issue #39's flight recorder): the robotics
// recording format rosbag2, Foxglove and Lichtblick read. The contract is MCAP's public
// specification (foxglove/mcap website/docs/spec): magic, Header, the data section (Schema,
// Channel and Message records in Chunks, each chunk followed by one Message Index per channel
// in it; Attachments and Metadata between chunks), Data End, then the summary section (every
// Schema and Channel again, a Chunk Index per chunk, Attachment and Metadata Indexes,
// Statistics, a Summary Offset per group), the Footer and the magic again. Chunks are
// compressed with zstd or lz4 (Debian's libzstd and liblz4) or stored as they are; every CRC
// is written. So a reader can seek by time (the chunk indexes) and list what the file holds
// (the statistics) without reading it all.
//
// Crash safety: the Header, each chunk (with its message indexes), each attachment and each
// metadata record reach the OS as soon as they are written, so a recording killed half way
// (kill -9, a crash) leaves a file whose every record but the last, cut one is whole: Reader
// (reader.h) reads it up to there. Without Data End and the summary, readers that start from
// the footer (an indexed reader) refuse such a file.
//
// Memory: one chunk's records (chunk_bytes, 1 MiB by default, then compressed) and the
// summary's indexes (a few dozen bytes per chunk, attachment and metadata record).
//
// Threads: one writer, one thread at a time (the recorder's own).
#ifndef SIMGATE_MCAP_WRITER_H_
#define SIMGATE_MCAP_WRITER_H_

#include <cstdint>
#include <cstdio>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace simgate::mcap {

enum class Compression { none, zstd, lz4 };
// "" / "zstd" / "lz4", as the Chunk records name it.
std::string_view compression_name(Compression compression);

struct WriterOptions {
  std::string profile;              // Header's profile: "" (none), "ros2", ...
  std::string library = "simgate";  // Header's library: who wrote the file
  Compression compression = Compression::zstd;
  std::size_t chunk_bytes = 1 << 20;  // uncompressed records past which a chunk is written
};

using Metadata = std::map<std::string, std::string>;

class Writer {
 public:
  // Creates (or truncates) `path` and writes the magic and the Header. Throws
  // std::runtime_error naming the file and the reason.
  Writer(const std::string& path, WriterOptions options);
  // Closes the file (close()) unless it was; errors are then swallowed (call close() to see
  // them).
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // A schema (its id, from 1) and a channel on it (its id, from 0; schema 0: none). Written
  // into the current chunk, before any message on them, and again in the summary.
  std::uint16_t add_schema(std::string_view name, std::string_view encoding, std::string_view data);
  std::uint16_t add_channel(std::uint16_t schema_id, std::string_view topic,
                            std::string_view message_encoding, const Metadata& metadata = {});
  // One message on `channel` (an id add_channel returned; std::invalid_argument otherwise),
  // times in nanoseconds.
  void write(std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
             std::uint64_t publish_time, std::string_view data);
  // An attachment (a file the recording carries: the config, a model) and a metadata record
  // (name -> key/value pairs): between chunks, indexed in the summary.
  void attach(std::uint64_t log_time, std::uint64_t create_time, std::string_view name,
              std::string_view media_type, std::string_view data);
  void add_metadata(std::string_view name, const Metadata& metadata);
  // Writes the open chunk now (a smaller one: nothing when it holds nothing) with its message
  // indexes, and hands it to the OS: a writer killed afterwards leaves its messages readable.
  // A recorder calls it every second or so, which bounds what a crash can lose.
  void flush_chunk();
  // Writes the open chunk, Data End, the summary and the footer, and closes the file.
  // Throws std::runtime_error when a write failed. Idempotent.
  void close();

  // The first write error (a full disk: strerror's words), "" while every write succeeded;
  // once there is one, nothing more is written and close() throws it.
  const std::string& error() const { return error_; }
  std::uint64_t message_count() const { return message_count_; }
  std::uint64_t bytes_written() const { return offset_; }

 private:
  // Writes `bytes` to the file (and into the data section's CRC while it runs).
  void emit(std::string_view bytes);
  // Hands what emit() buffered to the OS (fflush): after the Header, each chunk with its
  // message indexes, each attachment and metadata record. A process killed (kill -9) later
  // leaves them in the file, which Reader reads up to there; a power cut may still lose them
  // (no fsync).
  void flush_file();

  std::string path_;
  WriterOptions options_;
  std::FILE* file_ = nullptr;
  std::uint64_t offset_ = 0;    // bytes written so far
  std::uint32_t data_crc_ = 0;  // of everything written before Data End
  bool closed_ = false;
  std::string error_;  // the first write error

  struct SchemaRecord {
    std::uint16_t id;
    std::string record;  // the whole record, as written
  };
  struct ChannelRecord {
    std::uint16_t id;
    std::string record;
  };
  std::vector<SchemaRecord> schemas_;
  std::vector<ChannelRecord> channels_;
  std::vector<std::uint64_t> channel_counts_;  // messages per channel

  // the open chunk: its records, times, and per channel the (log time, offset) of messages
  std::string chunk_;
  std::uint64_t chunk_start_ = 0, chunk_end_ = 0;
  bool chunk_has_messages_ = false;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;

  // the summary's indexes, as records
  std::string chunk_indexes_, attachment_indexes_, metadata_indexes_;
  std::uint32_t chunk_count_ = 0, attachment_count_ = 0, metadata_count_ = 0;
  std::uint64_t message_count_ = 0, message_start_ = 0, message_end_ = 0;
};

}  // namespace simgate::mcap

#endif  // SIMGATE_MCAP_WRITER_H_
