// request_worlds.h — what a transport's RequestManager keeps of the worlds it routes to
// (issue #43): private to core/src (request_manager.cc, request_manager_worlds.cc).
#ifndef SIMGATE_CORE_SRC_REQUEST_WORLDS_H_
#define SIMGATE_CORE_SRC_REQUEST_WORLDS_H_

#include <map>
#include <memory>
#include <mutex>
#include <unordered_map>

#include "simgate/core/request_manager.h"

namespace simgate {

struct RequestManager::Worlds {
  mutable std::mutex mutex;                                      // guards both maps
  std::map<unsigned, std::shared_ptr<RequestManager>> managers;  // world -> its manager
  // calls sent to a world and not answered yet: where a cancel goes
  std::unordered_map<RequestId, std::shared_ptr<RequestManager>> sent;

  std::shared_ptr<RequestManager> find(unsigned world) const {
    std::lock_guard lock(mutex);
    auto it = managers.find(world);
    return it == managers.end() ? nullptr : it->second;
  }
};

}  // namespace simgate

#endif  // SIMGATE_CORE_SRC_REQUEST_WORLDS_H_
