// simgate/sim/allowed_files.h — the files a client may name: those under the directories a
// deployment allows (`spawn.allowed_dirs`), which `simulation spawn_entity` reads fragments
// from and `simulation create_world` scenes from. A client never reads elsewhere, links
// resolved: a file outside is as one that does not exist.
#ifndef SIMGATE_SIM_ALLOWED_FILES_H_
#define SIMGATE_SIM_ALLOWED_FILES_H_

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace simgate::sim {

// The regular file `path` names: absolute, or relative to one of `allowed` (canonical
// directories; the first that has it), and inside one of them once links are resolved.
// nullopt when there is none (or `path` is empty, over 4096 bytes or holds a NUL). Only
// looks: reads nothing.
std::optional<std::filesystem::path> find_allowed_file(const std::vector<std::string>& allowed,
                                                       const std::string& path);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_ALLOWED_FILES_H_
