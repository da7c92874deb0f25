// simgate/ros2 types — the ROS 2 message types of ros2_msgs.idl as the ros2 transport gives
// them to Cyclone: named as ROS 2 names them, announced by name only, as rmw_cyclonedds
// announces its own.
//
// idlc adds XTypes type information to every descriptor it generates; rmw_cyclonedds
// announces none (its endpoints match by type name alone). A participant that announces type
// information makes its peers, and itself, look types up by their ids; Cyclone 0.10 (Debian
// 12's) fails on some peers' answers (a Cyclone 11 peer's type objects end in a crash of
// its type-lookup thread). name_only() returns the generated descriptor without it: the
// endpoints match as a ROS 2 node's do, by name, and no type is ever looked up.
//
// Threads: any; the copies live as long as the process.
#ifndef SIMGATE_PROTOCOLS_ROS2_ROS2_TYPES_H_
#define SIMGATE_PROTOCOLS_ROS2_ROS2_TYPES_H_

#include <dds/dds.h>

namespace simgate::ros2 {

// `generated` (an idlc descriptor) without its XTypes type information: the same type, keys
// and CDR, announced by name only: its own, or `type_name` (a static string) when given. One
// copy per descriptor and name, made on first use.
const dds_topic_descriptor_t* name_only(const dds_topic_descriptor_t& generated,
                                        const char* type_name = nullptr);

}  // namespace simgate::ros2

#endif  // SIMGATE_PROTOCOLS_ROS2_ROS2_TYPES_H_
