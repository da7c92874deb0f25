// simgate/sim/image_codec.h — images as bytes a JSON reply can carry: PNG and base64.
//
// encode_png writes a PNG file (W3C PNG, 2nd edition) of one image: 8-bit RGB (colour
// type 2) or 16-bit grayscale (colour type 0), no interlace, deflate-compressed by zlib
// with filter type None on every row. Rows are given top row first, as PNG stores them.
// The PNG goes into JSON as base64 (simgate/core/base64.h), as MORSE's cameras put theirs.
//
// Pure functions, no MuJoCo: callable from any thread (the render thread encodes).
#ifndef SIMGATE_SIM_IMAGE_CODEC_H_
#define SIMGATE_SIM_IMAGE_CODEC_H_

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/base64.h"

namespace simgate::sim {

// A PNG of `width` x `height` 8-bit RGB pixels (3 bytes per pixel, rows top first).
// Throws std::invalid_argument when the sizes do not match or are not positive.
std::vector<std::uint8_t> encode_png_rgb8(std::span<const std::uint8_t> rgb, int width, int height);
// A PNG of `width` x `height` 16-bit grayscale samples (rows top first, host order; the
// file stores them big-endian as PNG requires).
std::vector<std::uint8_t> encode_png_gray16(std::span<const std::uint16_t> gray, int width,
                                            int height);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_IMAGE_CODEC_H_
