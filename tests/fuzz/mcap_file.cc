// Fuzz target mcap_file: a recording that `simgate replay` (or a test) opens, read by the MCAP
// reader (protocols/mcap/reader.h) from the first record to the last: a file from anywhere
// (a download, a crash's leftovers, a forgery) is untrusted input.
//
// Properties: nothing but mcap::ReadError is thrown, and its offset lies inside the file; the
// reader ends (next() returns false) after at most one item per byte; a message's channel was
// handed over before it; a file read to its end is complete() or says where it is cut
// (truncation() names an offset within the file); records longer than the file allocate
// nothing (ASan's RSS limit would tell).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <set>
#include <string>
#include <variant>

#include "fuzz_support.h"
#include "simgate/mcap/reader.h"

namespace simgate::fuzz {
namespace {

// The file the reader opens: one per process, rewritten for each input (tmpfs when there).
const std::string& scratch_path() {
  static const std::string path = [] {
    const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    return std::string(dir) + "/simgate-fuzz-mcap-" + std::to_string(getpid()) + ".mcap";
  }();
  return path;
}

void read_all(std::size_t size) {
  mcap::Reader reader(scratch_path());
  mcap::Item item;
  std::set<std::uint16_t> channels;
  std::size_t items = 0;
  while (reader.next(item)) {
    FUZZ_CHECK(++items <= size, "at most one item per byte of the file");
    if (const auto* c = std::get_if<mcap::Channel>(&item)) channels.insert(c->id);
    if (const auto* m = std::get_if<mcap::Message>(&item))
      FUZZ_CHECK(channels.contains(m->channel_id) && reader.channel(m->channel_id),
                 "a message's channel was handed over before it");
  }
  FUZZ_CHECK(!reader.next(item), "the end stays the end");
  FUZZ_CHECK(reader.end_offset() <= size, "the reader stops inside the file");
  if (!reader.complete()) FUZZ_CHECK(!reader.truncation().empty(), "a cut file says where");
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate;
  const std::string& path = fuzz::scratch_path();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return 0;
  const bool written = std::fwrite(data, 1, size, f) == size;
  std::fclose(f);
  if (!written) return 0;
  try {
    fuzz::read_all(size);
  } catch (const mcap::ReadError& e) {
    FUZZ_CHECK(e.offset() <= size, "an error's offset lies inside the file");
    FUZZ_CHECK(std::string(e.what()).find(path) != std::string::npos, "an error names the file");
  }
  return 0;
}
