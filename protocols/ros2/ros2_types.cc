// The ROS 2 types announced by name only. See ros2_types.h.
#include "ros2_types.h"

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

namespace simgate::ros2 {

const dds_topic_descriptor_t* name_only(const dds_topic_descriptor_t& generated,
                                        const char* type_name) {
  static std::mutex mutex;
  static std::map<std::pair<const dds_topic_descriptor_t*, std::string>,
                  std::unique_ptr<dds_topic_descriptor_t>>
      copies;
  const char* name = type_name ? type_name : generated.m_typename;
  std::lock_guard lock(mutex);
  auto& copy = copies[{&generated, name}];
  if (!copy)
    copy.reset(new dds_topic_descriptor_t{generated.m_size,
                                          generated.m_align,
                                          generated.m_flagset & ~DDS_TOPIC_XTYPES_METADATA,
                                          generated.m_nkeys,
                                          name,
                                          generated.m_keys,
                                          generated.m_nops,
                                          generated.m_ops,
                                          generated.m_meta,
                                          {nullptr, 0},
                                          {nullptr, 0},
                                          generated.restrict_data_representation});
  return copy.get();
}

}  // namespace simgate::ros2
