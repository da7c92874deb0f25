// SimSceneGeometry: `simulation get_scene_geometry` and the `simulation` component's
// body_poses stream (scene_geometry.cc, docs/world/scene_geometry.md) on real models: an
// inline scene with one geom of each kind a client draws (plane, box, sphere, capsule, an
// inline mesh), colours from the geom and from its material; a height field; Debian's
// sample models; a spawned entity; the meshes written once per model (SceneGeometryCache).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <set>
#include <utility>

#include <Eigen/Geometry>

#include <unistd.h>

#include "mjcf_fixture.h"
#include "simgate/sim/supervision.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {
namespace {

// One geom of each drawable kind. "top" takes its material's colour (its own rgba is left at
// MuJoCo's default); "tetra" has a material too but an rgba of its own, which wins.
constexpr const char* k_geometry_scene = R"(<mujoco model="geometry">
  <option timestep="0.002"/>
  <asset>
    <material name="blue" rgba="0 0 1 1"/>
    <mesh name="tetra" vertex="0 0 0  1 0 0  0 1 0  0 0 1"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" rgba="0.2 0.3 0.4 1"/>
    <body name="table" pos="0 0 0.5">
      <geom name="top" type="box" size="0.4 0.3 0.02" material="blue"/>
      <body name="arm" pos="0.1 0 0.1">
        <joint type="hinge" axis="0 0 1"/>
        <geom name="rod" type="capsule" size="0.02 0.1" pos="0.05 0 0" rgba="1 0 0 1"/>
      </body>
    </body>
    <body name="ball" pos="0 0 2">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.1" rgba="0 1 0 0.5" group="1"/>
    </body>
    <body name="shape" pos="2 0 0.5">
      <geom name="tetra" type="mesh" mesh="tetra" material="blue" rgba="1 1 0 1"/>
    </body>
  </worldbody>
</mujoco>)";

class SimSceneGeometryTest : public testing::MjcfSim {
 protected:
  void start(const std::string& xml) {
    load_string(xml);
    serve();
  }
  json geometry(json params = json::array()) {
    return value("simulation", "get_scene_geometry", std::move(params));
  }
  // The geom of `geometry` named `name` (null when none is).
  static json geom(const json& geometry, const std::string& name) {
    for (const auto& g : geometry["geoms"])
      if (g["name"] == name) return g;
    return nullptr;
  }
  static void expect_numbers(const json& actual, std::vector<double> expected,
                             double tolerance = 1e-6) {
    ASSERT_TRUE(actual.is_array()) << actual.dump();
    ASSERT_EQ(actual.size(), expected.size()) << actual.dump();
    for (std::size_t i = 0; i < expected.size(); ++i)
      EXPECT_NEAR(actual[i].get<double>(), expected[i], tolerance)
          << actual.dump() << " [" << i << "]";
  }
};

TEST_F(SimSceneGeometryTest, ComponentsFramesAreOnTheirBodies) {
  // a laser on a turned site of a turned body; a camera on an MJCF camera; an actuator has none
  load_string(R"(<mujoco>
  <worldbody>
    <geom type="plane" size="5 5 0.1"/>
    <body name="rover" pos="1 2 0.1" euler="0 0 90">
      <freejoint/>
      <geom type="box" size="0.3 0.2 0.1"/>
      <site name="laser" pos="0.2 0 0.15" euler="0 0 45"/>
      <camera name="eye" pos="0 0 0.3" xyaxes="0 -1 0 0 0 1"/>
    </body>
  </worldbody>
</mujoco>)");
  Robot& robot = add_robot("rover", "rover");
  add_component(robot, "laser", "laser_scanner", {{"site", "laser"}}, "rover");
  add_component(robot, "camera", "video_camera", {{"camera", "eye"}}, "rover");
  add_component(robot, "teleport", "teleport", json::object(), "rover");
  serve();
  const json frames = geometry()["frames"];
  ASSERT_EQ(frames.size(), 2u) << frames.dump();
  const int rover = sim_->model().body_id("rover");
  EXPECT_EQ(frames[0]["name"], "rover.laser");
  EXPECT_EQ(frames[0]["body"], rover);
  // the site's own place on the body, whatever the body's pose in the world
  expect_numbers(frames[0]["pos"], {0.2, 0, 0.15});
  const double c = std::cos(M_PI / 8), s = std::sin(M_PI / 8);
  expect_numbers(frames[0]["quat"], {c, 0, 0, s});
  // the camera: its optical frame (x right, y down, z forward): the MJCF camera looks along
  // its -z (here the body's +x, y up = the body's +z), so the optical z is the body's +x, the
  // optical y the body's -z, the optical x the body's -y
  EXPECT_EQ(frames[1]["name"], "rover.camera");
  EXPECT_EQ(frames[1]["body"], rover);
  expect_numbers(frames[1]["pos"], {0, 0, 0.3});
  const json& q = frames[1]["quat"];
  const Eigen::Quaterniond optical(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(),
                                   q[3].get<double>());
  const Eigen::Matrix3d r = optical.toRotationMatrix();
  for (const auto& [column, expected] :
       {std::pair{0, Eigen::Vector3d(0, -1, 0)}, std::pair{1, Eigen::Vector3d(0, 0, -1)},
        std::pair{2, Eigen::Vector3d(1, 0, 0)}})
    EXPECT_TRUE(r.col(column).isApprox(expected, 1e-9))
        << column << ": " << r.col(column).transpose();
}

TEST_F(SimSceneGeometryTest, DescribesEveryBodyAndGeomOfTheModel) {
  start(k_geometry_scene);
  const json g = geometry();
  EXPECT_EQ(g["generation"], 0);
  EXPECT_EQ(g["timestamp"].get<double>(), sim_->state_time());
  // bodies: every one, in id order, with its parent and its world pose
  ASSERT_EQ(g["bodies"].size(), static_cast<std::size_t>(sim_->m()->nbody));
  for (int b = 0; b < sim_->m()->nbody; ++b) EXPECT_EQ(g["bodies"][b]["id"], b);
  EXPECT_EQ(g["bodies"][0]["name"], "world");
  EXPECT_EQ(g["bodies"][0]["parent"], 0);
  const int table = sim_->model().body_id("table"), arm = sim_->model().body_id("arm");
  EXPECT_EQ(g["bodies"][arm]["name"], "arm");
  EXPECT_EQ(g["bodies"][arm]["parent"], table);
  EXPECT_EQ(g["bodies"][table]["parent"], 0);
  expect_numbers(g["bodies"][arm]["pos"],
                 {0.1, 0, 0.6});  // world frame: the table's 0.5 plus its own 0.1
  expect_numbers(g["bodies"][arm]["quat"], {1, 0, 0, 0});

  // geoms: type, size (MuJoCo's geom_size), colour, body, place on the body, group
  ASSERT_EQ(g["geoms"].size(), static_cast<std::size_t>(sim_->m()->ngeom));
  const json floor = geom(g, "floor"), top = geom(g, "top"), rod = geom(g, "rod"),
             ball = geom(g, "ball"), tetra = geom(g, "tetra");
  EXPECT_EQ(floor["type"], "plane");
  expect_numbers(floor["size"], {5, 5, 0.1});
  expect_numbers(floor["rgba"], {0.2, 0.3, 0.4, 1});
  EXPECT_EQ(floor["body"], 0);
  EXPECT_EQ(top["type"], "box");
  expect_numbers(top["size"], {0.4, 0.3, 0.02});
  expect_numbers(top["rgba"], {0, 0, 1, 1});  // the material's
  EXPECT_EQ(top["body"], table);
  EXPECT_EQ(rod["type"], "capsule");
  expect_numbers(rod["size"], {0.02, 0.1, 0});
  expect_numbers(rod["rgba"], {1, 0, 0, 1});
  expect_numbers(rod["pos"], {0.05, 0, 0});
  expect_numbers(rod["quat"], {1, 0, 0, 0});
  EXPECT_EQ(rod["body"], arm);
  EXPECT_EQ(ball["type"], "sphere");
  expect_numbers(ball["size"], {0.1, 0, 0});
  expect_numbers(ball["rgba"], {0, 1, 0, 0.5});
  EXPECT_EQ(ball["group"], 1);
  EXPECT_EQ(rod["group"], 0);
  EXPECT_EQ(tetra["type"], "mesh");
  expect_numbers(tetra["rgba"], {1, 1, 0, 1});  // its own rgba wins over its material's
  EXPECT_EQ(tetra["mesh"], 0);
  EXPECT_FALSE(ball.contains("mesh"));  // only meshes say which
  // colours are written as the floats MuJoCo holds, shortest: 0.2, not 0.20000000298023224
  EXPECT_NE(floor["rgba"].dump().find("[0.2,0.3,0.4,1.0]"), std::string::npos)
      << floor["rgba"].dump();
}

// The mesh's vertices are in the geom's frame: placed by the geom's pos and quat on its body
// (MuJoCo moves them to the mesh's centre of mass and principal axes when it compiles), they
// are the points the MJCF wrote. Faces index the mesh's own vertices from 0.
TEST_F(SimSceneGeometryTest, MeshVerticesPlacedByTheGeomAreThePointsTheMjcfWrote) {
  start(k_geometry_scene);
  const json g = geometry();
  ASSERT_EQ(g["meshes"].size(), 1u);
  const json mesh = g["meshes"][0];
  EXPECT_EQ(mesh["name"], "tetra");
  const json& vertices = mesh["vertices"];
  ASSERT_EQ(vertices.size(), 12u) << vertices.dump();
  const json tetra = geom(g, "tetra");
  const double w = tetra["quat"][0], x = tetra["quat"][1], y = tetra["quat"][2],
               z = tetra["quat"][3];
  const std::array<std::array<double, 3>, 4> written = {
      {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  std::set<int> found;
  for (std::size_t v = 0; v < 4; ++v) {
    const double px = vertices[3 * v], py = vertices[3 * v + 1], pz = vertices[3 * v + 2];
    // rotate by the unit quaternion (w, x, y, z), then translate
    const double r[3] = {
        (1 - 2 * (y * y + z * z)) * px + 2 * (x * y - w * z) * py + 2 * (x * z + w * y) * pz,
        2 * (x * y + w * z) * px + (1 - 2 * (x * x + z * z)) * py + 2 * (y * z - w * x) * pz,
        2 * (x * z - w * y) * px + 2 * (y * z + w * x) * py + (1 - 2 * (x * x + y * y)) * pz};
    // which written point it is
    for (std::size_t k = 0; k < written.size(); ++k) {
      double distance = 0;
      for (int i = 0; i < 3; ++i)
        distance += std::abs(r[i] + tetra["pos"][i].get<double>() - written[k][i]);
      if (distance < 3e-4) found.insert(static_cast<int>(k));
    }
  }
  EXPECT_EQ(found.size(), 4u) << vertices.dump();
  const json& faces = mesh["faces"];
  ASSERT_EQ(faces.size(), 3u * static_cast<std::size_t>(sim_->m()->mesh_facenum[0]));
  ASSERT_EQ(faces.size(), 12u);  // the tetrahedron's four triangles (MuJoCo's convex hull)
  for (const auto& index : faces) {
    EXPECT_GE(index.get<int>(), 0);
    EXPECT_LT(index.get<int>(), 4);
  }
}

TEST_F(SimSceneGeometryTest, IncludeMeshesFalseLeavesTheMeshesOut) {
  start(k_geometry_scene);
  for (const json& params : {json{{"include_meshes", false}}, json::array({false})}) {
    const json g = geometry(params);
    EXPECT_EQ(g["meshes"], json::array()) << params.dump();
    EXPECT_EQ(geom(g, "tetra")["mesh"], 0);  // the index still says which mesh to draw
    EXPECT_EQ(g["geoms"].size(), static_cast<std::size_t>(sim_->m()->ngeom));
  }
  EXPECT_EQ(geometry(json::object())["meshes"].size(), 1u);  // true by default
  const Outcome wrong = call("simulation", "get_scene_geometry", {{"include_meshes", "no"}});
  EXPECT_EQ(wrong.status, Status::failed);
  EXPECT_EQ(wrong.failure, Failure::bad_arguments) << wrong.message;
}

TEST_F(SimSceneGeometryTest, BodiesPosesAreTheCurrentOnes) {
  start(k_geometry_scene);
  const int ball = sim_->model().body_id("ball");
  const double z0 = geometry()["bodies"][ball]["pos"][2];
  EXPECT_NEAR(z0, 2.0, 1e-9);
  run_for(0.3);  // it falls
  const json g = geometry({{"include_meshes", false}});
  const double z1 = g["bodies"][ball]["pos"][2];
  EXPECT_LT(z1, z0 - 0.3);  // about 0.44 m in 0.3 s
  EXPECT_EQ(z1, sim_->d()->xpos[3 * ball + 2]);
  EXPECT_EQ(g["timestamp"].get<double>(), sim_->state_time());
  EXPECT_EQ(g["generation"], 0);  // stepping replaces no model
}

// Debian's sample models (libmujoco-dev's examples): the counts are the model's.
TEST_F(SimSceneGeometryTest, SampleModelsAreDescribedWhole) {
  int models = 0;
  for (const char* file :
       {"/usr/share/mujoco/model/humanoid/humanoid.xml", "/usr/share/mujoco/model/mug/mug.xml"}) {
    if (!std::filesystem::exists(file)) continue;
    SCOPED_TRACE(file);
    rm_.reset();
    sim_.reset();
    load_file(file);
    serve();
    const mjModel* m = sim_->m();
    const json g = geometry();
    EXPECT_EQ(g["bodies"].size(), static_cast<std::size_t>(m->nbody));
    EXPECT_EQ(g["geoms"].size(), static_cast<std::size_t>(m->ngeom));
    ASSERT_EQ(g["meshes"].size(), static_cast<std::size_t>(m->nmesh));
    for (int i = 0; i < m->nmesh; ++i) {
      EXPECT_EQ(g["meshes"][i]["vertices"].size(),
                3u * static_cast<std::size_t>(m->mesh_vertnum[i]));
      EXPECT_EQ(g["meshes"][i]["faces"].size(), 3u * static_cast<std::size_t>(m->mesh_facenum[i]));
      const auto& faces = g["meshes"][i]["faces"];
      const auto largest = std::max_element(
          faces.begin(), faces.end(),
          [](const json& a, const json& b) { return a.get<int>() < b.get<int>(); });
      if (largest != faces.end()) {
        EXPECT_LT(largest->get<int>(), m->mesh_vertnum[i]);
      }
    }
    for (int i = 0; i < m->ngeom; ++i) {
      EXPECT_EQ(g["geoms"][i]["body"], m->geom_bodyid[i]);
      EXPECT_NE(g["geoms"][i]["type"], "unknown");
    }
    for (int b = 0; b < m->nbody; ++b) EXPECT_EQ(g["bodies"][b]["parent"], m->body_parentid[b]);
    ++models;
  }
  if (models == 0)
    GTEST_SKIP() << "no sample model under /usr/share/mujoco/model (Debian's libmujoco-dev)";
}

TEST_F(SimSceneGeometryTest, BodyPosesSamplesAreEveryBodysWorldPose) {
  start(k_geometry_scene);
  ComponentEntry* simulation = sim_->find("simulation");
  ASSERT_NE(simulation, nullptr);
  ASSERT_NE(simulation->component->stream(), nullptr);
  EXPECT_EQ(simulation->component->stream()->kind, "body_poses");
  sim_->streams().add(*simulation->component, "simulation", {"test"},
                      SupervisionServices::k_body_poses_frequency);
  auto subscription = sim_->streams().subscribe("simulation", "test", {64, "test", {}});
  ASSERT_TRUE(subscription);
  run_for(1.0);  // 500 steps of 2 ms at 30 Hz (simulated): one every 1/30 s, plus the first at once
  std::vector<SamplePtr> samples;
  subscription->take(samples);
  EXPECT_GE(samples.size(), 29u);
  EXPECT_LE(samples.size(), 32u);
  const json& last = samples.back()->data();
  EXPECT_EQ(last["timestamp"].get<double>(), samples.back()->time());
  EXPECT_EQ(last["generation"], 0);
  ASSERT_EQ(last["poses"].size(), static_cast<std::size_t>(sim_->m()->nbody));
  for (const auto& pose : last["poses"]) EXPECT_EQ(pose.size(), 7u);
  // [x, y, z, qw, qx, qy, qz]: the world's at the origin, the ball's where it fell
  expect_numbers(last["poses"][0], {0, 0, 0, 1, 0, 0, 0});
  const int ball = sim_->model().body_id("ball");
  const json first_ball = samples.front()->data()["poses"][ball];
  EXPECT_NEAR(first_ball[2].get<double>(), 2.0, 1e-9);
  EXPECT_LT(last["poses"][ball][2].get<double>(), 1.0);
  // a sample is what get_scene_geometry says of the bodies at that moment
  const json now = body_poses(*sim_);
  const json g = geometry({{"include_meshes", false}});
  EXPECT_EQ(now["timestamp"], g["timestamp"]);
  EXPECT_EQ(now["generation"], g["generation"]);
  for (int b = 0; b < sim_->m()->nbody; ++b) {
    const json& pose = now["poses"][b];
    for (int i = 0; i < 3; ++i) EXPECT_EQ(pose[i], g["bodies"][b]["pos"][i]);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(pose[3 + i], g["bodies"][b]["quat"][i]);
  }
  sim_->streams().unsubscribe(subscription);
}

// The meshes and heightfields are written once per model (SceneGeometryCache): repeated
// answers are equal, and equal to the answer written without the cache.
TEST_F(SimSceneGeometryTest, RepeatedCallsGiveEqualMeshesWrittenOnce) {
  start(k_geometry_scene);
  SceneGeometryCache cache;
  const json uncached = scene_geometry(*sim_, true);
  const json first = scene_geometry(*sim_, true, &cache);
  const json second = scene_geometry(*sim_, true, &cache);
  EXPECT_EQ(cache.builds(), 1u);
  EXPECT_EQ(first, uncached);
  EXPECT_EQ(second, first);
  EXPECT_EQ(first.dump(), uncached.dump());
  ASSERT_EQ(first["meshes"].size(), 1u);
  // without the meshes, the cache is not even looked at
  SceneGeometryCache unused;
  EXPECT_EQ(scene_geometry(*sim_, false, &unused)["meshes"], json::array());
  EXPECT_EQ(unused.builds(), 0u);
  // through the service: the same meshes every time, the poses of now
  const json a = geometry();
  run_for(0.1);
  const json b = geometry();
  EXPECT_EQ(a["meshes"], uncached["meshes"]);
  EXPECT_EQ(b["meshes"], a["meshes"]);
  EXPECT_NE(b["bodies"], a["bodies"]);  // the ball fell
}

// A heightfield geom: its `hfield` index and the hfield's grid and elevations (from a file
// in MuJoCo's binary format: int32 nrow, int32 ncol, then the float elevations row by row;
// MuJoCo 2.2 has no inline `elevation`).
TEST_F(SimSceneGeometryTest, HeightfieldsAreDescribedWithTheirElevations) {
  const std::filesystem::path file = std::filesystem::temp_directory_path() /
                                     ("simgate-hfield-" + std::to_string(::getpid()) + ".bin");
  {
    std::ofstream out(file, std::ios::binary);
    const std::int32_t nrow = 3, ncol = 4;
    const std::array<float, 12> elevations{0, 1, 2, 3, 1, 2, 3, 4, 0, 0, 4, 2};
    out.write(reinterpret_cast<const char*>(&nrow), sizeof nrow);
    out.write(reinterpret_cast<const char*>(&ncol), sizeof ncol);
    out.write(reinterpret_cast<const char*>(elevations.data()), sizeof elevations);
  }
  struct Remove {
    std::filesystem::path path;
    ~Remove() { std::filesystem::remove(path); }
  } remove{file};
  start(R"(<mujoco model="terrain">
  <asset>
    <hfield name="bumps" size="2 1.5 0.4 0.1" file=")" +
        file.string() + R"("/>
  </asset>
  <worldbody>
    <geom name="ground" type="hfield" hfield="bumps" pos="1 2 0" rgba="0.3 0.6 0.3 1"/>
    <body name="ball" pos="0 0 1"><freejoint/><geom type="sphere" size="0.1"/></body>
  </worldbody>
</mujoco>)");
  const json g = geometry();
  const json ground = geom(g, "ground");
  EXPECT_EQ(ground["type"], "hfield");
  EXPECT_EQ(ground["hfield"], 0);
  EXPECT_FALSE(geom(g, "").contains("hfield"));  // the sphere
  ASSERT_EQ(g["hfields"].size(), 1u) << g.dump();
  const json& hfield = g["hfields"][0];
  EXPECT_EQ(hfield["name"], "bumps");
  EXPECT_EQ(hfield["nrow"], 3);
  EXPECT_EQ(hfield["ncol"], 4);
  expect_numbers(hfield["size"], {2, 1.5, 0.4, 0.1});
  // MuJoCo scales the elevations to 0..1 (divided by the highest): row by row
  std::vector<double> expected;
  for (double e : {0, 1, 2, 3, 1, 2, 3, 4, 0, 0, 4, 2}) expected.push_back(e / 4);
  expect_numbers(hfield["data"], expected);
  for (int i = 0; i < 12; ++i)
    EXPECT_EQ(hfield["data"][i].get<double>(), sim_->m()->hfield_data[i]);
  // without the meshes, no heightfield data either
  EXPECT_EQ(geometry({{"include_meshes", false}})["hfields"], json::array());
}

// A spawn replaces the model: the generation changes (in the answer and in the stream), the
// new body and geom are there, and what was there keeps its ids.
using SimSceneGeometrySpawnTest = testing::DemoSim;

TEST_F(SimSceneGeometrySpawnTest, ASpawnChangesTheGenerationAndAddsItsGeoms) {
  ComponentEntry* simulation = sim_->find("simulation");
  sim_->streams().add(*simulation->component, "simulation", {"test"},
                      SupervisionServices::k_body_poses_frequency);
  auto subscription = sim_->streams().subscribe("simulation", "test", {64, "test", {}});
  const json before = call("simulation", "get_scene_geometry", {false}).value.value();
  const std::uint64_t generation = before["generation"];
  const Outcome spawned = finish(rm_->call(
      "simulation", "spawn_entity",
      {"crate",
       R"(<body><freejoint/><geom name="crate_box" type="box" size="0.1 0.2 0.3" rgba="0.9 0.5 0.1 1"/></body>)",
       {1.0, 1.0, 0.5}}));
  ASSERT_EQ(spawned.status, Status::success) << spawned.message;
  const json after = call("simulation", "get_scene_geometry", {false}).value.value();
  EXPECT_NE(after["generation"], generation);
  EXPECT_EQ(after["generation"], sim_->model_generation());
  EXPECT_EQ(after["bodies"].size(), before["bodies"].size() + 1);
  EXPECT_EQ(after["geoms"].size(), before["geoms"].size() + 1);
  json crate;
  for (const auto& g : after["geoms"])
    if (g["type"] == "box" && g["size"] == json({0.1, 0.2, 0.3})) crate = g;
  ASSERT_FALSE(crate.is_null()) << after["geoms"].dump();
  const int body = crate["body"];
  EXPECT_EQ(after["bodies"][body]["name"], "crate");
  EXPECT_NEAR(after["bodies"][body]["pos"][0].get<double>(), 1.0, 0.05);
  // the geoms that were there are the same, in the same places of the list
  for (std::size_t i = 0; i < before["geoms"].size(); ++i) {
    EXPECT_EQ(after["geoms"][i]["type"], before["geoms"][i]["type"]);
    EXPECT_EQ(after["geoms"][i]["body"], before["geoms"][i]["body"]);
  }
  // the stream's samples carry the new generation and the new body (the next one due: at
  // 30 Hz, within 17 steps of 2 ms)
  std::vector<SamplePtr> samples;
  for (int step = 0;
       step < 40 && (samples.empty() || samples.back()->data()["generation"] == generation);
       ++step) {
    sim_->step();
    subscription->take(samples);
  }
  ASSERT_FALSE(samples.empty());
  EXPECT_EQ(samples.front()->data()["generation"], generation);
  EXPECT_EQ(samples.back()->data()["generation"], sim_->model_generation());
  EXPECT_EQ(samples.back()->data()["poses"].size(), after["bodies"].size());
  sim_->streams().unsubscribe(subscription);
}

// The meshes written once per model: a spawned entity's mesh is in the next answer.
TEST_F(SimSceneGeometrySpawnTest, TheAnswerAfterASpawnHasTheSpawnedMesh) {
  const json before = call("simulation", "get_scene_geometry", {true}).value.value();
  EXPECT_EQ(call("simulation", "get_scene_geometry", {true}).value.value()["meshes"],
            before["meshes"]);
  SceneGeometryCache cache;
  EXPECT_EQ(scene_geometry(*sim_, true, &cache)["meshes"], before["meshes"]);
  const Outcome spawned = finish(rm_->call(
      "simulation", "spawn_entity",
      {"wedge",
       R"(<mujoco><asset><mesh name="wedge_mesh" vertex="0 0 0  1 0 0  0 1 0  0 0 1  1 1 1"/></asset>)"
       R"(<worldbody><body><freejoint/><geom type="mesh" mesh="wedge_mesh"/></body></worldbody></mujoco>)",
       {2.0, 2.0, 0.5}}));
  ASSERT_EQ(spawned.status, Status::success) << spawned.message;
  const json after = call("simulation", "get_scene_geometry", {true}).value.value();
  ASSERT_EQ(after["meshes"].size(), before["meshes"].size() + 1) << after["meshes"].dump();
  EXPECT_EQ(after["meshes"].back()["name"], "wedge_mesh");
  EXPECT_EQ(after["meshes"].back()["vertices"].size(), 15u);
  EXPECT_EQ(after, scene_geometry(*sim_, true));  // the same as written afresh
  EXPECT_EQ(scene_geometry(*sim_, true, &cache)["meshes"], after["meshes"]);
  EXPECT_EQ(cache.builds(), 2u);
}

}  // namespace
}  // namespace simgate::sim
