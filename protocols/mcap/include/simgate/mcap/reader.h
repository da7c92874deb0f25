// simgate/mcap/reader.h — an MCAP file reader (issue #39's flight recorder: `simgate replay`,
// and the tests of writer.h). The contract is MCAP's public specification, as for writer.h:
// the magic, the Header, then the data section read in file order: Schema, Channel and
// Message records (inside Chunks, decompressed with zstd or lz4 (the LZ4 frame format) or
// stored as they are; or directly in the data section), Attachments and Metadata. The
// indexes (Message Index, Chunk Index, ...), Statistics and the summary section are skipped:
// the reader never seeks, so it also reads a file whose recording was cut.
//
// Life cycle: Reader(path) opens the file and reads the magic and the Header; next() hands
// the records over one at a time, in file order, until it returns false at the end. Then
// complete() says whether the file was whole (Data End, the summary, the footer and the
// magic again); if not, truncation() says where it stops being readable.
//
// Truncated files: a recording killed (kill -9, a crash) leaves a file that ends inside a
// record, or after one, without Data End, the summary or the footer (writer.h writes each
// chunk, attachment and metadata record through to the OS at once). The reader hands over
// every record before the cut and stops there, without an error: a chunk that is cut is
// dropped whole (none of its messages). An empty file, or one that ends inside the magic or
// the Header, is a truncated file with nothing in it.
//
// Errors (ReadError, with the byte offset of what is wrong): a file that is not MCAP, a CRC
// that does not match (a chunk's records, an attachment, the data section in Data End, the
// summary in the footer; each is checked when it is not 0), an unknown chunk compression, a
// record that is malformed in the middle of the file (a field running past its record's end,
// a message on a channel no Channel record defined before it). Schema and Channel records are
// handed over once, at their first appearance; copies (the specification says they are
// identical) are skipped.
//
// Memory: one record's content (a chunk: compressed, and its records decompressed), never the
// whole file. Records longer than the file are a cut, not an allocation.
//
// Threads: one reader, one thread at a time.
#ifndef SIMGATE_MCAP_READER_H_
#define SIMGATE_MCAP_READER_H_

#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>

#include "simgate/mcap/writer.h"  // Metadata: the key/value map both sides use

namespace simgate::mcap {

// What is wrong with the file, and where: "recording.mcap: not an MCAP file (bad magic at
// offset 0)", "recording.mcap: chunk CRC mismatch at offset 1234 (...)".
class ReadError : public std::runtime_error {
 public:
  ReadError(const std::string& message, std::uint64_t offset)
      : std::runtime_error(message), offset_(offset) {}
  // The byte offset in the file of the record (or bytes) that is wrong.
  std::uint64_t offset() const { return offset_; }

 private:
  std::uint64_t offset_;
};

// The records next() hands over (the specification's fields; times in nanoseconds).
struct Schema {
  std::uint16_t id = 0;  // from 1
  std::string name, encoding, data;
  friend bool operator==(const Schema&, const Schema&) = default;
};
struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;  // 0: no schema
  std::string topic, message_encoding;
  Metadata metadata;
  friend bool operator==(const Channel&, const Channel&) = default;
};
struct Message {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0, publish_time = 0;
  std::string data;
  friend bool operator==(const Message&, const Message&) = default;
};
struct Attachment {
  std::uint64_t log_time = 0, create_time = 0;
  std::string name, media_type, data;
  friend bool operator==(const Attachment&, const Attachment&) = default;
};
struct MetadataRecord {  // a Metadata record (Metadata is the map it holds)
  std::string name;
  Metadata metadata;
  friend bool operator==(const MetadataRecord&, const MetadataRecord&) = default;
};
using Item = std::variant<Schema, Channel, Message, Attachment, MetadataRecord>;

class Reader {
 public:
  // Opens `path` and reads the magic and the Header. Throws ReadError when the file cannot
  // be opened (offset 0) or is not MCAP; a file that ends before the Header is whole is not
  // an error (next() then returns false, truncation() says so).
  explicit Reader(const std::string& path);
  ~Reader();
  Reader(Reader&&) noexcept;
  Reader& operator=(Reader&&) noexcept;

  // The Header's fields ("" until the Header was read whole).
  const std::string& profile() const { return profile_; }
  const std::string& library() const { return library_; }

  // The next record in file order into `item`: true; false when there is none left (the end
  // of the file, its summary, footer and magic checked; or a cut: complete(), truncation()),
  // and from then on. Throws ReadError (the reader is then at its end too). Blocks on the
  // file's reads.
  bool next(Item& item);

  // After next() returned false: whether the file was whole (Data End, the summary, the
  // footer and the trailing magic). False while there is more to read.
  bool complete() const { return complete_; }
  // After next() returned false: the offset up to which the file was read, its size when
  // complete(); in a cut file, the start of the record that is cut (or the file's size when
  // it ends between two records).
  std::uint64_t end_offset() const { return end_offset_; }
  // Where and why a cut file stops being readable ("recording.mcap: readable up to offset
  // 5120: a Chunk record of 16384 bytes at offset 5120 runs past the end of the file (9000
  // bytes)"); "" for a complete file or one not read to its end yet.
  const std::string& truncation() const { return truncation_; }

  // The schemas and channels read so far, by id; nullptr for one not seen (yet).
  const Schema* schema(std::uint16_t id) const;
  const Channel* channel(std::uint16_t id) const;

 private:
  struct CloseFile {
    void operator()(std::FILE* file) const { std::fclose(file); }
  };
  struct Decompressors;  // zstd's and lz4's contexts (reader.cc)
  enum class Section { data, summary, trailing_magic, end };

  // Reads the next record of the file: its opcode and length into prefix_, its content into
  // record_; updates the section's CRC. False (after cut()) when the file ends before it does.
  bool read_record(std::uint8_t& opcode);
  // Reads `n` more bytes into `out`; false (nothing read) when the file ends first.
  bool read_bytes(std::uint64_t n, std::string& out);
  // The Chunk record in record_ (at offset `at`): its records into chunk_, their CRC checked.
  void open_chunk(std::uint64_t at);
  void decompress(const std::string& compression, std::string_view in, std::uint64_t size);
  // The next record of the open chunk into `item`: false when it is not one to hand over.
  bool next_in_chunk(Item& item);
  // A Schema, Channel or Message record (at `at`, or in the chunk at `at`) into `item`: false
  // for a copy of a schema or channel already handed over.
  bool take(std::uint8_t opcode, std::string_view content, std::uint64_t at, bool in_chunk,
            Item& item);
  // Ends reading at `at`, a cut file: truncation() says `why`.
  void cut(std::uint64_t at, const std::string& why);
  // Ends reading and throws ReadError(path: what, at).
  [[noreturn]] void fail(std::uint64_t at, const std::string& what);

  std::string path_;
  std::unique_ptr<std::FILE, CloseFile> file_;
  std::uint64_t size_ = 0;    // the file's size when it was opened
  std::uint64_t offset_ = 0;  // of the next byte to read
  std::string profile_, library_;
  Section section_ = Section::data;
  std::uint32_t crc_ = 0;  // of the bytes read in this section: the data section, the summary
  std::uint32_t crc_before_record_ = 0;  // crc_ before the last record read
  std::uint64_t summary_start_ = 0;      // the offset after Data End
  bool complete_ = false;
  std::uint64_t end_offset_ = 0;
  std::string truncation_;

  std::string prefix_;              // the opcode and length of the record being read
  std::string record_;              // its content
  std::string chunk_;               // the open chunk's records, decompressed
  std::size_t chunk_at_ = 0;        // the next record in chunk_
  std::uint64_t chunk_offset_ = 0;  // the chunk record's offset in the file
  std::unique_ptr<Decompressors> decompressors_;
  std::map<std::uint16_t, Schema> schemas_;
  std::map<std::uint16_t, Channel> channels_;
};

}  // namespace simgate::mcap

#endif  // SIMGATE_MCAP_READER_H_
