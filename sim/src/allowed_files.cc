#include "simgate/sim/allowed_files.h"

#include <algorithm>

namespace simgate::sim {

namespace fs = std::filesystem;

std::optional<fs::path> find_allowed_file(const std::vector<std::string>& allowed,
                                          const std::string& path) {
  if (path.empty() || path.size() > 4096 || path.find('\0') != std::string::npos)
    return std::nullopt;
  std::vector<fs::path> candidates;
  if (fs::path(path).is_absolute())
    candidates.push_back(path);
  else
    for (const auto& dir : allowed) candidates.push_back(fs::path(dir) / path);
  for (const fs::path& candidate : candidates) {
    std::error_code ec;
    const fs::path file = fs::canonical(candidate, ec);
    if (ec || !fs::is_regular_file(file, ec)) continue;
    const std::string f = file.string();
    const bool inside = std::any_of(allowed.begin(), allowed.end(), [&](const std::string& dir) {
      return f.size() > dir.size() && f.compare(0, dir.size(), dir) == 0 && f[dir.size()] == '/';
    });
    if (inside) return file;
  }
  return std::nullopt;
}

}  // namespace simgate::sim
