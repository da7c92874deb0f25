// SimModel: loading MJCF scenes, MuJoCo errors as exceptions (never a process exit).
#include <algorithm>
#include <string>

#include <gtest/gtest.h>

#include "simgate/core/log.h"
#include "simgate/sim/model.h"
#include "sim_fixture.h"

namespace simgate::sim {
namespace {

constexpr const char* k_box = R"(<mujoco><worldbody>
  <body name="box" pos="0 0 1"><freejoint name="box_root"/><geom type="box" size=".1 .1 .1"/></body>
</worldbody></mujoco>)";

TEST(SimModelTest, LoadsInlineSceneAndFindsNames) {
  Model m = Model::load_string(k_box);
  EXPECT_GT(m.body_id("box"), 0);
  EXPECT_EQ(m.body_id("nope"), -1);
  EXPECT_EQ(m.free_joint_of(m.body_id("box")), m.joint_id("box_root"));
  EXPECT_EQ(m.body_name(m.body_id("box")), "box");
}

TEST(SimModelTest, LoadsTheDemoScene) {
  Model m = Model::load_file(testing::demo_scene());
  EXPECT_GT(m.body_id("robot"), 0);
  EXPECT_GE(m.actuator_id("robot_left_motor"), 0);
}

TEST(SimModelTest, InvalidXmlIsAnExceptionNamingTheScene) {
  try {
    Model::load_string(
        "<mujoco><worldbody><body name='x'><geom type='sphere'/></worldbod></mujoco>",
        "broken.xml");
    FAIL() << "no exception";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.xml"), std::string::npos) << e.what();
  }
}

TEST(SimModelTest, MissingFileNamesThePath) {
  try {
    Model::load_file("/nonexistent/scene.xml");
    FAIL() << "no exception";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.xml"), std::string::npos) << e.what();
  }
}

TEST(SimModelTest, EngineErrorBecomesAnExceptionNotAnExit) {
  install_mujoco_handlers();
  EXPECT_THROW(mju_error("deliberate test error"), MujocoError);
}

TEST(SimModelTest, EngineWarningBecomesALogLine) {
  install_mujoco_handlers();
  std::vector<std::string> lines;
  log::set_sink([&](log::Level level, std::string_view text) {
    if (level == log::Level::warning) lines.emplace_back(text);
  });
  mju_warning("deliberate test warning");
  log::set_sink({});
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("deliberate test warning"), std::string::npos);
}

// ---- the current MuJoCo (issue #36) ---------------------------------------------------------

TEST(SimModelTest, MujocosEnginePluginsAreLoadedFromBesideItsLibrary) {
  install_mujoco_handlers();
  const EnginePlugins& plugins = engine_plugins();
  EXPECT_FALSE(plugins.directory.empty());
  for (const char* name : {"mujoco.pid", "mujoco.sensor.touch_grid"})
    EXPECT_NE(std::find(plugins.names.begin(), plugins.names.end(), name), plugins.names.end())
        << name << " not among " << ::testing::PrintToString(plugins.names);
}

TEST(SimModelTest, AModelOfTheCurrentMujocoLoadsAndItsPidActuatorHoldsTheTarget) {
  // an actuator plugin, actuatorfrcrange, <frame>, <replicate>, <flexcomp>: all refused by 2.2.2
  Model m = Model::load_file(testing::test_model("current_mujoco.xml"));
  EXPECT_EQ(m.model()->nplugin, 1);
  int posts = 0;  // <replicate>'s four copies, named post + a suffix
  for (int b = 0; b < m.model()->nbody; ++b) posts += m.body_name(b).rfind("post", 0) == 0;
  EXPECT_EQ(posts, 4);
  EXPECT_EQ(m.model()->nflex, 1);
  const int swing = m.joint_id("swing");
  ASSERT_GE(swing, 0);
  EXPECT_EQ(m.model()->jnt_actfrclimited[swing], 1);
  // the PID drives the pendulum to 0.5 rad (its ctrl) and holds it there
  const int pid = m.actuator_id("swing_pid");
  ASSERT_GE(pid, 0);
  m.data()->ctrl[pid] = 0.5;
  for (int i = 0; i < 2500; ++i) mj_step(m.model(), m.data());  // 5 s
  EXPECT_NEAR(m.data()->qpos[m.model()->jnt_qposadr[swing]], 0.5, 0.05);
}

TEST(SimModelTest, AModelUsingAPluginNobodyRegisteredIsRefusedNamingIt) {
  try {
    Model::load_string(R"(<mujoco><extension><plugin plugin="no.such.plugin"/></extension>
      <worldbody><body><geom size="0.1"/></body></worldbody></mujoco>)",
                       "unknown-plugin.xml");
    FAIL() << "no exception";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("no.such.plugin"), std::string::npos) << e.what();
  }
}

TEST(SimModelTest, SteppingTheModelMovesTheFreeBody) {
  Model m = Model::load_string(k_box);
  double z0 = m.data()->xpos[3 * m.body_id("box") + 2];
  for (int i = 0; i < 100; ++i) mj_step(m.model(), m.data());
  EXPECT_LT(m.data()->xpos[3 * m.body_id("box") + 2], z0);  // it falls
}

}  // namespace
}  // namespace simgate::sim
