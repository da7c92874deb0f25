// Test helper: reads back what the cameras write — base64 (RFC 4648) and PNG files of the
// kind image_codec.h writes (8-bit RGB or 16-bit grayscale, no interlace), checking every
// chunk's CRC and inflating the IDAT data with zlib. Independent of the encoder's code.
#ifndef SIMGATE_TESTS_SIM_CAMERA_PNG_H_
#define SIMGATE_TESTS_SIM_CAMERA_PNG_H_

#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace simgate::sim::testing {

// Bytes of a base64 text; stops at the first character outside the alphabet ('=').
inline std::vector<std::uint8_t> decode_base64(const std::string& text) {
  std::vector<std::uint8_t> out;
  std::uint32_t bits = 0;
  int count = 0;
  for (char ch : text) {
    int v;
    if (ch >= 'A' && ch <= 'Z')
      v = ch - 'A';
    else if (ch >= 'a' && ch <= 'z')
      v = ch - 'a' + 26;
    else if (ch >= '0' && ch <= '9')
      v = ch - '0' + 52;
    else if (ch == '+')
      v = 62;
    else if (ch == '/')
      v = 63;
    else
      break;
    bits = (bits << 6) | static_cast<std::uint32_t>(v);
    count += 6;
    if (count >= 8) {
      count -= 8;
      out.push_back(static_cast<std::uint8_t>(bits >> count));
    }
  }
  return out;
}

struct DecodedPng {
  std::string error;  // non-empty: what was wrong with the file
  int width = 0, height = 0, bit_depth = 0, colour_type = 0;
  std::vector<std::uint8_t> pixels;  // the rows without their filter bytes, top first
  int chunks = 0;                    // chunks read (IHDR, IDAT..., IEND)
};

inline std::uint32_t read_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         p[3];
}

inline DecodedPng decode_png(const std::vector<std::uint8_t>& file) {
  DecodedPng png;
  static const std::uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (file.size() < 8 || std::memcmp(file.data(), signature, 8) != 0)
    return png.error = "no PNG signature", png;
  std::vector<std::uint8_t> packed;
  bool ended = false;
  for (std::size_t at = 8; at < file.size() && !ended;) {
    if (at + 12 > file.size()) return png.error = "truncated chunk", png;
    const std::uint32_t length = read_u32(&file[at]);
    if (at + 12 + length > file.size()) return png.error = "chunk longer than the file", png;
    const std::string type(reinterpret_cast<const char*>(&file[at + 4]), 4);
    const std::uint8_t* data = &file[at + 8];
    const uLong crc = crc32(crc32(0L, Z_NULL, 0), &file[at + 4], length + 4);
    if (crc != read_u32(data + length)) return png.error = "bad CRC in chunk " + type, png;
    ++png.chunks;
    if (type == "IHDR") {
      if (length != 13) return png.error = "IHDR of " + std::to_string(length) + " bytes", png;
      png.width = static_cast<int>(read_u32(data));
      png.height = static_cast<int>(read_u32(data + 4));
      png.bit_depth = data[8];
      png.colour_type = data[9];
      if (data[10] != 0 || data[11] != 0 || data[12] != 0)
        return png.error = "unexpected IHDR methods", png;
    } else if (type == "IDAT") {
      packed.insert(packed.end(), data, data + length);
    } else if (type == "IEND") {
      ended = true;
    }
    at += 12 + length;
  }
  if (!ended) return png.error = "no IEND", png;
  const int channels = png.colour_type == 2 ? 3 : png.colour_type == 0 ? 1 : 0;
  if (channels == 0) return png.error = "colour type " + std::to_string(png.colour_type), png;
  const std::size_t row = static_cast<std::size_t>(png.width) * channels * (png.bit_depth / 8);
  std::vector<std::uint8_t> raw((row + 1) * static_cast<std::size_t>(png.height));
  uLongf raw_size = raw.size();
  if (uncompress(raw.data(), &raw_size, packed.data(), packed.size()) != Z_OK ||
      raw_size != raw.size())
    return png.error = "IDAT does not inflate to the image's size", png;
  for (int y = 0; y < png.height; ++y) {
    const std::uint8_t* r = &raw[static_cast<std::size_t>(y) * (row + 1)];
    if (r[0] != 0)
      return png.error = "filter type " + std::to_string(r[0]) + " (only None is written)", png;
    png.pixels.insert(png.pixels.end(), r + 1, r + 1 + row);
  }
  return png;
}

}  // namespace simgate::sim::testing

#endif  // SIMGATE_TESTS_SIM_CAMERA_PNG_H_
