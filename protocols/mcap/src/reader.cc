#include "simgate/mcap/reader.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>
#include <sys/stat.h>

#include <lz4frame.h>
#include <zstd.h>

#include "format.h"

namespace simgate::mcap {

namespace {

// A field that runs past the end of its record (FieldReader's reads).
struct FieldOverrun {};

// The fields of one record's content, read in order (little-endian, as the specification
// serializes them). Every read throws FieldOverrun when the content ends first.
class FieldReader {
 public:
  explicit FieldReader(std::string_view bytes) : rest_(bytes) {}
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  std::string_view take(std::uint64_t n) {
    if (n > rest_.size()) throw FieldOverrun{};
    const std::string_view out = rest_.substr(0, n);
    rest_.remove_prefix(n);
    return out;
  }
  // String (and uint32 length-prefixed Bytes)
  std::string string() { return std::string(take(u32())); }
  // Map<string, string>: a uint32 byte length, then key and value Strings
  Metadata string_map() {
    FieldReader entries(take(u32()));
    Metadata out;
    while (!entries.rest_.empty()) {
      std::string key = entries.string();
      out[std::move(key)] = entries.string();
    }
    return out;
  }
  std::string_view rest() const { return rest_; }

 private:
  std::uint64_t le(int size) {
    const std::string_view bytes = take(size);
    std::uint64_t v = 0;
    for (int i = size - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[i]);
    return v;
  }
  std::string_view rest_;
};

std::uint64_t le64(const char* bytes) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[i]);
  return v;
}

// "Chunk", "Message Index", ... (the specification's names), "opcode 0x80" for the others.
std::string record_name(std::uint8_t opcode) {
  static const char* const names[] = {nullptr,      "Header",           "Footer",
                                      "Schema",     "Channel",          "Message",
                                      "Chunk",      "Message Index",    "Chunk Index",
                                      "Attachment", "Attachment Index", "Statistics",
                                      "Metadata",   "Metadata Index",   "Summary Offset",
                                      "Data End"};
  if (opcode >= 1 && opcode <= format::data_end) return names[opcode];
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02X", opcode);
  return std::string("opcode ") + hex;
}

std::string crc_hex(std::uint32_t crc) {
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%08X", crc);
  return hex;
}

}  // namespace

// zstd's and lz4's decompression contexts, made when a chunk first needs one.
struct Reader::Decompressors {
  ZSTD_DCtx* zstd = nullptr;
  LZ4F_dctx* lz4 = nullptr;
  ~Decompressors() {
    ZSTD_freeDCtx(zstd);
    if (lz4) LZ4F_freeDecompressionContext(lz4);
  }
};

Reader::Reader(const std::string& path)
    : path_(path), decompressors_(std::make_unique<Decompressors>()) {
  file_.reset(std::fopen(path.c_str(), "rb"));
  struct stat st{};
  if (!file_ || ::fstat(::fileno(file_.get()), &st) != 0)
    throw ReadError(path + ": cannot open: " + std::strerror(errno), 0);
  size_ = static_cast<std::uint64_t>(st.st_size);
  section_ = Section::end;  // until the Header is read whole

  // the magic: a file shorter than it is cut if it is the magic's beginning
  std::string magic;
  const std::uint64_t have = std::min<std::uint64_t>(size_, format::k_magic.size());
  if (!read_bytes(have, magic) || magic != format::k_magic.substr(0, have))
    fail(0, "not an MCAP file (bad magic at offset 0)");
  if (have < format::k_magic.size()) {
    cut(0, size_ == 0
               ? "the file is empty"
               : "the file ends inside the magic (" + std::to_string(size_) + " of 8 bytes)");
    return;
  }
  crc_ = format::crc32_of(magic);

  // the Header
  section_ = Section::data;
  std::uint8_t opcode = 0;
  if (!read_record(opcode)) return;
  if (opcode != format::header)
    fail(format::k_magic.size(), "not an MCAP file (" + record_name(opcode) +
                                     " record at offset 8, where the Header belongs)");
  try {
    FieldReader fields(record_);
    profile_ = fields.string();
    library_ = fields.string();
  } catch (const FieldOverrun&) {
    fail(format::k_magic.size(), "malformed Header record at offset 8");
  }
}

Reader::~Reader() = default;
Reader::Reader(Reader&&) noexcept = default;
Reader& Reader::operator=(Reader&&) noexcept = default;

const Schema* Reader::schema(std::uint16_t id) const {
  const auto it = schemas_.find(id);
  return it == schemas_.end() ? nullptr : &it->second;
}

const Channel* Reader::channel(std::uint16_t id) const {
  const auto it = channels_.find(id);
  return it == channels_.end() ? nullptr : &it->second;
}

void Reader::cut(std::uint64_t at, const std::string& why) {
  section_ = Section::end;
  complete_ = false;
  end_offset_ = at;
  truncation_ = path_ + ": readable up to offset " + std::to_string(at) + ": " + why;
}

void Reader::fail(std::uint64_t at, const std::string& what) {
  section_ = Section::end;
  chunk_.clear();
  chunk_at_ = 0;
  end_offset_ = at;
  throw ReadError(path_ + ": " + what, at);
}

bool Reader::read_bytes(std::uint64_t n, std::string& out) {
  if (n > size_ - offset_) return false;
  out.resize(n);
  if (n && std::fread(out.data(), 1, n, file_.get()) != n) {
    if (std::ferror(file_.get()))
      fail(offset_,
           "cannot read at offset " + std::to_string(offset_) + ": " + std::strerror(errno));
    fail(offset_,
         "the file became shorter while it was read (at offset " + std::to_string(offset_) + ")");
  }
  offset_ += n;
  return true;
}

bool Reader::read_record(std::uint8_t& opcode) {
  const std::uint64_t at = offset_;
  if (!read_bytes(format::k_record_prefix, prefix_)) {
    if (at < size_) {
      cut(at, "the record at offset " + std::to_string(at) + " is cut in its opcode and length (" +
                  std::to_string(size_ - at) + " of 9 bytes)");
    } else if (section_ == Section::data) {
      cut(at,
          "the file ends there, without Data End, the summary and the footer (a recording "
          "that did not close)");
    } else {
      cut(at,
          "the file ends in the summary section, before the footer (the data section was "
          "read whole)");
    }
    return false;
  }
  opcode = static_cast<std::uint8_t>(prefix_[0]);
  const std::uint64_t length = le64(prefix_.data() + 1);
  if (opcode == 0) fail(at, "invalid opcode 0x00 at offset " + std::to_string(at));
  if (!read_bytes(length, record_)) {
    cut(at, "a " + record_name(opcode) + " record of " + std::to_string(length) +
                " bytes at offset " + std::to_string(at) + " runs past the end of the file (" +
                std::to_string(size_) + " bytes)");
    return false;
  }
  if (section_ == Section::data || section_ == Section::summary) {
    crc_before_record_ = crc_;
    crc_ = format::crc32_of(record_, format::crc32_of(prefix_, crc_));
  }
  return true;
}

bool Reader::next(Item& item) {
  for (;;) {
    if (chunk_at_ < chunk_.size()) {
      if (next_in_chunk(item)) return true;
      continue;
    }
    if (section_ == Section::end) return false;
    const std::uint64_t at = offset_;

    if (section_ == Section::trailing_magic) {
      std::string magic;
      const std::uint64_t have = std::min<std::uint64_t>(size_ - at, format::k_magic.size());
      read_bytes(have, magic);
      if (magic != format::k_magic.substr(0, have))
        fail(at, "bad trailing magic at offset " + std::to_string(at));
      if (have < format::k_magic.size()) {
        cut(at, "the file ends inside the trailing magic (the data section was read whole)");
        return false;
      }
      if (offset_ != size_)
        fail(offset_, std::to_string(size_ - offset_) +
                          " bytes after the trailing magic at offset " + std::to_string(offset_));
      section_ = Section::end;
      complete_ = true;
      end_offset_ = size_;
      return false;
    }

    std::uint8_t opcode = 0;
    if (!read_record(opcode)) return false;
    try {
      if (opcode == format::footer) {
        // after Data End: the summary's CRC (a file without Data End, from an older writer,
        // ends here too)
        FieldReader fields(record_);
        const std::uint64_t summary_start = fields.u64();
        fields.u64();  // summary_offset_start
        const std::uint32_t crc = fields.u32();
        const std::uint32_t actual = format::crc32_of(
            std::string_view(record_).substr(0, 16), format::crc32_of(prefix_, crc_before_record_));
        if (section_ == Section::summary && crc != 0 &&
            (summary_start == 0 || summary_start == summary_start_) && actual != crc)
          fail(at, "summary CRC mismatch (the footer at offset " + std::to_string(at) + " says " +
                       crc_hex(crc) + ", the summary gives " + crc_hex(actual) + ")");
        section_ = Section::trailing_magic;
        continue;
      }
      if (section_ == Section::summary) continue;  // the summary's records: skipped

      switch (opcode) {
        case format::header: fail(at, "a second Header record at offset " + std::to_string(at));
        case format::schema:
        case format::channel:
        case format::message:
          if (take(opcode, record_, at, false, item)) return true;
          break;
        case format::chunk: open_chunk(at); break;
        case format::attachment: {
          FieldReader fields(record_);
          Attachment a;
          a.log_time = fields.u64();
          a.create_time = fields.u64();
          a.name = fields.string();
          a.media_type = fields.string();
          a.data = std::string(fields.take(fields.u64()));
          const std::size_t checked = record_.size() - fields.rest().size();
          const std::uint32_t crc = fields.u32();
          const std::uint32_t actual =
              format::crc32_of(std::string_view(record_).substr(0, checked));
          if (crc != 0 && actual != crc)
            fail(at, "attachment '" + a.name + "' CRC mismatch at offset " + std::to_string(at) +
                         " (the record says " + crc_hex(crc) + ", its bytes give " +
                         crc_hex(actual) + ")");
          item = std::move(a);
          return true;
        }
        case format::metadata: {
          FieldReader fields(record_);
          MetadataRecord m;
          m.name = fields.string();
          m.metadata = fields.string_map();
          item = std::move(m);
          return true;
        }
        case format::data_end: {
          const std::uint32_t crc = FieldReader(record_).u32();
          if (crc != 0 && crc != crc_before_record_)
            fail(at, "data section CRC mismatch (Data End at offset " + std::to_string(at) +
                         " says " + crc_hex(crc) + ", the bytes before it give " +
                         crc_hex(crc_before_record_) + ")");
          section_ = Section::summary;
          summary_start_ = offset_;
          crc_ = 0;
          break;
        }
        default: break;  // indexes, statistics, records of later versions or extensions: skipped
      }
    } catch (const FieldOverrun&) {
      fail(at, "malformed " + record_name(opcode) + " record at offset " + std::to_string(at) +
                   " (a field runs past the record's end)");
    }
  }
}

void Reader::open_chunk(std::uint64_t at) {
  chunk_offset_ = at;
  chunk_at_ = 0;
  chunk_.clear();
  FieldReader fields(record_);
  fields.u64();  // message_start_time
  fields.u64();  // message_end_time
  const std::uint64_t size = fields.u64();
  const std::uint32_t crc = fields.u32();
  const std::string compression = fields.string();
  const std::string_view records = fields.take(fields.u64());
  const std::string chunk_at = "the chunk at offset " + std::to_string(at);
  if (compression.empty()) {
    if (records.size() != size)
      fail(at, chunk_at + " holds " + std::to_string(records.size()) +
                   " bytes of records, its uncompressed size says " + std::to_string(size));
    chunk_.assign(records);
  } else if (compression == "zstd" || compression == "lz4") {
    decompress(compression, records, size);
  } else {
    fail(at, "unknown chunk compression '" + compression + "' at offset " + std::to_string(at));
  }
  if (crc != 0) {
    const std::uint32_t actual = format::crc32_of(chunk_);
    if (actual != crc)
      fail(at, "chunk CRC mismatch at offset " + std::to_string(at) + " (the chunk says " +
                   crc_hex(crc) + ", its records give " + crc_hex(actual) + ")");
  }
}

void Reader::decompress(const std::string& compression, std::string_view in, std::uint64_t size) {
  const std::uint64_t at = chunk_offset_;
  const std::string chunk_at = "the chunk at offset " + std::to_string(at);
  // The output grows as it comes, up to one byte more than the chunk says (to tell a chunk
  // that decompresses to more): a chunk that claims more than it holds allocates no more
  // than what it holds.
  const std::uint64_t limit = size + 1;
  std::size_t produced = 0;
  chunk_.resize(std::min<std::uint64_t>(limit, in.size() * 64 + (1u << 20)));
  const auto room = [&]() {
    if (produced < chunk_.size()) return true;
    if (chunk_.size() >= limit) return false;
    chunk_.resize(std::min<std::uint64_t>(limit, 2 * chunk_.size()));
    return true;
  };
  if (compression == "zstd") {
    if (!decompressors_->zstd && !(decompressors_->zstd = ZSTD_createDCtx()))
      throw std::bad_alloc();
    ZSTD_DCtx* const z = decompressors_->zstd;
    ZSTD_DCtx_reset(z, ZSTD_reset_session_only);
    ZSTD_inBuffer input{in.data(), in.size(), 0};
    while (room()) {
      ZSTD_outBuffer output{chunk_.data(), chunk_.size(), produced};
      const std::size_t consumed = input.pos;
      const std::size_t hint = ZSTD_decompressStream(z, &output, &input);
      if (ZSTD_isError(hint))
        fail(at, chunk_at + ": zstd cannot decompress its records: " + ZSTD_getErrorName(hint));
      const bool moved = output.pos != produced || input.pos != consumed;
      produced = output.pos;
      if (input.pos == input.size && hint == 0) break;  // every frame decoded
      if (input.pos == input.size && produced < chunk_.size())
        fail(at, chunk_at + ": its zstd records end inside a frame");
      if (!moved) fail(at, chunk_at + ": zstd makes no progress on its records");
    }
  } else {
    if (!decompressors_->lz4 &&
        LZ4F_isError(LZ4F_createDecompressionContext(&decompressors_->lz4, LZ4F_VERSION)))
      throw std::bad_alloc();
    LZ4F_dctx* const z = decompressors_->lz4;
    LZ4F_resetDecompressionContext(z);
    while (room()) {
      std::size_t out_size = chunk_.size() - produced, in_size = in.size();
      const std::size_t hint =
          LZ4F_decompress(z, chunk_.data() + produced, &out_size, in.data(), &in_size, nullptr);
      if (LZ4F_isError(hint))
        fail(at, chunk_at + ": lz4 cannot decompress its records: " + LZ4F_getErrorName(hint));
      produced += out_size;
      in.remove_prefix(in_size);
      if (in.empty() && hint == 0) break;  // every frame decoded
      if (in.empty() && produced < chunk_.size())
        fail(at, chunk_at + ": its lz4 records end inside a frame");
      if (out_size == 0 && in_size == 0)
        fail(at, chunk_at + ": lz4 makes no progress on its records");
    }
  }
  if (produced != size)
    fail(at, chunk_at + " decompresses to " + (produced > size ? "more than " : "") +
                 std::to_string(std::min<std::uint64_t>(produced, size)) +
                 " bytes, its uncompressed size says " + std::to_string(size));
  chunk_.resize(produced);
}

bool Reader::next_in_chunk(Item& item) {
  const std::uint64_t at = chunk_offset_;
  const std::size_t start = chunk_at_;
  const std::string_view rest = std::string_view(chunk_).substr(start);
  const auto in_chunk = [&]() {
    return " at byte " + std::to_string(start) + " of the chunk at offset " + std::to_string(at);
  };
  if (rest.size() < format::k_record_prefix)
    fail(at, "malformed chunk: a record is cut in its opcode and length" + in_chunk());
  const auto opcode = static_cast<std::uint8_t>(rest[0]);
  const std::uint64_t length = le64(rest.data() + 1);
  if (opcode == 0) fail(at, "invalid opcode 0x00" + in_chunk());
  if (length > rest.size() - format::k_record_prefix)
    fail(at, "a " + record_name(opcode) + " record of " + std::to_string(length) + " bytes" +
                 in_chunk() + " runs past the chunk's end");
  chunk_at_ += format::k_record_prefix + length;
  const std::string_view content = rest.substr(format::k_record_prefix, length);
  try {
    switch (opcode) {
      case format::schema:
      case format::channel:
      case format::message: return take(opcode, content, at, true, item);
      default: return false;  // not allowed in a chunk by the specification: skipped
    }
  } catch (const FieldOverrun&) {
    fail(at, "malformed " + record_name(opcode) + " record" + in_chunk() +
                 " (a field runs past the record's end)");
  }
}

bool Reader::take(std::uint8_t opcode, std::string_view content, std::uint64_t at, bool in_chunk,
                  Item& item) {
  const auto where = [&]() {
    return (in_chunk ? " in the chunk at offset " : " at offset ") + std::to_string(at);
  };
  FieldReader fields(content);
  if (opcode == format::message) {
    Message m;
    m.channel_id = fields.u16();
    m.sequence = fields.u32();
    m.log_time = fields.u64();
    m.publish_time = fields.u64();
    m.data = std::string(fields.rest());
    if (!channels_.count(m.channel_id))
      fail(at, "a message on channel " + std::to_string(m.channel_id) + where() +
                   ", which no Channel record defined before it");
    item = std::move(m);
    return true;
  }
  if (opcode == format::schema) {
    Schema s;
    s.id = fields.u16();
    s.name = fields.string();
    s.encoding = fields.string();
    s.data = fields.string();
    if (s.id == 0) return false;  // invalid: ignored, as the specification says
    const auto [it, added] = schemas_.try_emplace(s.id, s);
    if (added) {
      item = std::move(s);
      return true;
    }
    if (!(it->second == s))
      fail(at, "schema " + std::to_string(s.id) + where() + " differs from the schema " +
                   std::to_string(s.id) + " read before it");
    return false;
  }
  Channel c;
  c.id = fields.u16();
  c.schema_id = fields.u16();
  c.topic = fields.string();
  c.message_encoding = fields.string();
  c.metadata = fields.string_map();
  if (c.schema_id != 0 && !schemas_.count(c.schema_id))
    fail(at, "channel " + std::to_string(c.id) + " ('" + c.topic + "')" + where() +
                 " uses schema " + std::to_string(c.schema_id) +
                 ", which no Schema record defined before it");
  const auto [it, added] = channels_.try_emplace(c.id, c);
  if (added) {
    item = std::move(c);
    return true;
  }
  if (!(it->second == c))
    fail(at, "channel " + std::to_string(c.id) + where() + " differs from the channel " +
                 std::to_string(c.id) + " read before it");
  return false;
}

}  // namespace simgate::mcap
