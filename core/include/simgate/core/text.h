// simgate/core/text.h — small text helpers shared by every layer (messages, logs).
// Pure functions; any thread.
#ifndef SIMGATE_CORE_TEXT_H_
#define SIMGATE_CORE_TEXT_H_

#include <string>
#include <vector>

namespace simgate {

// The items with `separator` between them: join({"a", "b", "c"}) is "a, b, c".
inline std::string join(const std::vector<std::string>& items, const std::string& separator = ", ") {
  std::string out;
  for (const auto& item : items) {
    if (!out.empty()) out += separator;
    out += item;
  }
  return out;
}

}  // namespace simgate

#endif  // SIMGATE_CORE_TEXT_H_
