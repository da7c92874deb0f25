// The PNG writer (image_codec.h). A PNG file is its 8-byte signature and chunks,
// each: length (4 bytes, big-endian), type (4 ASCII), data, CRC-32 of type and data.
// IHDR gives the size and pixel format, IDAT the zlib stream of the filtered rows (each
// row prefixed by its filter type, 0 = None here), IEND closes the file.
#include "simgate/sim/image_codec.h"

#include <zlib.h>

#include <stdexcept>
#include <string>

namespace simgate::sim {

namespace {

constexpr std::uint8_t k_png_signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
// zlib level: a camera encodes every frame, so speed over the last few percent of size
constexpr int k_deflate_level = 3;

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  out.push_back(static_cast<std::uint8_t>(v >> 24));
  out.push_back(static_cast<std::uint8_t>(v >> 16));
  out.push_back(static_cast<std::uint8_t>(v >> 8));
  out.push_back(static_cast<std::uint8_t>(v));
}

void put_chunk(std::vector<std::uint8_t>& out, const char (&type)[5], const std::uint8_t* data,
               std::size_t size) {
  put_u32(out, static_cast<std::uint32_t>(size));
  const std::size_t start = out.size();
  out.insert(out.end(), type, type + 4);
  if (size > 0) out.insert(out.end(), data, data + size);
  // the CRC covers the type and the data
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, out.data() + start, static_cast<uInt>(out.size() - start));
  put_u32(out, static_cast<std::uint32_t>(crc));
}

void check_size(std::size_t samples, int width, int height, int per_pixel, const char* what) {
  if (width <= 0 || height <= 0)
    throw std::invalid_argument(std::string("PNG ") + what +
                                ": width and height must be positive, found " +
                                std::to_string(width) + "x" + std::to_string(height));
  if (samples != static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * per_pixel)
    throw std::invalid_argument(std::string("PNG ") + what + ": " + std::to_string(samples) +
                                " samples for " + std::to_string(width) + "x" +
                                std::to_string(height));
}

// The file for `raw`: the rows already prefixed by their filter byte.
std::vector<std::uint8_t> png_file(const std::vector<std::uint8_t>& raw, int width, int height,
                                   int bit_depth, int colour_type) {
  // IHDR: width, height, bit depth, colour type, compression 0, filter 0, interlace 0
  std::vector<std::uint8_t> ihdr;
  put_u32(ihdr, static_cast<std::uint32_t>(width));
  put_u32(ihdr, static_cast<std::uint32_t>(height));
  ihdr.insert(ihdr.end(), {static_cast<std::uint8_t>(bit_depth),
                           static_cast<std::uint8_t>(colour_type), 0, 0, 0});

  uLongf packed_size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<std::uint8_t> packed(packed_size);
  if (compress2(packed.data(), &packed_size, raw.data(), static_cast<uLong>(raw.size()),
                k_deflate_level) != Z_OK)
    throw std::runtime_error("PNG: zlib could not compress the image");

  std::vector<std::uint8_t> out(std::begin(k_png_signature), std::end(k_png_signature));
  out.reserve(packed_size + 64);
  put_chunk(out, "IHDR", ihdr.data(), ihdr.size());
  put_chunk(out, "IDAT", packed.data(), packed_size);
  put_chunk(out, "IEND", nullptr, 0);
  return out;
}

}  // namespace

std::vector<std::uint8_t> encode_png_rgb8(std::span<const std::uint8_t> rgb, int width,
                                          int height) {
  check_size(rgb.size(), width, height, 3, "rgb8");
  const std::size_t row = static_cast<std::size_t>(width) * 3;
  std::vector<std::uint8_t> raw;
  raw.reserve((row + 1) * static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) {
    raw.push_back(0);  // filter: None
    const std::uint8_t* start = rgb.data() + row * static_cast<std::size_t>(y);
    raw.insert(raw.end(), start, start + row);
  }
  return png_file(raw, width, height, 8, 2);
}

std::vector<std::uint8_t> encode_png_gray16(std::span<const std::uint16_t> gray, int width,
                                            int height) {
  check_size(gray.size(), width, height, 1, "gray16");
  std::vector<std::uint8_t> raw;
  raw.reserve((static_cast<std::size_t>(width) * 2 + 1) * static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) {
    raw.push_back(0);  // filter: None
    for (int x = 0; x < width; ++x) {
      const std::uint16_t v =
          gray[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + x];
      raw.push_back(static_cast<std::uint8_t>(v >> 8));  // PNG samples are big-endian
      raw.push_back(static_cast<std::uint8_t>(v));
    }
  }
  return png_file(raw, width, height, 16, 0);
}

}  // namespace simgate::sim
