#include "simgate/foxglove/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "simgate/foxglove/protocol.h"

#include "parts.h"

namespace simgate::foxglove {

namespace {

using parts::array_of;
using parts::at;
using parts::numbers_schema;
using parts::pose_schema;
using parts::time_schema;
using parts::timestamp;
using parts::vector3;

// A model generation: a non-negative integer, whichever way JSON holds it.
std::optional<std::uint64_t> generation_of(const json& object) {
  const auto g = object.find("generation");
  if (g == object.end() || !g->is_number_integer() || g->get<std::int64_t>() < 0)
    return std::nullopt;
  return g->get<std::uint64_t>();
}

// A MuJoCo pos [x, y, z] and quat [w, x, y, z] as Foxglove's pose.
json pose(const json& pos, const json& quat) {
  return json{
      {"position", vector3(at(pos, 0), at(pos, 1), at(pos, 2))},
      {"orientation",
       {{"x", at(quat, 1)}, {"y", at(quat, 2)}, {"z", at(quat, 3)}, {"w", at(quat, 0, 1)}}}};
}

json colour(const json& rgba) {
  return json{{"r", at(rgba, 0, 0.5)},
              {"g", at(rgba, 1, 0.5)},
              {"b", at(rgba, 2, 0.5)},
              {"a", at(rgba, 3, 1)}};
}

// `pose` moved by `offset` along its own z axis (a capsule's end caps).
json along_z(const json& pos, const json& quat, double offset) {
  const double w = at(quat, 0, 1), x = at(quat, 1), y = at(quat, 2), z = at(quat, 3);
  // the body-frame z axis of the rotation
  const double zx = 2 * (x * z + w * y), zy = 2 * (y * z - w * x), zz = 1 - 2 * (x * x + y * y);
  return json::array(
      {at(pos, 0) + offset * zx, at(pos, 1) + offset * zy, at(pos, 2) + offset * zz});
}

json entity(const std::string& frame, double time) {
  return json{{"timestamp", timestamp(time)}, {"frame_id", frame},
              {"id", "body/" + frame},        {"lifetime", {{"sec", 0}, {"nsec", 0}}},
              {"frame_locked", true},         {"metadata", json::array()},
              {"arrows", json::array()},      {"cubes", json::array()},
              {"spheres", json::array()},     {"cylinders", json::array()},
              {"lines", json::array()},       {"triangles", json::array()},
              {"texts", json::array()},       {"models", json::array()}};
}

// The most grid points along each side of a heightfield drawn: a larger one is sampled.
constexpr std::size_t k_max_hfield_side = 256;

// Heightfield `hfield` (a get_scene_geometry hfields entry: size [x, y, top, base], nrow x
// ncol elevations from 0 to 1, row by row along y from -y) as a triangle list at `pose`;
// null when it is malformed.
json hfield_triangles(const json& hfield, json pose, json color) {
  if (!hfield.is_object()) return nullptr;
  const json& size = hfield.contains("size") ? hfield["size"] : json::array();
  const json& data = hfield.contains("data") ? hfield["data"] : json::array();
  const std::size_t nrow = hfield.value("nrow", std::size_t{0}),
                    ncol = hfield.value("ncol", std::size_t{0});
  if (nrow < 2 || ncol < 2 || !data.is_array() || data.size() != nrow * ncol) return nullptr;
  // every `stride`-th row and column, the last ones always
  const std::size_t stride = (std::max(nrow, ncol) + k_max_hfield_side - 1) / k_max_hfield_side;
  std::vector<std::size_t> rows, columns;
  for (std::size_t r = 0; r < nrow; r += stride) rows.push_back(r);
  if (rows.back() != nrow - 1) rows.push_back(nrow - 1);
  for (std::size_t c = 0; c < ncol; c += stride) columns.push_back(c);
  if (columns.back() != ncol - 1) columns.push_back(ncol - 1);
  const double x = at(size, 0), y = at(size, 1), top = at(size, 2);
  json points = json::array();
  for (std::size_t r : rows)
    for (std::size_t c : columns)
      points.push_back(
          vector3(x * (2.0 * static_cast<double>(c) / static_cast<double>(ncol - 1) - 1),
                  y * (2.0 * static_cast<double>(r) / static_cast<double>(nrow - 1) - 1),
                  top * at(data, r * ncol + c)));
  json indices = json::array();
  const std::size_t width = columns.size();
  for (std::size_t r = 0; r + 1 < rows.size(); ++r)
    for (std::size_t c = 0; c + 1 < width; ++c) {
      const std::size_t a = r * width + c, b = a + 1, d = a + width, e = d + 1;
      for (std::size_t i : {a, b, e, a, e, d}) indices.push_back(i);  // counterclockwise from +z
    }
  return json{{"pose", std::move(pose)},
              {"points", std::move(points)},
              {"color", std::move(color)},
              {"colors", json::array()},
              {"indices", std::move(indices)}};
}

// Adds geom `g` (a get_scene_geometry geom) to `e`; false when it has no primitive here.
bool add_geom(json& e, const json& g, const json& meshes, const json& hfields) {
  const std::string type = g.value("type", "");
  const json& size = g.contains("size") ? g["size"] : json::array();
  const json& pos = g.contains("pos") ? g["pos"] : json::array();
  const json& quat = g.contains("quat") ? g["quat"] : json::array();
  const json color = colour(g.contains("rgba") ? g["rgba"] : json::array());
  const auto shape = [&](double x, double y, double z) {
    return json{{"pose", pose(pos, quat)}, {"size", vector3(x, y, z)}, {"color", color}};
  };
  if (type == "box") {
    e["cubes"].push_back(shape(2 * at(size, 0), 2 * at(size, 1), 2 * at(size, 2)));
  } else if (type == "sphere") {
    const double d = 2 * at(size, 0);
    e["spheres"].push_back(shape(d, d, d));
  } else if (type == "ellipsoid") {
    e["spheres"].push_back(shape(2 * at(size, 0), 2 * at(size, 1), 2 * at(size, 2)));
  } else if (type == "cylinder" || type == "capsule") {
    const double d = 2 * at(size, 0), length = 2 * at(size, 1);
    json cylinder = shape(d, d, length);
    cylinder["bottom_scale"] = 1;
    cylinder["top_scale"] = 1;
    e["cylinders"].push_back(std::move(cylinder));
    if (type == "capsule")
      for (double end : {-at(size, 1), at(size, 1)})
        e["spheres"].push_back(json{{"pose", pose(along_z(pos, quat, end), quat)},
                                    {"size", vector3(d, d, d)},
                                    {"color", color}});
  } else if (type == "plane") {
    // 0: infinite in MuJoCo; drawn 20 m wide
    const double x = at(size, 0) > 0 ? 2 * at(size, 0) : 20,
                 y = at(size, 1) > 0 ? 2 * at(size, 1) : 20;
    e["cubes"].push_back(shape(x, y, 0.001));
  } else if (type == "mesh" && g.contains("mesh") && g["mesh"].is_number_integer()) {
    const auto id = g["mesh"].get<std::int64_t>();
    if (id < 0 || static_cast<std::size_t>(id) >= meshes.size()) return false;
    const json& mesh = meshes[static_cast<std::size_t>(id)];
    const json& vertices = mesh.contains("vertices") ? mesh["vertices"] : json::array();
    const json& faces = mesh.contains("faces") ? mesh["faces"] : json::array();
    json points = json::array();
    for (std::size_t i = 0; i + 2 < vertices.size(); i += 3)
      points.push_back(vector3(at(vertices, i), at(vertices, i + 1), at(vertices, i + 2)));
    json indices = json::array();
    for (const json& f : faces)
      if (f.is_number_integer() && f.get<std::int64_t>() >= 0 &&
          static_cast<std::size_t>(f.get<std::int64_t>()) < points.size())
        indices.push_back(f);
    if (points.empty() || indices.size() < 3) return false;
    indices.get_ref<json::array_t&>().resize(indices.size() / 3 * 3);
    e["triangles"].push_back(json{{"pose", pose(pos, quat)},
                                  {"points", std::move(points)},
                                  {"color", color},
                                  {"colors", json::array()},
                                  {"indices", std::move(indices)}});
  } else if (type == "hfield" && g.contains("hfield") && g["hfield"].is_number_integer()) {
    const auto id = g["hfield"].get<std::int64_t>();
    if (id < 0 || static_cast<std::size_t>(id) >= hfields.size()) return false;
    json triangles =
        hfield_triangles(hfields[static_cast<std::size_t>(id)], pose(pos, quat), color);
    if (triangles.is_null()) return false;
    e["triangles"].push_back(std::move(triangles));
  } else {
    return false;  // an SDF: not drawn
  }
  return true;
}

}  // namespace

SceneFrames SceneFrames::from_geometry(const json& geometry, std::string_view prefix) {
  SceneFrames f;
  if (!geometry.is_object()) return f;
  f.generation = generation_of(geometry).value_or(0);
  const auto bodies = geometry.find("bodies");
  if (bodies == geometry.end() || !bodies->is_array()) return f;
  for (const json& b : *bodies) {
    const std::size_t id = f.names.size();
    std::string name = b.is_object() ? b.value("name", "") : "";
    if (name.empty()) name = id == 0 ? "world" : "body" + std::to_string(id);
    f.names.push_back(std::string(prefix) + name);
  }
  const auto fixed = geometry.find("frames");
  if (fixed == geometry.end() || !fixed->is_array()) return f;
  for (const json& c : *fixed) {
    if (!c.is_object() || !c.contains("name") || !c["name"].is_string() || !c.contains("body") ||
        !c["body"].is_number_integer())
      continue;
    const auto body = c["body"].get<std::int64_t>();
    if (body < 0 || static_cast<std::size_t>(body) >= f.names.size()) continue;
    SceneFrames::Fixed frame;
    frame.name = std::string(prefix) + c["name"].get<std::string>();
    frame.body = static_cast<std::size_t>(body);
    const json& pos = c.contains("pos") ? c["pos"] : json::array();
    const json& quat = c.contains("quat") ? c["quat"] : json::array();
    for (std::size_t i = 0; i < 3; ++i) frame.pos[i] = at(pos, i);
    for (std::size_t i = 0; i < 4; ++i) frame.quat[i] = at(quat, i, i == 0 ? 1 : 0);
    f.fixed.push_back(std::move(frame));
  }
  return f;
}

json frame_transforms_schema() {
  const json transform{
      {"type", "object"},
      {"properties",
       {{"timestamp", time_schema()},
        {"parent_frame_id", {{"type", "string"}}},
        {"child_frame_id", {{"type", "string"}}},
        {"translation", numbers_schema({"x", "y", "z"})},
        {"rotation", numbers_schema({"x", "y", "z", "w"})}}},
      {"required", {"timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"}}};
  return json{{"title", k_frame_transforms},
              {"description", "Every body's world pose (simgate: the simulation's body_poses)"},
              {"type", "object"},
              {"properties", {{"transforms", array_of(transform)}}},
              {"required", {"transforms"}}};
}

json scene_update_schema() {
  const json colour_schema = numbers_schema({"r", "g", "b", "a"});
  const json shape{{"type", "object"},
                   {"properties",
                    {{"pose", pose_schema()},
                     {"size", numbers_schema({"x", "y", "z"})},
                     {"color", colour_schema}}},
                   {"required", {"pose", "size", "color"}}};
  json cylinder = shape;
  cylinder["properties"]["bottom_scale"] = json{{"type", "number"}};
  cylinder["properties"]["top_scale"] = json{{"type", "number"}};
  cylinder["required"] = {"pose", "size", "bottom_scale", "top_scale", "color"};
  const json triangles{{"type", "object"},
                       {"properties",
                        {{"pose", pose_schema()},
                         {"points", array_of(numbers_schema({"x", "y", "z"}))},
                         {"color", colour_schema},
                         {"colors", array_of(colour_schema)},
                         {"indices", array_of(json{{"type", "integer"}, {"minimum", 0}})}}},
                       {"required", {"pose", "points", "color", "colors", "indices"}}};
  const json any_list = array_of(json{{"type", "object"}});
  const json entity_schema{
      {"type", "object"},
      {"properties",
       {{"timestamp", time_schema()},
        {"frame_id", {{"type", "string"}}},
        {"id", {{"type", "string"}}},
        {"lifetime", time_schema()},
        {"frame_locked", {{"type", "boolean"}}},
        {"metadata", any_list},
        {"arrows", any_list},
        {"cubes", array_of(shape)},
        {"spheres", array_of(shape)},
        {"cylinders", array_of(cylinder)},
        {"lines", any_list},
        {"triangles", array_of(triangles)},
        {"texts", any_list},
        {"models", any_list}}},
      {"required",
       {"timestamp", "frame_id", "id", "lifetime", "frame_locked", "metadata", "arrows", "cubes",
        "spheres", "cylinders", "lines", "triangles", "texts", "models"}}};
  const json deletion{{"type", "object"},
                      {"properties",
                       {{"timestamp", time_schema()},
                        {"type", {{"type", "integer"}, {"enum", {0, 1}}}},
                        {"id", {{"type", "string"}}}}},
                      {"required", {"timestamp", "type", "id"}}};
  return json{
      {"title", k_scene_update},
      {"description", "Every geom, on its body's frame (simgate: get_scene_geometry)"},
      {"type", "object"},
      {"properties", {{"deletions", array_of(deletion)}, {"entities", array_of(entity_schema)}}},
      {"required", {"deletions", "entities"}}};
}

std::string frame_transforms(const json& body_poses, const SceneFrames& frames) {
  if (!body_poses.is_object() || !frames.known()) return {};
  if (generation_of(body_poses) != frames.generation) return {};
  const auto poses = body_poses.find("poses");
  if (poses == body_poses.end() || !poses->is_array() || poses->size() != frames.names.size())
    return {};
  const json stamp = timestamp(body_poses.value("timestamp", 0.0));
  json transforms = json::array();
  for (std::size_t b = 1; b < poses->size(); ++b) {
    const json& p = (*poses)[b];
    transforms.push_back(json{
        {"timestamp", stamp},
        {"parent_frame_id", frames.names[0]},
        {"child_frame_id", frames.names[b]},
        {"translation", vector3(at(p, 0), at(p, 1), at(p, 2))},
        {"rotation", {{"x", at(p, 4)}, {"y", at(p, 5)}, {"z", at(p, 6)}, {"w", at(p, 3, 1)}}}});
  }
  for (const SceneFrames::Fixed& f : frames.fixed)
    transforms.push_back(
        json{{"timestamp", stamp},
             {"parent_frame_id", frames.names[f.body]},
             {"child_frame_id", f.name},
             {"translation", vector3(f.pos[0], f.pos[1], f.pos[2])},
             {"rotation", parts::quaternion(f.quat[0], f.quat[1], f.quat[2], f.quat[3])}});
  return dump(json{{"transforms", std::move(transforms)}});
}

std::string scene_update(const json& geometry, const SceneFrames& frames) {
  const double time = geometry.is_object() ? geometry.value("timestamp", 0.0) : 0.0;
  json entities = json::array();
  const json& geoms =
      geometry.is_object() && geometry.contains("geoms") ? geometry["geoms"] : json::array();
  const json& meshes =
      geometry.is_object() && geometry.contains("meshes") ? geometry["meshes"] : json::array();
  const json& hfields =
      geometry.is_object() && geometry.contains("hfields") ? geometry["hfields"] : json::array();
  std::vector<json> by_body(frames.names.size());
  for (const json& g : geoms) {
    if (!g.is_object() || !g.contains("body") || !g["body"].is_number_integer()) continue;
    const auto body = g["body"].get<std::int64_t>();
    if (body < 0 || static_cast<std::size_t>(body) >= by_body.size()) continue;
    json& e = by_body[static_cast<std::size_t>(body)];
    if (e.is_null()) e = entity(frames.names[static_cast<std::size_t>(body)], time);
    add_geom(e, g, meshes, hfields);
  }
  for (json& e : by_body)
    if (!e.is_null()) entities.push_back(std::move(e));
  // what an earlier model drew goes first
  json deletions = json::array({json{{"timestamp", timestamp(time)}, {"type", 1}, {"id", ""}}});
  return dump(json{{"deletions", std::move(deletions)}, {"entities", std::move(entities)}});
}

}  // namespace simgate::foxglove
