// `simulation get_scene_geometry` and the `simulation` component's body_poses samples
// (world_services.h, docs/world/scene_geometry.md): what a client needs to draw the scene
// itself (a web page with three.js): the bodies' tree and current poses, every geom's shape,
// size, colour and place on its body, and the meshes' vertices and faces; then, streamed,
// only the bodies' poses.
#include <charconv>
#include <cstdlib>
#include <memory>

#include <Eigen/Geometry>

#include "simgate/sim/sim_component.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {

namespace {

// The word on the wire for a geom type (MuJoCo's MJCF spelling).
const char* geom_type_name(int type) {
  switch (type) {
    case mjGEOM_PLANE: return "plane";
    case mjGEOM_HFIELD: return "hfield";
    case mjGEOM_SPHERE: return "sphere";
    case mjGEOM_CAPSULE: return "capsule";
    case mjGEOM_ELLIPSOID: return "ellipsoid";
    case mjGEOM_CYLINDER: return "cylinder";
    case mjGEOM_BOX: return "box";
    case mjGEOM_MESH: return "mesh";
    default: return "unknown";
  }
}

// MuJoCo's own name of object `id`, or "" when it has none.
std::string raw_name(const mjModel* m, mjtObj type, int id) {
  const char* name = mj_id2name(m, type, id);
  return name ? name : "";
}

json triple(const mjtNum* v) { return json::array({v[0], v[1], v[2]}); }
json quad(const mjtNum* v) { return json::array({v[0], v[1], v[2], v[3]}); }

// A float as the double whose shortest spelling is the float's own (0.1f → 0.1, not
// 0.10000000149011612): mesh vertices and colours are floats, and the longer spelling would
// double the size of a mesh on the wire for digits that carry nothing.
double short_double(float f) {
  char text[32];
  const auto end = std::to_chars(text, text + sizeof text - 1, f).ptr;
  *end = '\0';
  return std::strtod(text, nullptr);
}

// The colour a geom is drawn with: its rgba, or its material's when it has one and its own
// rgba was left at MuJoCo's default (0.5 0.5 0.5 1), as MuJoCo's renderer does.
json geom_rgba(const mjModel* m, int g) {
  const float* rgba = m->geom_rgba + 4 * g;
  const int material = m->geom_matid[g];
  const bool default_rgba =
      rgba[0] == 0.5f && rgba[1] == 0.5f && rgba[2] == 0.5f && rgba[3] == 1.0f;
  const float* chosen = material >= 0 && default_rgba ? m->mat_rgba + 4 * material : rgba;
  return json::array({short_double(chosen[0]), short_double(chosen[1]), short_double(chosen[2]),
                      short_double(chosen[3])});
}

json mesh_json(const mjModel* m, int mesh) {
  const int vert_first = m->mesh_vertadr[mesh], vert_count = m->mesh_vertnum[mesh];
  const int face_first = m->mesh_faceadr[mesh], face_count = m->mesh_facenum[mesh];
  json vertices = json::array();
  vertices.get_ref<json::array_t&>().reserve(3 * static_cast<std::size_t>(vert_count));
  for (int i = 3 * vert_first; i < 3 * (vert_first + vert_count); ++i)
    vertices.push_back(short_double(m->mesh_vert[i]));
  // mesh_face holds indices into the mesh's own vertices (0-based from mesh_vertadr)
  json faces = json::array();
  faces.get_ref<json::array_t&>().reserve(3 * static_cast<std::size_t>(face_count));
  for (int i = 3 * face_first; i < 3 * (face_first + face_count); ++i)
    faces.push_back(m->mesh_face[i]);
  return {{"name", raw_name(m, mjOBJ_MESH, mesh)},
          {"vertices", std::move(vertices)},
          {"faces", std::move(faces)}};
}

// A heightfield: MuJoCo's hfield_size (x and y half sizes, the top's height, the base's
// depth), its grid and its elevations (0 to 1, times size[2]), row by row along y.
json hfield_json(const mjModel* m, int hfield) {
  const int nrow = m->hfield_nrow[hfield], ncol = m->hfield_ncol[hfield];
  const std::size_t count = static_cast<std::size_t>(nrow) * static_cast<std::size_t>(ncol);
  const float* first = m->hfield_data + m->hfield_adr[hfield];
  json data = json::array();
  data.get_ref<json::array_t&>().reserve(count);
  for (std::size_t i = 0; i < count; ++i) data.push_back(short_double(first[i]));
  return {{"name", raw_name(m, mjOBJ_HFIELD, hfield)},
          {"size", quad(m->hfield_size + 4 * hfield)},
          {"nrow", nrow},
          {"ncol", ncol},
          {"data", std::move(data)}};
}

json model_data_json(const mjModel* m) {
  json meshes = json::array();
  for (int mesh = 0; mesh < m->nmesh; ++mesh) meshes.push_back(mesh_json(m, mesh));
  json hfields = json::array();
  for (int hfield = 0; hfield < m->nhfield; ++hfield) hfields.push_back(hfield_json(m, hfield));
  return {{"meshes", std::move(meshes)}, {"hfields", std::move(hfields)}};
}

}  // namespace

const json& SceneGeometryCache::model_data(const Simulation& sim) {
  if (model_ != sim.m() || generation_ != sim.model_generation() || data_.is_null()) {
    data_ = model_data_json(sim.m());
    model_ = sim.m();
    generation_ = sim.model_generation();
    ++builds_;
  }
  return data_;
}

json scene_geometry(const Simulation& sim, bool include_meshes, SceneGeometryCache* cache) {
  const mjModel* m = sim.m();
  const mjData* d = sim.d();
  json bodies = json::array();
  for (int b = 0; b < m->nbody; ++b)
    bodies.push_back({{"id", b},
                      {"name", sim.model().body_name(b)},
                      {"parent", m->body_parentid[b]},
                      {"pos", triple(d->xpos + 3 * b)},
                      {"quat", quad(d->xquat + 4 * b)}});
  json geoms = json::array();
  for (int g = 0; g < m->ngeom; ++g) {
    json geom{{"id", g},
              {"name", raw_name(m, mjOBJ_GEOM, g)},
              {"body", m->geom_bodyid[g]},
              {"type", geom_type_name(m->geom_type[g])},
              {"size", triple(m->geom_size + 3 * g)},
              {"rgba", geom_rgba(m, g)},
              {"pos", triple(m->geom_pos + 3 * g)},
              {"quat", quad(m->geom_quat + 4 * g)},
              {"group", m->geom_group[g]}};
    if (m->geom_type[g] == mjGEOM_MESH) geom["mesh"] = m->geom_dataid[g];
    if (m->geom_type[g] == mjGEOM_HFIELD) geom["hfield"] = m->geom_dataid[g];
    geoms.push_back(std::move(geom));
  }
  // the components' frames, each on its body: where their data is in the scene
  json frames = json::array();
  for (const auto& entry : sim.components()) {
    if (!entry->sim_component) continue;
    const auto f = entry->sim_component->sensing_frame();
    if (!f || f->body < 0 || f->body >= m->nbody) continue;
    const Eigen::Quaterniond body_rotation(d->xquat[4 * f->body], d->xquat[4 * f->body + 1],
                                           d->xquat[4 * f->body + 2], d->xquat[4 * f->body + 3]);
    const Eigen::Vector3d body_position(d->xpos[3 * f->body], d->xpos[3 * f->body + 1],
                                        d->xpos[3 * f->body + 2]);
    const Eigen::Vector3d pos = body_rotation.conjugate() * (f->position - body_position);
    const Eigen::Quaterniond quat = (body_rotation.conjugate() * f->orientation).normalized();
    frames.push_back({{"name", entry->component->name()},
                      {"body", f->body},
                      {"pos", {pos.x(), pos.y(), pos.z()}},
                      {"quat", {quat.w(), quat.x(), quat.y(), quat.z()}}});
  }
  json answer{{"timestamp", sim.state_time()}, {"generation", sim.model_generation()},
              {"bodies", std::move(bodies)},   {"geoms", std::move(geoms)},
              {"frames", std::move(frames)},   {"meshes", json::array()},
              {"hfields", json::array()}};
  if (include_meshes) {
    if (cache) {
      const json& data = cache->model_data(sim);
      answer["meshes"] = data["meshes"];
      answer["hfields"] = data["hfields"];
    } else {
      json data = model_data_json(m);
      answer["meshes"] = std::move(data["meshes"]);
      answer["hfields"] = std::move(data["hfields"]);
    }
  }
  return answer;
}

json body_poses(const Simulation& sim) {
  const mjModel* m = sim.m();
  const mjData* d = sim.d();
  json poses = json::array();
  poses.get_ref<json::array_t&>().reserve(static_cast<std::size_t>(m->nbody));
  for (int b = 0; b < m->nbody; ++b) {
    const mjtNum* p = d->xpos + 3 * b;
    const mjtNum* q = d->xquat + 4 * b;
    poses.push_back(json::array({p[0], p[1], p[2], q[0], q[1], q[2], q[3]}));
  }
  return {{"timestamp", sim.state_time()},
          {"generation", sim.model_generation()},
          {"poses", std::move(poses)}};
}

void add_scene_geometry_services(SupervisionServices& simulation, Simulation& sim) {
  // the meshes and heightfields, written once per model (services run under the lock, one
  // at a time: the cache needs no lock of its own)
  auto cache = std::make_shared<SceneGeometryCache>();
  simulation
      .offer_service("get_scene_geometry",
                     [&sim, cache](bool include_meshes) {
                       return scene_geometry(sim, include_meshes, cache.get());
                     },
                     {{"include_meshes", true}})
      .doc(
          "What a client needs to draw the scene: {timestamp, generation (changes when the model "
          "is replaced), "
          "bodies [{id, name, parent, pos, quat}] (current world poses), geoms [{id, name, body, "
          "type, size, rgba, "
          "pos, quat, group, mesh?, hfield?}] (on their body), meshes [{name, vertices, faces}], "
          "hfields [{name, "
          "size, nrow, ncol, data}] (both [] unless include_meshes)}");
}

}  // namespace simgate::sim
