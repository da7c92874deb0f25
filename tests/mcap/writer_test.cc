// The MCAP writer (simgate/mcap/writer.h) on its own: the file's frame as the specification
// lays it out (magic, Header first, Data End, the footer pointing at the summary and its
// offsets, the magic last), a file with no message still whole, and mistakes refused with
// the reason. (That readers nobody on the team wrote read the files, seek in them and check
// their CRCs is mcap_reader_test.js's, with @mcap/core, and mcap_pypi_reader_test.py's, with
// PyPI's mcap; that the team's reader reads them back, also when cut short, reader_test.cc's.)
#include "simgate/mcap/writer.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <string>
#include <unistd.h>

namespace simgate::mcap {
namespace {

namespace fs = std::filesystem;

std::uint64_t le(const std::string& bytes, std::size_t at, int size) {
  std::uint64_t v = 0;
  for (int i = size - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
  return v;
}

class McapWriterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("simgate-mcap-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string read(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  // The opcodes of the records from `at` to `end`, in order.
  static std::vector<int> opcodes(const std::string& file, std::size_t at, std::size_t end) {
    std::vector<int> out;
    while (at + 9 <= end) {
      out.push_back(static_cast<unsigned char>(file[at]));
      at += 9 + le(file, at + 1, 8);
    }
    return out;
  }
  fs::path dir_;
};

TEST_F(McapWriterTest, TheFileIsFramedAsTheSpecificationSays) {
  const fs::path path = dir_ / "framed.mcap";
  {
    WriterOptions options;
    options.compression = Compression::none;
    options.chunk_bytes = 64;  // a chunk every message or two
    Writer w(path.string(), options);
    const auto schema = w.add_schema("s", "jsonschema", "{}");
    const auto channel = w.add_channel(schema, "/t", "json");
    for (std::uint32_t i = 0; i < 10; ++i) w.write(channel, i, 100 + i, 100 + i, "{\"x\":1}");
    w.attach(5, 0, "a.txt", "text/plain", "hello");
    w.add_metadata("m", {{"k", "v"}});
    w.close();
    EXPECT_EQ(w.message_count(), 10u);
  }
  const std::string file = read(path);
  const std::string magic("\x89MCAP0\r\n", 8);
  ASSERT_GT(file.size(), 16u);
  EXPECT_EQ(file.substr(0, 8), magic);
  EXPECT_EQ(file.substr(file.size() - 8), magic);
  // the footer: the last record before the magic, 20 bytes of content
  const std::size_t footer = file.size() - 8 - (9 + 20);
  ASSERT_EQ(static_cast<unsigned char>(file[footer]), 0x02);
  const std::uint64_t summary_start = le(file, footer + 9, 8);
  const std::uint64_t offsets_start = le(file, footer + 17, 8);
  ASSERT_GT(summary_start, 0u);
  ASSERT_GT(offsets_start, summary_start);
  // the data section: the Header first, chunks each followed by its message index, the
  // attachment and the metadata between chunks, Data End last
  const std::vector<int> data = opcodes(file, 8, summary_start);
  ASSERT_FALSE(data.empty());
  EXPECT_EQ(data.front(), 0x01);
  EXPECT_EQ(data.back(), 0x0F);
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (data[i] == 0x06) {
      EXPECT_EQ(data[i + 1], 0x07) << "a chunk's message index follows it";
    }
  }
  EXPECT_EQ(std::count(data.begin(), data.end(), 0x09), 1);
  EXPECT_EQ(std::count(data.begin(), data.end(), 0x0C), 1);
  // the summary: schemas, channels, chunk indexes, attachment and metadata indexes,
  // statistics; then one summary offset per group
  const std::vector<int> summary = opcodes(file, summary_start, offsets_start);
  EXPECT_EQ(summary.front(), 0x03);
  EXPECT_EQ(std::count(summary.begin(), summary.end(), 0x08),
            std::count(data.begin(), data.end(), 0x06));
  EXPECT_EQ(summary.back(), 0x0B);
  const std::vector<int> offsets = opcodes(file, offsets_start, footer);
  EXPECT_EQ(offsets.size(), 6u);  // schema, channel, chunk index, attachment/metadata index, stats
  for (int op : offsets) EXPECT_EQ(op, 0x0E);
}

TEST_F(McapWriterTest, AFileWithoutMessagesIsWholeToo) {
  const fs::path path = dir_ / "empty.mcap";
  Writer(path.string(), WriterOptions{}).close();
  const std::string file = read(path);
  const std::vector<int> records = opcodes(file, 8, file.size() - 8);
  ASSERT_GE(records.size(), 3u);
  EXPECT_EQ(records.front(), 0x01);
  EXPECT_EQ(records.back(), 0x02);
  EXPECT_NE(std::find(records.begin(), records.end(), 0x0F), records.end());
}

TEST_F(McapWriterTest, MistakesAreRefusedWithTheReason) {
  try {
    Writer w((dir_ / "no" / "such" / "dir.mcap").string(), WriterOptions{});
    FAIL() << "a file in a directory that does not exist";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("dir.mcap"), std::string::npos) << e.what();
  }
  Writer w((dir_ / "mistakes.mcap").string(), WriterOptions{});
  EXPECT_THROW(w.write(0, 0, 0, 0, "{}"), std::invalid_argument);       // no channel yet
  EXPECT_THROW(w.add_channel(3, "/t", "json"), std::invalid_argument);  // no schema 3
  const auto none = w.add_channel(0, "/raw", "json");                   // schema 0: none, allowed
  w.write(none, 0, 1, 1, "{}");
  w.close();
  w.close();  // idempotent
  EXPECT_EQ(w.message_count(), 1u);
}

}  // namespace
}  // namespace simgate::mcap
