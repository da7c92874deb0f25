// The PNG and base64 writers (image_codec.h): RFC 4648's test vectors, and PNG files that
// decode (camera_png.h: CRCs, IHDR, zlib inflate) back to the pixels given.
#include <gtest/gtest.h>

#include <stdexcept>

#include "camera_png.h"
#include "simgate/sim/image_codec.h"

namespace simgate::sim {
namespace {

using testing::decode_base64;
using testing::decode_png;

std::string b64(const std::string& s) {
  return base64_encode({reinterpret_cast<const std::uint8_t*>(s.data()), s.size()});
}

TEST(CameraCodecTest, Base64MatchesRfc4648Vectors) {
  EXPECT_EQ(b64(""), "");
  EXPECT_EQ(b64("f"), "Zg==");
  EXPECT_EQ(b64("fo"), "Zm8=");
  EXPECT_EQ(b64("foo"), "Zm9v");
  EXPECT_EQ(b64("foob"), "Zm9vYg==");
  EXPECT_EQ(b64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(b64("foobar"), "Zm9vYmFy");
}

TEST(CameraCodecTest, Base64UsesTheWholeAlphabet) {
  std::vector<std::uint8_t> all(256);
  for (int i = 0; i < 256; ++i) all[i] = static_cast<std::uint8_t>(i);
  const std::string text = base64_encode(all);
  EXPECT_EQ(text.size(), 344u);
  EXPECT_EQ(text.substr(0, 8), "AAECAwQF");
  EXPECT_EQ(text.substr(text.size() - 8), "/P3+/w==");  // both 62 and 63, and padding
  EXPECT_EQ(decode_base64(text), all);
}

TEST(CameraCodecTest, Rgb8PngDecodesToItsPixels) {
  const int w = 7, h = 5;  // odd sizes: rows are not multiples of anything
  std::vector<std::uint8_t> rgb(w * h * 3);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<std::uint8_t>(i * 37 + 11);
  const auto file = encode_png_rgb8(rgb, w, h);
  const auto png = decode_png(file);
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.width, w);
  EXPECT_EQ(png.height, h);
  EXPECT_EQ(png.bit_depth, 8);
  EXPECT_EQ(png.colour_type, 2);
  EXPECT_EQ(png.chunks, 3);
  EXPECT_EQ(png.pixels, rgb);
}

TEST(CameraCodecTest, Gray16PngStoresBigEndianSamples) {
  const std::vector<std::uint16_t> gray = {0, 1, 0x1234, 65535, 1700, 300};
  const auto png = decode_png(encode_png_gray16(gray, 3, 2));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.bit_depth, 16);
  EXPECT_EQ(png.colour_type, 0);
  ASSERT_EQ(png.pixels.size(), 12u);
  EXPECT_EQ(png.pixels[4], 0x12);
  EXPECT_EQ(png.pixels[5], 0x34);
  for (std::size_t i = 0; i < gray.size(); ++i)
    EXPECT_EQ((png.pixels[2 * i] << 8) | png.pixels[2 * i + 1], gray[i]);
}

TEST(CameraCodecTest, PngRefusesMismatchedSizes) {
  std::vector<std::uint8_t> rgb(10);
  EXPECT_THROW(encode_png_rgb8(rgb, 2, 2), std::invalid_argument);
  EXPECT_THROW(encode_png_rgb8({}, 0, 0), std::invalid_argument);
  std::vector<std::uint16_t> gray(4);
  EXPECT_THROW(encode_png_gray16(gray, 3, 2), std::invalid_argument);
}

}  // namespace
}  // namespace simgate::sim
