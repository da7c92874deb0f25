#include "simgate/mcap/writer.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <lz4frame.h>
#include <zstd.h>

#include "format.h"

namespace simgate::mcap {

namespace {

using namespace format;  // the magic, the opcodes, crc32_of

void u16(std::string& out, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}
void u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}
void u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}
// A String: u32 length, bytes.
void str(std::string& out, std::string_view s) {
  u32(out, static_cast<std::uint32_t>(s.size()));
  out += s;
}
void map(std::string& out, const Metadata& m) {
  std::string entries;
  for (const auto& [key, value] : m) {
    str(entries, key);
    str(entries, value);
  }
  u32(out, static_cast<std::uint32_t>(entries.size()));
  out += entries;
}
// A record: opcode, u64 length, content.
std::string record(Op op, std::string_view content) {
  std::string out;
  out.reserve(9 + content.size());
  out.push_back(static_cast<char>(op));
  u64(out, content.size());
  out += content;
  return out;
}

std::string compress(Compression c, const std::string& data) {
  if (c == Compression::zstd) {
    std::string out(ZSTD_compressBound(data.size()), '\0');
    const std::size_t n = ZSTD_compress(out.data(), out.size(), data.data(), data.size(), 1);
    if (ZSTD_isError(n))
      throw std::runtime_error(std::string("MCAP: zstd could not compress a chunk: ") +
                               ZSTD_getErrorName(n));
    out.resize(n);
    return out;
  }
  if (c == Compression::lz4) {
    std::string out(LZ4F_compressFrameBound(data.size(), nullptr), '\0');
    const std::size_t n =
        LZ4F_compressFrame(out.data(), out.size(), data.data(), data.size(), nullptr);
    if (LZ4F_isError(n))
      throw std::runtime_error(std::string("MCAP: lz4 could not compress a chunk: ") +
                               LZ4F_getErrorName(n));
    out.resize(n);
    return out;
  }
  return data;
}

}  // namespace

std::string_view compression_name(Compression compression) {
  switch (compression) {
    case Compression::zstd: return "zstd";
    case Compression::lz4: return "lz4";
    case Compression::none: return "";
  }
  return "";
}

Writer::Writer(const std::string& path, WriterOptions options)
    : path_(path), options_(std::move(options)) {
  file_ = std::fopen(path.c_str(), "wb");
  if (!file_)
    throw std::runtime_error("MCAP: cannot create '" + path + "': " + std::strerror(errno));
  emit(k_magic);
  std::string h;
  str(h, options_.profile);
  str(h, options_.library);
  emit(record(header, h));
  flush_file();
}

Writer::~Writer() {
  try {
    close();
  } catch (...) {}
}

void Writer::flush_file() {
  if (std::fflush(file_) != 0 && error_.empty()) error_ = std::strerror(errno);
}

void Writer::emit(std::string_view bytes) {
  if (!error_.empty()) return;
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size())
    error_ = std::strerror(errno);
  data_crc_ = crc32_of(bytes, data_crc_);
  offset_ += bytes.size();
}

std::uint16_t Writer::add_schema(std::string_view name, std::string_view encoding,
                                 std::string_view data) {
  if (schemas_.size() >= 0xFFFE) throw std::length_error("MCAP: too many schemas");
  const auto id = static_cast<std::uint16_t>(schemas_.size() + 1);
  std::string c;
  u16(c, id);
  str(c, name);
  str(c, encoding);
  str(c, data);  // uint32 length-prefixed bytes
  schemas_.push_back({id, record(schema, c)});
  chunk_ += schemas_.back().record;
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, std::string_view topic,
                                  std::string_view message_encoding, const Metadata& metadata) {
  if (schema_id > schemas_.size())
    throw std::invalid_argument("MCAP: no schema " + std::to_string(schema_id));
  if (channels_.size() > 0xFFFF) throw std::length_error("MCAP: too many channels");
  const auto id = static_cast<std::uint16_t>(channels_.size());
  std::string c;
  u16(c, id);
  u16(c, schema_id);
  str(c, topic);
  str(c, message_encoding);
  map(c, metadata);
  channels_.push_back({id, record(channel, c)});
  channel_counts_.push_back(0);
  chunk_ += channels_.back().record;
  return id;
}

void Writer::write(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
                   std::uint64_t publish_time, std::string_view data) {
  if (channel_id >= channels_.size())
    throw std::invalid_argument("MCAP: no channel " + std::to_string(channel_id));
  chunk_index_[channel_id].emplace_back(log_time, chunk_.size());
  chunk_.push_back(static_cast<char>(message));
  u64(chunk_, 2 + 4 + 8 + 8 + data.size());
  u16(chunk_, channel_id);
  u32(chunk_, sequence);
  u64(chunk_, log_time);
  u64(chunk_, publish_time);
  chunk_ += data;
  chunk_start_ = chunk_has_messages_ ? std::min(chunk_start_, log_time) : log_time;
  chunk_end_ = chunk_has_messages_ ? std::max(chunk_end_, log_time) : log_time;
  message_start_ = message_count_ ? std::min(message_start_, log_time) : log_time;
  message_end_ = message_count_ ? std::max(message_end_, log_time) : log_time;
  chunk_has_messages_ = true;
  ++message_count_;
  ++channel_counts_[channel_id];
  if (chunk_.size() >= options_.chunk_bytes) flush_chunk();
}

void Writer::flush_chunk() {
  if (chunk_.empty()) return;
  const std::string records = compress(options_.compression, chunk_);
  std::string c;
  u64(c, chunk_has_messages_ ? chunk_start_ : 0);
  u64(c, chunk_has_messages_ ? chunk_end_ : 0);
  u64(c, chunk_.size());
  u32(c, crc32_of(chunk_));
  str(c, compression_name(options_.compression));
  u64(c, records.size());
  c += records;
  const std::uint64_t chunk_offset = offset_;
  const std::string chunk_record = record(chunk, c);
  emit(chunk_record);
  // one Message Index per channel with messages in the chunk
  std::string offsets;  // Map<uint16, uint64>
  const std::uint64_t indexes_start = offset_;
  for (const auto& [id, entries] : chunk_index_) {
    std::string m;
    u16(m, id);
    u32(m, static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, at] : entries) {
      u64(m, time);
      u64(m, at);
    }
    u16(offsets, id);
    u64(offsets, offset_);
    emit(record(message_index, m));
  }
  flush_file();  // the chunk and its indexes reach the OS: a kill -9 from now on keeps them
  std::string index;
  u64(index, chunk_has_messages_ ? chunk_start_ : 0);
  u64(index, chunk_has_messages_ ? chunk_end_ : 0);
  u64(index, chunk_offset);
  u64(index, chunk_record.size());
  u32(index, static_cast<std::uint32_t>(offsets.size()));
  index += offsets;
  u64(index, offset_ - indexes_start);
  str(index, compression_name(options_.compression));
  u64(index, records.size());
  u64(index, chunk_.size());
  chunk_indexes_ += record(chunk_index, index);
  ++chunk_count_;
  chunk_.clear();
  chunk_index_.clear();
  chunk_has_messages_ = false;
}

void Writer::attach(std::uint64_t log_time, std::uint64_t create_time, std::string_view name,
                    std::string_view media_type, std::string_view data) {
  flush_chunk();  // an attachment is never inside a chunk
  std::string c;
  u64(c, log_time);
  u64(c, create_time);
  str(c, name);
  str(c, media_type);
  u64(c, data.size());
  c += data;
  u32(c, crc32_of(c));
  const std::string r = record(attachment, c);
  std::string index;
  u64(index, offset_);
  u64(index, r.size());
  u64(index, log_time);
  u64(index, create_time);
  u64(index, data.size());
  str(index, name);
  str(index, media_type);
  attachment_indexes_ += record(attachment_index, index);
  ++attachment_count_;
  emit(r);
  flush_file();
}

void Writer::add_metadata(std::string_view name, const Metadata& metadata) {
  flush_chunk();
  std::string c;
  str(c, name);
  map(c, metadata);
  const std::string r = record(Op::metadata, c);
  std::string index;
  u64(index, offset_);
  u64(index, r.size());
  str(index, name);
  metadata_indexes_ += record(metadata_index, index);
  ++metadata_count_;
  emit(r);
  flush_file();
}

void Writer::close() {
  if (closed_) return;
  closed_ = true;
  flush_chunk();
  std::string end;
  u32(end, data_crc_);
  emit(record(data_end, end));

  // the summary: one group per record kind, each located by a Summary Offset
  const std::uint64_t summary_start = offset_;
  std::string summary, offsets;
  const auto group = [&](Op op, const std::string& records) {
    if (records.empty()) return;
    std::string o;
    o.push_back(static_cast<char>(op));
    u64(o, summary_start + summary.size());
    u64(o, records.size());
    offsets += record(summary_offset, o);
    summary += records;
  };
  std::string all;
  for (const auto& s : schemas_) all += s.record;
  group(schema, all);
  all.clear();
  for (const auto& c : channels_) all += c.record;
  group(channel, all);
  group(chunk_index, chunk_indexes_);
  group(attachment_index, attachment_indexes_);
  group(metadata_index, metadata_indexes_);
  std::string stats;
  u64(stats, message_count_);
  u16(stats, static_cast<std::uint16_t>(schemas_.size()));
  u32(stats, static_cast<std::uint32_t>(channels_.size()));
  u32(stats, attachment_count_);
  u32(stats, metadata_count_);
  u32(stats, chunk_count_);
  u64(stats, message_count_ ? message_start_ : 0);
  u64(stats, message_count_ ? message_end_ : 0);
  std::string counts;
  for (std::size_t id = 0; id < channel_counts_.size(); ++id) {
    u16(counts, static_cast<std::uint16_t>(id));
    u64(counts, channel_counts_[id]);
  }
  u32(stats, static_cast<std::uint32_t>(counts.size()));
  stats += counts;
  group(statistics, record(statistics, stats));
  const std::uint64_t summary_offset_start = summary_start + summary.size();
  summary += offsets;

  std::string f;
  f.push_back(static_cast<char>(footer));
  u64(f, 8 + 8 + 4);
  u64(f, summary.empty() ? 0 : summary_start);
  u64(f, offsets.empty() ? 0 : summary_offset_start);
  u32(f, crc32_of(f, crc32_of(summary)));
  emit(summary);
  emit(f);
  emit(k_magic);
  flush_file();
  if (std::fclose(file_) != 0 && error_.empty()) error_ = std::strerror(errno);
  file_ = nullptr;
  if (!error_.empty()) throw std::runtime_error("MCAP: writing '" + path_ + "' failed: " + error_);
}

}  // namespace simgate::mcap
