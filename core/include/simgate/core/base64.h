// simgate/core/base64.h — RFC 4648's base64 (standard alphabet, '=' padding, no line
// breaks): how bytes (a camera's PNG, raw pixels) travel inside JSON text.
//
// Pure functions: any thread.
#ifndef SIMGATE_CORE_BASE64_H_
#define SIMGATE_CORE_BASE64_H_

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace simgate {

// The base64 text of `bytes`.
std::string base64_encode(std::span<const std::uint8_t> bytes);
// The bytes of base64 text. Throws std::invalid_argument on a character outside the
// alphabet or a length that is not a multiple of 4.
std::vector<std::uint8_t> base64_decode(std::string_view text);

}  // namespace simgate

#endif  // SIMGATE_CORE_BASE64_H_
