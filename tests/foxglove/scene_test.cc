// The simulation's scene in Foxglove's schemas (simgate/foxglove/scene.h): frames named from
// get_scene_geometry, body poses as transforms from the world, geoms as primitives sized as
// Foxglove draws them (full extents, where MuJoCo gives half ones).
#include "simgate/foxglove/scene.h"

#include <gtest/gtest.h>

namespace simgate::foxglove {
namespace {

// A get_scene_geometry answer: the world, a body "arm" and an unnamed one.
json geometry() {
  return json{
      {"timestamp", 2.5},
      {"generation", 3},
      {"bodies",
       {{{"id", 0}, {"name", "world"}, {"parent", 0}},
        {{"id", 1}, {"name", "arm"}, {"parent", 0}},
        {{"id", 2}, {"name", ""}, {"parent", 1}}}},
      {"geoms",
       {{{"body", 0},
         {"type", "plane"},
         {"size", {0, 0, 0.1}},
         {"rgba", {1, 1, 1, 1}},
         {"pos", {0, 0, 0}},
         {"quat", {1, 0, 0, 0}}},
        {{"body", 1},
         {"type", "box"},
         {"size", {0.1, 0.2, 0.3}},
         {"rgba", {1, 0, 0, 1}},
         {"pos", {1, 2, 3}},
         {"quat", {1, 0, 0, 0}}},
        {{"body", 1},
         {"type", "capsule"},
         {"size", {0.05, 0.5, 0}},
         {"rgba", {0, 1, 0, 0.5}},
         {"pos", {0, 0, 1}},
         {"quat", {1, 0, 0, 0}}},
        {{"body", 2},
         {"type", "mesh"},
         {"mesh", 0},
         {"size", {1, 1, 1}},
         {"rgba", {0, 0, 1, 1}},
         {"pos", {0, 0, 0}},
         {"quat", {1, 0, 0, 0}}},
        {{"body", 2}, {"type", "hfield"}, {"hfield", 0}, {"size", {1, 1, 1}}}}},
      {"meshes",
       {{{"name", "tri"}, {"vertices", {0, 0, 0, 1, 0, 0, 0, 1, 0}}, {"faces", {0, 1, 2, 7}}}}}};
}

TEST(FoxgloveScene, FramesAreTheBodiesNames) {
  const SceneFrames frames = SceneFrames::from_geometry(geometry());
  EXPECT_EQ(frames.generation, 3u);
  EXPECT_EQ(frames.names, (std::vector<std::string>{"world", "arm", "body2"}));
  EXPECT_FALSE(SceneFrames::from_geometry(json::object()).known());
}

TEST(FoxgloveScene, ComponentsFramesHangFromTheirBodies) {
  json g = geometry();
  g["frames"] = {
      {{"name", "arm.laser"}, {"body", 1}, {"pos", {0.1, 0, 0.2}}, {"quat", {0, 1, 0, 0}}},
      {{"name", "nowhere"}, {"body", 9}},  // no such body: left out
      {{"body", 1}}};                      // no name: left out
  const SceneFrames frames = SceneFrames::from_geometry(g);
  ASSERT_EQ(frames.fixed.size(), 1u);
  const json poses{
      {"timestamp", 1.25},
      {"generation", 3},
      {"poses", {{0, 0, 0, 1, 0, 0, 0}, {1, 2, 3, 1, 0, 0, 0}, {4, 5, 6, 1, 0, 0, 0}}}};
  const json message = json::parse(frame_transforms(poses, frames));
  ASSERT_EQ(message["transforms"].size(), 3u);  // two bodies, then the laser's frame
  const json& laser = message["transforms"][2];
  EXPECT_EQ(laser["parent_frame_id"], "arm");
  EXPECT_EQ(laser["child_frame_id"], "arm.laser");
  EXPECT_EQ(laser["translation"], (json{{"x", 0.1}, {"y", 0}, {"z", 0.2}}));
  EXPECT_EQ(laser["rotation"], (json{{"x", 1}, {"y", 0}, {"z", 0}, {"w", 0}}));
  EXPECT_EQ(laser["timestamp"], (json{{"sec", 1}, {"nsec", 250000000}}));
}

TEST(FoxgloveScene, AWorldsFramesBeginWithItsPrefix) {
  // world 1's frames apart from world 0's in a client that shows both: every frame id,
  // the root's and the components' too, begins "w1/"; the scene's entities hang from them
  json g = geometry();
  g["frames"] = {{{"name", "arm.laser"}, {"body", 1}}};
  const SceneFrames frames = SceneFrames::from_geometry(g, "w1/");
  EXPECT_EQ(frames.names, (std::vector<std::string>{"w1/world", "w1/arm", "w1/body2"}));
  const json poses{
      {"generation", 3},
      {"poses", {{0, 0, 0, 1, 0, 0, 0}, {1, 2, 3, 1, 0, 0, 0}, {4, 5, 6, 1, 0, 0, 0}}}};
  const json message = json::parse(frame_transforms(poses, frames));
  ASSERT_EQ(message["transforms"].size(), 3u);
  EXPECT_EQ(message["transforms"][0]["parent_frame_id"], "w1/world");
  EXPECT_EQ(message["transforms"][0]["child_frame_id"], "w1/arm");
  EXPECT_EQ(message["transforms"][2]["parent_frame_id"], "w1/arm");
  EXPECT_EQ(message["transforms"][2]["child_frame_id"], "w1/arm.laser");
  const json scene = json::parse(scene_update(g, frames));
  ASSERT_FALSE(scene["entities"].empty());
  for (const json& entity : scene["entities"])
    EXPECT_TRUE(entity["frame_id"].get<std::string>().starts_with("w1/")) << entity["frame_id"];
}

TEST(FoxgloveScene, BodyPosesBecomeTransformsFromTheWorld) {
  const SceneFrames frames = SceneFrames::from_geometry(geometry());
  const json poses{
      {"timestamp", 1.25},
      {"generation", 3},
      {"poses", {{0, 0, 0, 1, 0, 0, 0}, {1, 2, 3, 0.5, 0.5, 0.5, 0.5}, {4, 5, 6, 1, 0, 0, 0}}}};
  const json message = json::parse(frame_transforms(poses, frames));
  ASSERT_EQ(message["transforms"].size(), 2u);  // not the world itself
  const json& arm = message["transforms"][0];
  EXPECT_EQ(arm["parent_frame_id"], "world");
  EXPECT_EQ(arm["child_frame_id"], "arm");
  EXPECT_EQ(arm["timestamp"], (json{{"sec", 1}, {"nsec", 250000000}}));
  EXPECT_EQ(arm["translation"], (json{{"x", 1}, {"y", 2}, {"z", 3}}));
  // MuJoCo's [w, x, y, z] as Foxglove's {x, y, z, w}
  EXPECT_EQ(arm["rotation"], (json{{"x", 0.5}, {"y", 0.5}, {"z", 0.5}, {"w", 0.5}}));
  EXPECT_EQ(message["transforms"][1]["child_frame_id"], "body2");
  // a sample of another model, or of another body count, makes nothing
  json other = poses;
  other["generation"] = 4;
  EXPECT_EQ(frame_transforms(other, frames), "");
  other = poses;
  other["poses"].erase(2);
  EXPECT_EQ(frame_transforms(other, frames), "");
  EXPECT_EQ(frame_transforms(json::array(), frames), "");
}

TEST(FoxgloveScene, GeomsBecomePrimitivesOnTheirBodysFrame) {
  const SceneFrames frames = SceneFrames::from_geometry(geometry());
  const json message = json::parse(scene_update(geometry(), frames));
  EXPECT_EQ(message["deletions"],
            (json{{{"timestamp", {{"sec", 2}, {"nsec", 500000000}}}, {"type", 1}, {"id", ""}}}));
  ASSERT_EQ(message["entities"].size(), 3u);
  const json& world = message["entities"][0];
  EXPECT_EQ(world["id"], "body/world");
  // an infinite plane is drawn 20 m wide, one millimetre thin
  EXPECT_EQ(world["cubes"][0]["size"], (json{{"x", 20}, {"y", 20}, {"z", 0.001}}));
  const json& arm = message["entities"][1];
  EXPECT_EQ(arm["frame_id"], "arm");
  EXPECT_TRUE(arm["frame_locked"].get<bool>());
  EXPECT_EQ(arm["lifetime"], (json{{"sec", 0}, {"nsec", 0}}));  // until the model changes
  // the box: MuJoCo's half sizes doubled, at its pose, in its colour
  EXPECT_EQ(arm["cubes"][0]["size"], (json{{"x", 0.2}, {"y", 0.4}, {"z", 0.6}}));
  EXPECT_EQ(arm["cubes"][0]["pose"]["position"], (json{{"x", 1}, {"y", 2}, {"z", 3}}));
  EXPECT_EQ(arm["cubes"][0]["color"], (json{{"r", 1}, {"g", 0}, {"b", 0}, {"a", 1}}));
  // the capsule: a cylinder of its length and two spheres at its ends
  ASSERT_EQ(arm["cylinders"].size(), 1u);
  EXPECT_EQ(arm["cylinders"][0]["size"], (json{{"x", 0.1}, {"y", 0.1}, {"z", 1.0}}));
  ASSERT_EQ(arm["spheres"].size(), 2u);
  EXPECT_DOUBLE_EQ(arm["spheres"][0]["pose"]["position"]["z"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(arm["spheres"][1]["pose"]["position"]["z"].get<double>(), 1.5);
  // the mesh: its triangles (an index past the vertices dropped); the heightfield, whose data
  // the answer lacks: nothing
  const json& body2 = message["entities"][2];
  EXPECT_EQ(body2["frame_id"], "body2");
  ASSERT_EQ(body2["triangles"].size(), 1u);
  EXPECT_EQ(body2["triangles"][0]["points"].size(), 3u);
  EXPECT_EQ(body2["triangles"][0]["indices"], (json{0, 1, 2}));
}

TEST(FoxgloveScene, AHeightfieldIsTheTrianglesOfItsGrid) {
  json g = geometry();
  // 2 rows (y = -1, 1) of 3 columns (x = -2, 0, 2), elevations times the top's 0.5
  g["hfields"] = {{{"name", "ground"},
                   {"size", {2, 1, 0.5, 0.1}},
                   {"nrow", 2},
                   {"ncol", 3},
                   {"data", {0, 0.5, 1, 1, 0.5, 0}}}};
  const json message = json::parse(scene_update(g, SceneFrames::from_geometry(g)));
  const json& body2 = message["entities"][2];
  ASSERT_EQ(body2["triangles"].size(), 2u);  // the mesh, then the heightfield
  const json& field = body2["triangles"][1];
  ASSERT_EQ(field["points"].size(), 6u);
  EXPECT_EQ(field["points"][0], (json{{"x", -2}, {"y", -1}, {"z", 0}}));
  EXPECT_EQ(field["points"][2], (json{{"x", 2}, {"y", -1}, {"z", 0.5}}));
  EXPECT_EQ(field["points"][3], (json{{"x", -2}, {"y", 1}, {"z", 0.5}}));
  // two cells, two triangles each, counterclockwise seen from above
  EXPECT_EQ(field["indices"], (json{0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4}));
  // a grid whose data does not fill it is not drawn
  g["hfields"][0]["data"].erase(5);
  const json short_field = json::parse(scene_update(g, SceneFrames::from_geometry(g)));
  EXPECT_EQ(short_field["entities"][2]["triangles"].size(), 1u);
}

TEST(FoxgloveScene, TheSchemasNameFoxglovesMessages) {
  EXPECT_EQ(frame_transforms_schema()["title"], "foxglove.FrameTransforms");
  EXPECT_EQ(scene_update_schema()["title"], "foxglove.SceneUpdate");
  EXPECT_EQ(scene_update_schema()["required"], (json{"deletions", "entities"}));
}

}  // namespace
}  // namespace simgate::foxglove
