// The MCAP reader (simgate/mcap/reader.h): what the writer wrote read back as it was, for
// each compression; files that are not MCAP, or corrupt (an unknown compression, a CRC that
// does not match, a malformed record), refused with the offset of what is wrong; files cut
// short (a recording killed half way) read up to the cut, without an error, at every byte
// they can be cut at; and a writer killed with SIGKILL leaving every chunk it wrote readable.
#include "simgate/mcap/reader.h"

#include <gtest/gtest.h>

#include <csignal>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

#include "simgate/mcap/writer.h"

namespace simgate::mcap {
namespace {

namespace fs = std::filesystem;

// ---- bytes by hand (the specification's serialization), for files the writer would not write
void u16(std::string& out, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}
void u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}
void u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}
void str(std::string& out, std::string_view s) {
  u32(out, static_cast<std::uint32_t>(s.size()));
  out += s;
}
std::string rec(std::uint8_t op, std::string_view content) {
  std::string out(1, static_cast<char>(op));
  u64(out, content.size());
  out += content;
  return out;
}
const std::string k_magic("\x89MCAP0\r\n", 8);
// The magic and a Header (profile "", library "hand").
std::string file_start() {
  std::string h;
  str(h, "");
  str(h, "hand");
  return k_magic + rec(0x01, h);
}
// Data End (CRC 0: not checked), a footer without summary, the magic.
std::string file_end() {
  std::string end, footer(16, '\0');
  u32(end, 0);
  u32(footer, 0);
  return rec(0x0F, end) + rec(0x02, footer) + k_magic;
}
std::string schema_record(std::uint16_t id) {
  std::string c;
  u16(c, id);
  str(c, "s");
  str(c, "jsonschema");
  str(c, "{}");
  return rec(0x03, c);
}
std::string channel_record(std::uint16_t id, std::uint16_t schema_id) {
  std::string c;
  u16(c, id);
  u16(c, schema_id);
  str(c, "/t");
  str(c, "json");
  u32(c, 0);  // no metadata
  return rec(0x04, c);
}
std::string message_record(std::uint16_t channel, std::uint64_t time) {
  std::string c;
  u16(c, channel);
  u32(c, 0);
  u64(c, time);
  u64(c, time);
  c += "{}";
  return rec(0x05, c);
}

std::uint64_t le(const std::string& bytes, std::size_t at, int size) {
  std::uint64_t v = 0;
  for (int i = size - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
  return v;
}

// A top-level record of a file: its opcode, offset and length (prefix included).
struct Span {
  int opcode;
  std::size_t offset, length;
};
// The records from the Header to the footer (not into chunks).
std::vector<Span> records_of(const std::string& file) {
  std::vector<Span> out;
  std::size_t at = 8;
  while (at + 9 <= file.size()) {
    const std::size_t length = 9 + le(file, at + 1, 8);
    out.push_back({static_cast<unsigned char>(file[at]), at, length});
    if (file[at] == 0x02) break;
    at += length;
  }
  return out;
}

// Everything a Reader hands over, and how it ended.
struct ReadBack {
  std::vector<Item> items;
  std::vector<Message> messages;
  bool complete = false;
  std::uint64_t end_offset = 0;
  std::string truncation;
};
ReadBack read_all(const fs::path& path) {
  ReadBack out;
  Reader reader(path.string());
  for (Item item; reader.next(item);) {
    if (const auto* m = std::get_if<Message>(&item)) out.messages.push_back(*m);
    out.items.push_back(std::move(item));
  }
  Item ignored;
  EXPECT_FALSE(reader.next(ignored)) << "next() stays at the end";
  out.complete = reader.complete();
  out.end_offset = reader.end_offset();
  out.truncation = reader.truncation();
  return out;
}

class McapReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("simgate-mcap-reader-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  static std::string read(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  fs::path write(const std::string& name, const std::string& bytes) {
    const fs::path path = dir_ / name;
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }
  // Expects reading `path` to throw ReadError at `offset` with `what` in its message.
  static void expect_error(const fs::path& path, std::uint64_t offset, const std::string& what) {
    try {
      read_all(path);
      ADD_FAILURE() << "no ReadError for " << path << " (" << what << ")";
    } catch (const ReadError& e) {
      EXPECT_EQ(e.offset(), offset) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
    }
  }
  // A recording as the flight recorder writes one: 2 schemas, 3 channels (one with metadata,
  // one without a schema), 120 messages over many small chunks, an attachment and a metadata
  // record half way.
  fs::path write_sample(const std::string& name, Compression compression,
                        std::size_t chunk_bytes = 512) {
    const fs::path path = dir_ / name;
    WriterOptions options;
    options.profile = "simgate";
    options.compression = compression;
    options.chunk_bytes = chunk_bytes;
    Writer w(path.string(), options);
    const auto pose = w.add_schema("simgate.pose", "jsonschema", R"({"type":"object"})");
    const auto log = w.add_schema("simgate.log", "jsonschema", "{}");
    const std::uint16_t channels[3] = {
        w.add_channel(pose, "/robot/pose", "json", {{"component", "robot.pose"}, {"hz", "100"}}),
        w.add_channel(log, "/log", "json"), w.add_channel(0, "/raw", "json")};
    for (std::uint32_t i = 0; i < 120; ++i) {
      if (i == 60) {
        w.attach(7, 3, "config.json", "application/json", R"({"scene":"demo.xml"})");
        w.add_metadata("simgate", {{"version", "0.1.0"}});
      }
      w.write(channels[i % 3], i / 3, 1000 + i, 2000 + i, "{\"i\":" + std::to_string(i) + "}");
    }
    w.close();
    return path;
  }
  fs::path dir_;
};

class McapReaderRoundTrip : public McapReaderTest,
                            public ::testing::WithParamInterface<Compression> {};

TEST_P(McapReaderRoundTrip, EveryRecordReadsBackAsWritten) {
  const fs::path path = write_sample("round-trip.mcap", GetParam());
  const std::uint64_t size = fs::file_size(path);
  Reader reader(path.string());
  EXPECT_EQ(reader.profile(), "simgate");
  EXPECT_EQ(reader.library(), "simgate");
  std::vector<Item> items;
  for (Item item; reader.next(item);) items.push_back(item);
  EXPECT_TRUE(reader.complete());
  EXPECT_EQ(reader.end_offset(), size);
  EXPECT_EQ(reader.truncation(), "");

  // the schemas and channels first (in the first chunk), then the messages in order, the
  // attachment and the metadata between message 59 and 60
  ASSERT_EQ(items.size(), 2u + 3u + 120u + 2u);
  EXPECT_EQ(std::get<Schema>(items[0]),
            (Schema{1, "simgate.pose", "jsonschema", R"({"type":"object"})"}));
  EXPECT_EQ(std::get<Schema>(items[1]), (Schema{2, "simgate.log", "jsonschema", "{}"}));
  EXPECT_EQ(std::get<Channel>(items[2]),
            (Channel{0, 1, "/robot/pose", "json", {{"component", "robot.pose"}, {"hz", "100"}}}));
  EXPECT_EQ(std::get<Channel>(items[3]), (Channel{1, 2, "/log", "json", {}}));
  EXPECT_EQ(std::get<Channel>(items[4]), (Channel{2, 0, "/raw", "json", {}}));
  std::size_t at = 5;
  for (std::uint32_t i = 0; i < 120; ++i, ++at) {
    if (i == 60) {
      EXPECT_EQ(std::get<Attachment>(items[at++]),
                (Attachment{7, 3, "config.json", "application/json", R"({"scene":"demo.xml"})"}));
      EXPECT_EQ(std::get<MetadataRecord>(items[at++]),
                (MetadataRecord{"simgate", {{"version", "0.1.0"}}}));
    }
    ASSERT_TRUE(std::holds_alternative<Message>(items[at])) << "item " << at;
    EXPECT_EQ(std::get<Message>(items[at]),
              (Message{static_cast<std::uint16_t>(i % 3), i / 3, 1000 + i, 2000 + i,
                       "{\"i\":" + std::to_string(i) + "}"}));
  }
  ASSERT_NE(reader.schema(2), nullptr);
  EXPECT_EQ(reader.schema(2)->name, "simgate.log");
  EXPECT_EQ(reader.schema(3), nullptr);
  ASSERT_NE(reader.channel(0), nullptr);
  EXPECT_EQ(reader.channel(0)->metadata.at("component"), "robot.pose");
  EXPECT_EQ(reader.channel(3), nullptr);
}

INSTANTIATE_TEST_SUITE_P(Compressions, McapReaderRoundTrip,
                         ::testing::Values(Compression::none, Compression::zstd, Compression::lz4),
                         [](const auto& info) {
                           return info.param == Compression::none
                                      ? std::string("none")
                                      : std::string(compression_name(info.param));
                         });

TEST_F(McapReaderTest, AFileWithoutRecordsIsComplete) {
  const fs::path path = dir_ / "no-records.mcap";
  Writer(path.string(), WriterOptions{}).close();
  const ReadBack back = read_all(path);
  EXPECT_TRUE(back.items.empty());
  EXPECT_TRUE(back.complete);
  EXPECT_EQ(back.end_offset, fs::file_size(path));
}

TEST_F(McapReaderTest, RecordsOutsideChunksAreReadAndCopiesOfSchemasAndChannelsSkipped) {
  const fs::path path =
      write("unchunked.mcap", file_start() + schema_record(1) + channel_record(4, 1) +
                                  message_record(4, 10) + schema_record(1) + channel_record(4, 1) +
                                  message_record(4, 11) + file_end());
  const ReadBack back = read_all(path);
  ASSERT_EQ(back.items.size(), 4u);
  EXPECT_EQ(std::get<Schema>(back.items[0]).id, 1);
  EXPECT_EQ(std::get<Channel>(back.items[1]).id, 4);
  ASSERT_EQ(back.messages.size(), 2u);
  EXPECT_EQ(back.messages[1].log_time, 11u);
  EXPECT_TRUE(back.complete);
}

TEST_F(McapReaderTest, AFileThatCannotBeOpenedIsAnError) {
  expect_error(dir_ / "missing.mcap", 0, "cannot open");
}

TEST_F(McapReaderTest, AFileThatIsNotMcapIsRefused) {
  expect_error(write("notes.mcap", "these are not the bytes you are looking for"), 0,
               "not an MCAP file (bad magic at offset 0)");
  // a later major version, "MCAP1"
  std::string other = read(write_sample("v1.mcap", Compression::zstd));
  other[5] = '1';
  expect_error(write("v1.mcap", other), 0, "not an MCAP file (bad magic at offset 0)");
  // the magic, then no Header
  expect_error(write("no-header.mcap", k_magic + schema_record(1)), 8,
               "not an MCAP file (Schema record at offset 8, where the Header belongs)");
}

TEST_F(McapReaderTest, AnUnknownCompressionIsAnErrorAtItsChunk) {
  const std::string start = file_start() + schema_record(1) + channel_record(0, 1);
  std::string chunk;
  u64(chunk, 1);
  u64(chunk, 1);
  u64(chunk, 12);
  u32(chunk, 0);
  str(chunk, "brotli");
  u64(chunk, 0);  // no records
  const fs::path path = write("brotli.mcap", start + rec(0x06, chunk) + file_end());
  expect_error(path, start.size(),
               "unknown chunk compression 'brotli' at offset " + std::to_string(start.size()));
}

TEST_F(McapReaderTest, AChunkCrcMismatchIsAnErrorAtItsChunk) {
  const fs::path path = write_sample("crc.mcap", Compression::none);
  std::string file = read(path);
  std::vector<Span> chunks;
  for (const Span& r : records_of(file))
    if (r.opcode == 0x06) chunks.push_back(r);
  ASSERT_GE(chunks.size(), 3u);
  const Span second = chunks[1];
  file[second.offset + second.length - 3] ^= 0x20;  // in its last message's payload
  write("crc.mcap", file);
  expect_error(path, second.offset,
               "chunk CRC mismatch at offset " + std::to_string(second.offset));
  // what precedes the chunk was read
  Reader reader(path.string());
  std::size_t messages = 0;
  Item item;
  try {
    while (reader.next(item)) messages += std::holds_alternative<Message>(item) ? 1 : 0;
    ADD_FAILURE() << "no ReadError";
  } catch (const ReadError&) {}
  EXPECT_GT(messages, 0u);
  EXPECT_FALSE(reader.next(item)) << "the reader stops at the error";
}

TEST_F(McapReaderTest, ACorruptCompressedChunkIsAnErrorAtItsChunk) {
  for (const Compression c : {Compression::zstd, Compression::lz4}) {
    SCOPED_TRACE(std::string(compression_name(c)));
    const fs::path path = write_sample("corrupt.mcap", c);
    std::string file = read(path);
    Span first{};
    for (const Span& r : records_of(file))
      if (r.opcode == 0x06) {
        first = r;
        break;
      }
    ASSERT_GT(first.length, 60u);
    for (std::size_t i = first.length - 20; i < first.length - 10; ++i)
      file[first.offset + i] ^= 0x5A;
    expect_error(write("corrupt.mcap", file), first.offset,
                 "at offset " + std::to_string(first.offset));
  }
}

TEST_F(McapReaderTest, AnAttachmentCrcMismatchIsAnError) {
  const fs::path path = write_sample("attachment.mcap", Compression::zstd);
  std::string file = read(path);
  for (const Span& r : records_of(file)) {
    if (r.opcode != 0x09) continue;
    file[r.offset + r.length - 6] ^= 0x01;  // in its data
    expect_error(write("attachment.mcap", file), r.offset,
                 "attachment 'config.json' CRC mismatch at offset " + std::to_string(r.offset));
    return;
  }
  FAIL() << "no attachment";
}

TEST_F(McapReaderTest, ADataSectionCrcMismatchIsAnErrorAtDataEnd) {
  // a byte of a Message Index (which the reader skips) changed: only Data End's CRC tells
  const fs::path path = write_sample("data-crc.mcap", Compression::zstd);
  std::string file = read(path);
  const std::vector<Span> records = records_of(file);
  std::size_t data_end = 0;
  for (const Span& r : records)
    if (r.opcode == 0x0F) data_end = r.offset;
  for (const Span& r : records) {
    if (r.opcode != 0x07) continue;
    file[r.offset + r.length - 1] ^= 0x01;
    expect_error(write("data-crc.mcap", file), data_end, "data section CRC mismatch");
    return;
  }
  FAIL() << "no message index";
}

TEST_F(McapReaderTest, ASummaryCrcMismatchIsAnErrorAtTheFooter) {
  // a byte of a Chunk Index changed: the footer's CRC tells (after every record was read)
  const fs::path path = write_sample("summary-crc.mcap", Compression::lz4);
  std::string file = read(path);
  const std::vector<Span> records = records_of(file);
  ASSERT_EQ(records.back().opcode, 0x02);
  for (const Span& r : records) {
    if (r.opcode != 0x08) continue;
    file[r.offset + 9] ^= 0x01;  // its message_start_time
    expect_error(
        write("summary-crc.mcap", file), records.back().offset,
        "summary CRC mismatch (the footer at offset " + std::to_string(records.back().offset));
    return;
  }
  FAIL() << "no chunk index";
}

TEST_F(McapReaderTest, AMalformedRecordIsAnError) {
  const std::string start = file_start();
  std::string metadata;
  str(metadata, "m");
  u32(metadata, 100);  // a map of 100 bytes in a record that holds 4
  str(metadata, "k");
  expect_error(write("malformed.mcap", start + rec(0x0C, metadata) + file_end()), start.size(),
               "malformed Metadata record at offset " + std::to_string(start.size()));
  const std::string channel = start + schema_record(1) + channel_record(0, 1);
  expect_error(write("no-channel.mcap", channel + message_record(3, 1) + file_end()),
               channel.size(),
               "a message on channel 3 at offset " + std::to_string(channel.size()));
  expect_error(write("zero.mcap", start + std::string(20, '\0')), start.size(),
               "invalid opcode 0x00 at offset " + std::to_string(start.size()));
}

TEST_F(McapReaderTest, AnEmptyFileIsACutFileWithNothingInIt) {
  const ReadBack back = read_all(write("empty.mcap", ""));
  EXPECT_TRUE(back.items.empty());
  EXPECT_FALSE(back.complete);
  EXPECT_EQ(back.end_offset, 0u);
  EXPECT_NE(back.truncation.find("the file is empty"), std::string::npos) << back.truncation;
}

TEST_F(McapReaderTest, ACutChunkIsDroppedWholeAndWhatPrecedesItIsRead) {
  const fs::path path = write_sample("cut.mcap", Compression::zstd);
  const std::string file = read(path);
  const ReadBack whole = read_all(path);
  std::vector<Span> chunks;
  for (const Span& r : records_of(file))
    if (r.opcode == 0x06) chunks.push_back(r);
  ASSERT_GE(chunks.size(), 3u);
  const Span third = chunks[2];
  const ReadBack back = read_all(write("cut-copy.mcap", file.substr(0, third.offset + 40)));
  EXPECT_FALSE(back.complete);
  EXPECT_EQ(back.end_offset, third.offset);
  EXPECT_NE(back.truncation.find("cut-copy.mcap: readable up to offset " +
                                 std::to_string(third.offset) + ": a Chunk record of " +
                                 std::to_string(third.length - 9) + " bytes at offset " +
                                 std::to_string(third.offset) + " runs past the end of the file"),
            std::string::npos)
      << back.truncation;
  ASSERT_LT(back.messages.size(), whole.messages.size());
  ASSERT_GT(back.messages.size(), 0u);
  for (std::size_t i = 0; i < back.messages.size(); ++i)
    EXPECT_EQ(back.messages[i], whole.messages[i]);
}

TEST_F(McapReaderTest, ARecordLongerThanTheFileIsACut) {
  std::string bogus(1, '\x06');
  u64(bogus, 99999999);
  bogus += "not quite";
  const std::string start = file_start();
  const ReadBack back = read_all(write("long.mcap", start + bogus));
  EXPECT_FALSE(back.complete);
  EXPECT_EQ(back.end_offset, start.size());
  EXPECT_NE(back.truncation.find("a Chunk record of 99999999 bytes at offset " +
                                 std::to_string(start.size()) + " runs past the end of the file"),
            std::string::npos)
      << back.truncation;
}

// Crash safety: a file cut at any byte reads as a prefix of the whole file's records, without
// an error; each chunk whose record (and message indexes) the cut leaves whole is read whole.
TEST_F(McapReaderTest, EveryCutOfAFileReadsAsAPrefixOfIt) {
  for (const Compression c : {Compression::none, Compression::zstd, Compression::lz4}) {
    SCOPED_TRACE(std::string("compression '") + std::string(compression_name(c)) + "'");
    const fs::path path = write_sample("whole.mcap", c, 256);
    const std::string file = read(path);
    const ReadBack whole = read_all(path);
    ASSERT_TRUE(whole.complete);
    // per chunk, the offset where it stops being cut (its record's end) and its messages
    // (counted by the message indexes after it)
    std::vector<std::pair<std::size_t, std::size_t>> chunk_ends;
    for (const Span& r : records_of(file)) {
      if (r.opcode == 0x06) chunk_ends.push_back({r.offset + r.length, 0});
      if (r.opcode == 0x07) chunk_ends.back().second += le(file, r.offset + 11, 4) / 16;
    }
    ASSERT_GE(chunk_ends.size(), 5u);

    // (the copy is cut shorter and shorter: rewriting it whole each time made ext4 write it
    // through to the disk at every close, a minute in all)
    const fs::path cut = write("cut.mcap", file);
    for (std::size_t size = file.size() + 1; size-- > 0;) {
      fs::resize_file(cut, size);
      ReadBack back;
      try {
        back = read_all(cut);
      } catch (const std::exception& e) {
        FAIL() << "cut at " << size << " of " << file.size() << ": " << e.what();
      }
      ASSERT_LE(back.items.size(), whole.items.size()) << "cut at " << size;
      for (std::size_t i = 0; i < back.items.size(); ++i)
        ASSERT_EQ(back.items[i], whole.items[i]) << "cut at " << size << ", item " << i;
      std::size_t expected = 0;
      for (const auto& [end, messages] : chunk_ends)
        if (end <= size) expected += messages;
      ASSERT_EQ(back.messages.size(), expected) << "cut at " << size;
      ASSERT_EQ(back.complete, size == file.size()) << "cut at " << size;
      ASSERT_LE(back.end_offset, size);
      ASSERT_EQ(back.truncation.empty(), back.complete) << "cut at " << size;
    }
  }
}

// Crash safety for real: a process killed with SIGKILL right after the writer wrote a chunk
// and an attachment (no close(), no destructor, no flush at exit) leaves both in the file.
TEST_F(McapReaderTest, AWriterKilledAfterAChunkLeavesItReadable) {
  const fs::path path = dir_ / "killed.mcap";
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(ready[0]);
    try {
      WriterOptions options;
      options.compression = Compression::zstd;
      options.chunk_bytes = 200;
      Writer w(path.string(), options);
      const auto channel = w.add_channel(0, "/t", "json");
      const std::uint64_t start = w.bytes_written();
      std::uint32_t written = 0;
      for (; w.bytes_written() == start; ++written) w.write(channel, written, written, 0, "{}");
      w.attach(1, 2, "a.txt", "text/plain", "hello");
      w.write(channel, written, written, 0, "{\"lost\":1}");  // (in the open chunk: lost)
      (void)!::write(ready[1], &written, sizeof written);
      for (;;) ::pause();  // killed here, the writer open
    } catch (...) {}
    ::_exit(1);
  }
  ::close(ready[1]);
  std::uint32_t written = 0;
  const bool told = ::read(ready[0], &written, sizeof written) == sizeof written;
  ::close(ready[0]);
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(told) << "the child wrote its chunk";
  ASSERT_TRUE(WIFSIGNALED(status));

  const ReadBack back = read_all(path);
  EXPECT_FALSE(back.complete);
  EXPECT_EQ(back.end_offset, fs::file_size(path));
  EXPECT_NE(back.truncation.find("without Data End"), std::string::npos) << back.truncation;
  ASSERT_EQ(back.messages.size(), written);
  EXPECT_EQ(back.messages.back().log_time, written - 1);
  ASSERT_TRUE(std::holds_alternative<Attachment>(back.items.back()));
  EXPECT_EQ(std::get<Attachment>(back.items.back()).data, "hello");
}

}  // namespace
}  // namespace simgate::mcap
