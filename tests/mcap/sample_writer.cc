// mcap_sample_writer PATH COMPRESSION: writes the MCAP file mcap_reader_test.js reads with
// @mcap/core (a reader nobody on the team wrote): 2 schemas, 3 channels, 5000 messages over
// many small chunks (16 KiB), their log times 1 ms apart and round-robin over the channels
// (channel 2 every other turn: counts differ), publish time = log time + 1, each message
// {"i": i}; an attachment "config.json" and a metadata record "simgate" between the chunks.
// COMPRESSION: none, zstd or lz4.
#include <iostream>
#include <string>

#include "simgate/mcap/writer.h"

int main(int argc, char** argv) {
  using namespace simgate::mcap;
  if (argc != 3) {
    std::cerr << "usage: mcap_sample_writer PATH none|zstd|lz4\n";
    return 2;
  }
  const std::string kind = argv[2];
  WriterOptions options;
  options.compression = kind == "zstd"  ? Compression::zstd
                        : kind == "lz4" ? Compression::lz4
                                        : Compression::none;
  options.chunk_bytes = 16 * 1024;
  try {
    Writer w(argv[1], options);
    const auto pose = w.add_schema("simgate.pose", "jsonschema",
                                   R"({"type":"object","properties":{"i":{"type":"integer"}}})");
    const auto other = w.add_schema("simgate.other", "jsonschema", R"({"type":"object"})");
    const std::uint16_t channels[3] = {
        w.add_channel(pose, "/robot/pose", "json", {{"component", "robot.pose"}}),
        w.add_channel(pose, "/human/pose", "json"), w.add_channel(other, "/simulation", "json")};
    std::uint32_t sequence[3] = {0, 0, 0};
    for (std::uint64_t i = 0; i < 5000; ++i) {
      if (i == 2500) {
        w.attach(i * 1'000'000, 7, "config.json", "application/json", R"({"scene": "demo.xml"})");
        w.add_metadata("simgate", {{"version", "0.1.0"}, {"mujoco", "4.0.0"}});
      }
      std::size_t c = i % 4;  // 0, 1, 2, 0: channel 0 twice as often
      if (c == 3) c = 0;
      const std::uint64_t t = 1'000'000'000 + i * 1'000'000;
      w.write(channels[c], ++sequence[c], t, t + 1, "{\"i\":" + std::to_string(i) + "}");
    }
    w.close();
    std::cout << w.bytes_written() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "mcap_sample_writer: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
