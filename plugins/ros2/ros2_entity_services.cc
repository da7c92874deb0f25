// The ros2 transport's services on entities (simulation_interfaces): get_entities (filtered by
// name), get_entities_states, get_entity_state, set_entity_state, get_entity_info,
// get_entity_bounds, spawn_entity and delete_entity, each mapped onto `simulation` calls
// (list_entities, get_entity_state, set_entity_state, list_robots, get_object_bbox,
// spawn_entity, delete_entity) and their outcomes onto the standard's results and
// EntityStates. The services made, and the simulation's own: ros2_sim_services.cc.
#include <memory>
#include <optional>
#include <set>

#include "ros2_mapping.h"
#include "ros2_service_replies.h"
#include "ros2_services.h"
#include "ros2_srvs.h"

namespace simgate::ros2 {

namespace {

using EntitiesRequest = simulation_interfaces_srv_dds__GetEntities_Request_;
using EntitiesResponse = simulation_interfaces_srv_dds__GetEntities_Response_;
using EntitiesStatesRequest = simulation_interfaces_srv_dds__GetEntitiesStates_Request_;
using EntitiesStatesResponse = simulation_interfaces_srv_dds__GetEntitiesStates_Response_;
using EntityStateRequest = simulation_interfaces_srv_dds__GetEntityState_Request_;
using EntityStateResponse = simulation_interfaces_srv_dds__GetEntityState_Response_;
using SetEntityStateRequest = simulation_interfaces_srv_dds__SetEntityState_Request_;
using SetEntityStateResponse = simulation_interfaces_srv_dds__SetEntityState_Response_;
using EntityInfoRequest = simulation_interfaces_srv_dds__GetEntityInfo_Request_;
using EntityInfoResponse = simulation_interfaces_srv_dds__GetEntityInfo_Response_;
using EntityBoundsRequest = simulation_interfaces_srv_dds__GetEntityBounds_Request_;
using EntityBoundsResponse = simulation_interfaces_srv_dds__GetEntityBounds_Response_;
using SpawnRequest = simulation_interfaces_srv_dds__SpawnEntity_Request_;
using SpawnResponse = simulation_interfaces_srv_dds__SpawnEntity_Response_;
using DeleteRequest = simulation_interfaces_srv_dds__DeleteEntity_Request_;
using DeleteResponse = simulation_interfaces_srv_dds__DeleteEntity_Response_;
using EntityState = simulation_interfaces_msg_dds__EntityState_;
using EntityFilters = simulation_interfaces_msg_dds__EntityFilters_;

void set_header(std_msgs_msg_dds__Header_& header, double sim_time, const std::string& frame) {
  const RosTime t = to_ros_time(sim_time);
  header.stamp.sec = t.sec;
  header.stamp.nanosec = t.nanosec;
  header.frame_id = dup(frame);
}

// An EntityState from `motion`; empty strings where there is nothing (every string set: a
// null one is not serialisable).
void fill_entity_state(EntityState& out, const EntityMotion& motion, double sim_time,
                       const std::string& frame) {
  set_header(out.header, sim_time, frame);
  out.pose.position = {motion.position[0], motion.position[1], motion.position[2]};
  out.pose.orientation = {motion.orientation[0], motion.orientation[1], motion.orientation[2],
                          motion.orientation[3]};
  out.twist.linear = {motion.linear[0], motion.linear[1], motion.linear[2]};
  out.twist.angular = {motion.angular[0], motion.angular[1], motion.angular[2]};
  out.acceleration = {};  // not measured: zeros
}

bool in_world_frame(const char* frame_id, const std::string& world_frame) {
  const std::string frame = text(frame_id);
  return frame.empty() || frame == world_frame || frame == "/" + world_frame;
}

std::string frame_refusal(const char* frame_id, const std::string& world_frame) {
  return "frame_id '" + text(frame_id) + "': poses are in the world frame '" + world_frame +
         "' (or an empty frame_id)";
}

// The ROS pose as simgate's [x, y, z, qx, qy, qz, qw]; an all-zero quaternion (a message
// built without ROS 2's defaults) is the identity.
json pose_array(const geometry_msgs_msg_dds__Pose_& pose) {
  const auto& q = pose.orientation;
  const bool zero = q.x == 0 && q.y == 0 && q.z == 0 && q.w == 0;
  return json::array({pose.position.x, pose.position.y, pose.position.z, zero ? 0.0 : q.x,
                      zero ? 0.0 : q.y, zero ? 0.0 : q.z, zero ? 1.0 : q.w});
}

std::string parameter_of(const Outcome& outcome) {
  return outcome.data.is_object() ? outcome.data.value("parameter", "") : std::string();
}

}  // namespace

void Ros2Services::list_entities(
    const void* request_filters,
    std::function<void(ServiceResult, std::vector<std::string>)> done) {
  const auto& filters = *static_cast<const EntityFilters*>(request_filters);
  if (filters.categories._length > 0) {
    done(ServiceResult::fail(ResultCode::feature_unsupported,
                             "filters.categories: entity categories are not filtered here "
                             "(ENTITY_CATEGORIES is not among the features); leave it empty"),
         {});
    return;
  }
  if (filters.tags.tags._length > 0) {
    done(ServiceResult::fail(ResultCode::feature_unsupported,
                             "filters.tags: entities have no tags here (ENTITY_TAGS is not among "
                             "the features); leave it empty"),
         {});
    return;
  }
  if (filters.bounds.type != 0) {
    done(ServiceResult::fail(ResultCode::feature_unsupported,
                             "filters.bounds: entities are not filtered by bounds here; leave "
                             "its type TYPE_EMPTY"),
         {});
    return;
  }
  std::shared_ptr<EntityFilter> filter;
  try {
    filter = std::make_shared<EntityFilter>(text(filters.filter));
  } catch (const std::invalid_argument& e) {
    done(ServiceResult::fail(ResultCode::operation_failed, e.what()), {});
    return;
  }
  caller_(Call{"simulation", "list_entities", json{{"filter", ""}}},
          [filter, done](Outcome&& outcome) {
            ServiceResult result = result_of(outcome);
            std::vector<std::string> names;
            if (result.is_ok() && outcome.value && outcome.value->is_array()) {
              for (const json& name : *outcome.value)
                if (name.is_string() && filter->matches(name.get<std::string>()))
                  names.push_back(name.get<std::string>());
            }
            done(std::move(result), std::move(names));
          });
}

void Ros2Services::get_entities(const void* request, const ReplyTo& to) {
  list_entities(&static_cast<const EntitiesRequest*>(request)->filters,
                [this, to](ServiceResult result, std::vector<std::string> names) {
                  EntitiesResponse* response;
                  Sample reply = new_reply(to, response);
                  set_result(response->result, result);
                  set_strings(response->entities, names);
                  send(to, std::move(reply));
                });
}

void Ros2Services::get_entities_states(const void* request, const ReplyTo& to) {
  list_entities(&static_cast<const EntitiesStatesRequest*>(request)->filters,
                [this, to](ServiceResult result, std::vector<std::string> names) {
                  // every entity's state asked at once; the reply when the last has come (an entity
                  // deleted meanwhile is left out)
                  struct Gathered {
                    std::vector<std::string> names;
                    std::vector<std::optional<EntityMotion>> motions;
                    std::size_t waiting = 0;
                    ServiceResult result;
                  };
                  auto gathered = std::make_shared<Gathered>();
                  gathered->names = std::move(names);
                  gathered->motions.resize(gathered->names.size());
                  gathered->waiting = gathered->names.size();
                  gathered->result = std::move(result);
                  auto finish = [this, to, gathered] {
                    EntitiesStatesResponse* response;
                    Sample reply = new_reply(to, response);
                    std::vector<std::string> names;
                    std::vector<const EntityMotion*> motions;
                    for (std::size_t i = 0; i < gathered->names.size(); ++i) {
                      if (!gathered->motions[i]) continue;
                      names.push_back(gathered->names[i]);
                      motions.push_back(&*gathered->motions[i]);
                    }
                    set_result(response->result, gathered->result);
                    set_strings(response->entities, names);
                    EntityState* states = alloc_sequence(response->states, motions.size());
                    const double now = sim_time_();
                    for (std::size_t i = 0; i < motions.size(); ++i)
                      fill_entity_state(states[i], *motions[i], now, settings_.world_frame);
                    send(to, std::move(reply));
                  };
                  if (!gathered->result.is_ok() || gathered->waiting == 0) {
                    finish();
                    return;
                  }
                  for (std::size_t i = 0; i < gathered->names.size(); ++i) {
                    caller_(
                        Call{"simulation", "get_entity_state", json{{"name", gathered->names[i]}}},
                        [gathered, i, finish](Outcome&& outcome) {
                          EntityMotion motion;
                          if (outcome.status == Status::success && outcome.value &&
                              entity_motion(*outcome.value, motion))
                            gathered->motions[i] = motion;
                          if (--gathered->waiting == 0) finish();
                        });
                  }
                });
}

void Ros2Services::get_entity_state(const void* request, const ReplyTo& to) {
  const std::string entity = text(static_cast<const EntityStateRequest*>(request)->entity);
  caller_(Call{"simulation", "get_entity_state", json{{"name", entity}}},
          [this, to](Outcome&& outcome) {
            EntityStateResponse* response;
            Sample reply = new_reply(to, response);
            ServiceResult result = result_of(outcome, "name");
            EntityMotion motion;
            if (result.is_ok() && !(outcome.value && entity_motion(*outcome.value, motion)))
              result = ServiceResult::fail(
                  ResultCode::operation_failed,
                  "get_entity_state said " + (outcome.value ? outcome.value->dump() : "nothing"));
            set_result(response->result, result);
            fill_entity_state(response->state, motion, sim_time_(), settings_.world_frame);
            send(to, std::move(reply));
          });
}

void Ros2Services::set_entity_state(const void* request, const ReplyTo& to) {
  const auto& rq = *static_cast<const SetEntityStateRequest*>(request);
  auto reply_with = [this, to](ServiceResult result) {
    SetEntityStateResponse* response;
    Sample reply = new_reply(to, response);
    set_result(response->result, result);
    send(to, std::move(reply));
  };
  if (rq.set_acceleration) {
    reply_with(ServiceResult::fail(ResultCode::feature_unsupported,
                                   "set_acceleration: accelerations follow from the forces; "
                                   "set the pose and/or the twist"));
    return;
  }
  if (!in_world_frame(rq.state.header.frame_id, settings_.world_frame)) {
    reply_with(ServiceResult::fail(ResultCode::operation_failed,
                                   frame_refusal(rq.state.header.frame_id, settings_.world_frame)));
    return;
  }
  const std::string entity = text(rq.entity);
  if (!rq.set_pose && !rq.set_twist) {
    // nothing to set: the entity must still exist
    call_for_result<SetEntityStateResponse>(
        to, Call{"simulation", "get_entity_state", json{{"name", entity}}}, "name");
    return;
  }
  json state = json::object();
  if (rq.set_pose) {
    const json pose = pose_array(rq.state.pose);
    state["pose"] = {{"position", {pose[0], pose[1], pose[2]}},
                     {"orientation", {pose[3], pose[4], pose[5], pose[6]}}};
  }
  if (rq.set_twist) {
    const auto& t = rq.state.twist;
    state["twist"] =
        twist_json({t.linear.x, t.linear.y, t.linear.z}, {t.angular.x, t.angular.y, t.angular.z});
  }
  caller_(Call{"simulation", "set_entity_state", json{{"name", entity}, {"state", state}}},
          [reply_with](Outcome&& outcome) {
            ServiceResult result = result_of(outcome, "name");
            if (!result.is_ok() && outcome.failure == Failure::bad_arguments &&
                parameter_of(outcome).rfind("state.pose", 0) == 0)
              result.code = k_invalid_pose;
            reply_with(std::move(result));
          });
}

void Ros2Services::get_entity_info(const void* request, const ReplyTo& to) {
  const std::string entity = text(static_cast<const EntityInfoRequest*>(request)->entity);
  auto reply_with = [this, to](ServiceResult result, std::uint8_t category,
                               std::string description) {
    EntityInfoResponse* response;
    Sample reply = new_reply(to, response);
    set_result(response->result, result);
    response->info.category.category = category;
    response->info.description = dup(description);
    alloc_sequence(response->info.tags, 0);
    send(to, std::move(reply));
  };
  // the entity must exist (NOT_FOUND, with simgate's suggestion), then: a robot or not
  caller_(Call{"simulation", "get_entity_state", json{{"name", entity}}},
          [this, entity, reply_with](Outcome&& outcome) {
            ServiceResult result = result_of(outcome, "name");
            if (!result.is_ok()) {
              reply_with(std::move(result), 0, "");
              return;
            }
            caller_(Call{"simulation", "list_robots", json::object()}, [entity, reply_with](
                                                                           Outcome&& robots) {
              bool robot = false;
              if (robots.status == Status::success && robots.value && robots.value->is_array())
                for (const json& name : *robots.value)
                  robot |= name.is_string() && name.get<std::string>() == entity;
              // EntityCategory: CATEGORY_ROBOT 1, CATEGORY_OBJECT 0
              reply_with(
                  ServiceResult::ok(), robot ? 1 : 0,
                  robot ? "robot '" + entity + "' (simulation details)" : "body '" + entity + "'");
            });
          });
}

void Ros2Services::get_entity_bounds(const void* request, const ReplyTo& to) {
  const std::string entity = text(static_cast<const EntityBoundsRequest*>(request)->entity);
  caller_(Call{"simulation", "get_object_bbox", json{{"object_name", entity}}},
          [this, to](Outcome&& outcome) {
            EntityBoundsResponse* response;
            Sample reply = new_reply(to, response);
            ServiceResult result = result_of(outcome, "object_name");
            const json& box = outcome.value ? *outcome.value : json();
            const bool shaped = box.is_array() && box.size() == 2 && box[0].is_array() &&
                                box[0].size() == 3 && box[1].is_array() && box[1].size() == 3;
            if (result.is_ok() && shaped) {
              response->bounds.type = 1;  // TYPE_BOX: two corners, in the entity's frame
              auto* points = alloc_sequence(response->bounds.points, 2);
              for (std::size_t i = 0; i < 2; ++i)
                points[i] = {box[i][0].get<double>(), box[i][1].get<double>(),
                             box[i][2].get<double>()};
            } else if (result.is_ok()) {
              result = ServiceResult::fail(ResultCode::operation_failed,
                                           "get_object_bbox said " + box.dump());
            }
            set_result(response->result, result);
            send(to, std::move(reply));
          });
}

void Ros2Services::spawn_entity(const void* request, const ReplyTo& to) {
  const auto& rq = *static_cast<const SpawnRequest*>(request);
  auto reply_with = [this, to](ServiceResult result, std::string name) {
    SpawnResponse* response;
    Sample reply = new_reply(to, response);
    set_result(response->result, result);
    response->entity_name = dup(name);
    send(to, std::move(reply));
  };
  std::string resource = text(rq.entity_resource.uri);
  if (resource.empty()) {
    resource = text(rq.entity_resource.resource_string);
  } else if (resource.rfind("file://", 0) == 0) {
    resource.erase(0, 7);
  } else if (resource.find("://") != std::string::npos) {
    reply_with(ServiceResult::fail(ResultCode::operation_failed,
                                   "entity_resource.uri '" + resource +
                                       "': a file name or file:// URI (or resource_string)"),
               "");
    return;
  }
  if (resource.empty()) {
    reply_with(ServiceResult::fail(k_no_resource,
                                   "entity_resource: both uri and resource_string are empty"),
               "");
    return;
  }
  if (!in_world_frame(rq.initial_pose.header.frame_id, settings_.world_frame)) {
    reply_with(
        ServiceResult::fail(k_spawn_invalid_pose,
                            frame_refusal(rq.initial_pose.header.frame_id, settings_.world_frame)),
        "");
    return;
  }
  const std::string wanted = text(rq.name);
  const bool renaming = rq.allow_renaming;
  if (wanted.empty() && !renaming) {
    reply_with(ServiceResult::fail(k_name_invalid, "name is empty (and allow_renaming is false)"),
               "");
    return;
  }
  const json pose = pose_array(rq.initial_pose.pose);
  // the names taken, so that a name in use is NAME_NOT_UNIQUE (or renamed when allowed)
  caller_(Call{"simulation", "list_entities", json{{"filter", ""}}},
          [this, wanted, renaming, resource, pose, reply_with](Outcome&& listed) {
            std::set<std::string> taken;
            if (listed.status == Status::success && listed.value && listed.value->is_array())
              for (const json& name : *listed.value)
                if (name.is_string()) taken.insert(name.get<std::string>());
            std::string name = wanted;
            if (taken.count(name) || name.empty()) {
              if (!renaming) {
                reply_with(
                    ServiceResult::fail(k_name_not_unique,
                                        "name '" + name + "' is taken (allow_renaming is false)"),
                    "");
                return;
              }
              const std::string stem = wanted.empty() ? std::string("entity") : wanted;
              for (int i = 1;; ++i) {
                name = stem + "_" + std::to_string(i);
                if (!taken.count(name)) break;
              }
            }
            caller_(Call{"simulation", "spawn_entity",
                         json{{"name", name}, {"mjcf", resource}, {"pose", pose}}},
                    [name, reply_with](Outcome&& outcome) {
                      ServiceResult result = result_of(outcome);
                      if (result.is_ok()) {
                        const std::string given = outcome.value && outcome.value->is_object()
                                                      ? outcome.value->value("name", name)
                                                      : name;
                        reply_with(std::move(result), given);
                        return;
                      }
                      if (outcome.failure == Failure::bad_arguments) {
                        const std::string parameter = parameter_of(outcome);
                        if (parameter == "mjcf") result.code = k_resource_parse_error;
                        if (parameter == "pose") result.code = k_spawn_invalid_pose;
                        if (parameter == "name") result.code = k_name_invalid;
                      }
                      reply_with(std::move(result), "");
                    });
          });
}

void Ros2Services::delete_entity(const void* request, const ReplyTo& to) {
  const std::string entity = text(static_cast<const DeleteRequest*>(request)->entity);
  call_for_result<DeleteResponse>(to, Call{"simulation", "delete_entity", json{{"name", entity}}},
                                  "name");
}

}  // namespace simgate::ros2
