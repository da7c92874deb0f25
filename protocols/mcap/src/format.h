// protocols/mcap/src/format.h — what writer.cc and reader.cc share of MCAP's specification:
// the magic, the records' opcodes and the CRC-32 every checksum of the format uses (zlib's).
// Private to simgate_protocol_mcap.
#ifndef SIMGATE_MCAP_FORMAT_H_
#define SIMGATE_MCAP_FORMAT_H_

#include <algorithm>
#include <cstdint>
#include <string_view>

#include <zlib.h>

namespace simgate::mcap::format {

// The 8 bytes that open and close every file ('0': major version 0).
inline constexpr std::string_view k_magic{"\x89MCAP0\r\n", 8};
// A record's opcode (1 byte) and content length (uint64): what precedes its content.
inline constexpr std::uint64_t k_record_prefix = 9;

// Opcodes (the specification's records; 0x00 is not valid).
enum Op : std::uint8_t {
  header = 0x01,
  footer = 0x02,
  schema = 0x03,
  channel = 0x04,
  message = 0x05,
  chunk = 0x06,
  message_index = 0x07,
  chunk_index = 0x08,
  attachment = 0x09,
  attachment_index = 0x0A,
  statistics = 0x0B,
  metadata = 0x0C,
  metadata_index = 0x0D,
  summary_offset = 0x0E,
  data_end = 0x0F,
};

// CRC-32 (zlib's: ISO-HDLC) of `bytes`, continuing `crc`.
inline std::uint32_t crc32_of(std::string_view bytes, std::uint32_t crc = 0) {
  uLong c = crc;
  while (!bytes.empty()) {  // zlib takes at most 4 GiB a call
    const auto n = static_cast<uInt>(std::min<std::size_t>(bytes.size(), 1u << 30));
    c = ::crc32(c, reinterpret_cast<const Bytef*>(bytes.data()), n);
    bytes.remove_prefix(n);
  }
  return static_cast<std::uint32_t>(c);
}

}  // namespace simgate::mcap::format

#endif  // SIMGATE_MCAP_FORMAT_H_
