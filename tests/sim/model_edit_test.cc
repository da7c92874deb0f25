// ModelEdit: a scene recompiled with entities spawned into it (model_edit.h): fragments
// checked and placed, ids of the scene kept, state carried across through the remap
// (model_remap.h), which refuses models that do not line up.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "simgate/core/errors.h"
#include "simgate/sim/model_edit.h"
#include "sim_fixture.h"

namespace simgate::sim {
namespace {

constexpr const char* k_edit_ball = R"(<body name="ignored" euler="0 0 90"><freejoint/>
  <geom type="sphere" size="0.1" mass="1"/></body>)";

// One spawned entity of `model`'s scene: `fragment` as `name` at `pose`.
SpawnedEntity entity(const std::string& name, const std::string& fragment, EntityPose pose = {}) {
  return {name, entity_sections(fragment, name, pose), {}};
}

// `fragment` refused, the message naming the parameter and containing `why`.
void expect_refused(const std::string& fragment, const std::string& why) {
  try {
    entity_sections(fragment, "e", {});
    ADD_FAILURE() << "accepted: " << fragment;
  } catch (const ServiceError& e) {
    EXPECT_EQ(e.failure(), Failure::bad_arguments);
    EXPECT_EQ(e.data().value("parameter", ""), "mjcf");
    EXPECT_NE(e.message().find(why), std::string::npos) << e.message();
  }
}

TEST(ModelEditTest, BodyFragmentIsNamedAndPlaced) {
  EntityPose pose;
  pose.position = {1, 2, 0.5};
  pose.orientation = std::array<double, 4>{0, 0, 0, 1};
  const std::string sections = entity_sections(k_edit_ball, "ball", pose);
  EXPECT_NE(sections.find("<worldbody><body name=\"ball\""), std::string::npos) << sections;
  EXPECT_NE(sections.find("pos=\"1 2 0.5\""), std::string::npos) << sections;
  EXPECT_NE(sections.find("quat=\"0 0 0 1\""), std::string::npos) << sections;
  // one orientation only: the fragment's euler gave way to the pose's quaternion
  EXPECT_EQ(sections.find("euler"), std::string::npos) << sections;
}

TEST(ModelEditTest, WithoutOrientationTheFragmentKeepsItsOwn) {
  const std::string sections = entity_sections(k_edit_ball, "ball", {});
  EXPECT_NE(sections.find("euler=\"0 0 90\""), std::string::npos) << sections;
}

TEST(ModelEditTest, MujocoFragmentKeepsItsSections) {
  const std::string sections = entity_sections(R"(<mujoco>
      <asset><material name="red" rgba="1 0 0 1"/></asset>
      <worldbody><body><joint name="spin" type="hinge"/><geom type="box" size=".1 .1 .1" material="red"/></body></worldbody>
      <actuator><motor name="spin_motor" joint="spin"/></actuator>
    </mujoco>)",
                                               "spinner", {});
  EXPECT_NE(sections.find("<asset>"), std::string::npos);
  EXPECT_NE(sections.find("<body name=\"spinner\""), std::string::npos);
  EXPECT_NE(sections.find("<actuator><motor name=\"spin_motor\""), std::string::npos) << sections;
}

TEST(ModelEditTest, BadFragmentsAreRefusedNamingTheReason) {
  expect_refused("<body><geom", "not well-formed XML");
  expect_refused("<geom type='sphere' size='1'/>", "found <geom>");
  expect_refused("<body/><body/>", "one root element");
  expect_refused("<mujoco><option timestep='1'/><worldbody><body/></worldbody></mujoco>", "<option> cannot be spawned");
  expect_refused("<mujoco><keyframe/><worldbody><body/></worldbody></mujoco>", "<keyframe> cannot be spawned");
  expect_refused("<mujoco><worldbody><body/><body/></worldbody></mujoco>", "exactly one <body>");
  expect_refused("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>", "exactly one <body>");
  expect_refused("<mujoco><asset/></mujoco>", "needs a <worldbody>");
  expect_refused("<body><include file='other.xml'/></body>", "<include> is not allowed");
  expect_refused("<mujoco><asset><mesh file='/etc/passwd'/></asset><worldbody><body/></worldbody></mujoco>",
                 "without '..'");
  expect_refused("<mujoco><asset><texture fileup='../../up.png'/></asset><worldbody><body/></worldbody></mujoco>",
                 "without '..'");
}

TEST(ModelEditTest, SpawnedEntityComesAfterTheSceneWhoseIdsStay) {
  Model scene = Model::load_file(testing::demo_scene());
  Model spawned = compile_scene(scene.scene(), {entity("ball", k_edit_ball)}, true);
  const mjModel* before = scene.model();
  const mjModel* after = spawned.model();
  // every object of the scene keeps its id and name
  for (auto [type, n] : {std::pair{mjOBJ_BODY, before->nbody}, {mjOBJ_JOINT, before->njnt}, {mjOBJ_GEOM, before->ngeom},
                         {mjOBJ_ACTUATOR, before->nu}, {mjOBJ_SENSOR, before->nsensor}}) {
    for (int id = 0; id < n; ++id) {
      const char* was = mj_id2name(before, type, id);
      const char* is = mj_id2name(after, type, id);
      EXPECT_EQ(was ? std::string(was) : "", is ? std::string(is) : "") << "object type " << type << " id " << id;
    }
  }
  EXPECT_EQ(spawned.body_id("ball"), before->nbody);
  ASSERT_EQ(spawned.entities().size(), 1u);
  EXPECT_EQ(spawned.entities()[0].counts.nbody, 1);
  EXPECT_EQ(spawned.entities()[0].counts.nq, 7);
  EXPECT_EQ(spawned.entities()[0].counts.nv, 6);
  // the recompiled model keeps the scene's name and options
  EXPECT_STREQ(after->names, "simgate-demo");
  EXPECT_EQ(after->opt.integrator, before->opt.integrator);
}

// MuJoCo 2.2.2 wants every keyframe array sized to the whole model: a scene's keys are
// padded with the spawned entity's initial state (it did not compile before).
TEST(ModelEditTest, AKeyframeSceneTakesAnEntityItsKeysPaddedWithTheEntitysInitialState) {
  Model scene = Model::load_string(R"(<mujoco model="keyed">
    <worldbody>
      <body name="arm"><joint name="hinge" type="hinge"/><geom type="capsule" size=".05" fromto="0 0 0 .3 0 0"/></body>
      <body name="target" mocap="true" pos="1 2 3"><geom type="sphere" size=".05" contype="0" conaffinity="0"/></body>
    </worldbody>
    <actuator><motor joint="hinge"/></actuator>
    <keyframe>
      <key name="bent" qpos="0.5" qvel="0.25" ctrl="0.125" mpos="4 5 6"/>
      <key name="bare" time="1"/>
    </keyframe>
  </mujoco>)");
  EntityPose pose;
  pose.position = {7, 8, 9};
  Model spawned = compile_scene(scene.scene(), {entity("ball", k_edit_ball, pose)}, true);
  const mjModel* m = spawned.model();
  ASSERT_EQ(m->nkey, 2);
  ASSERT_EQ(m->nq, 1 + 7);
  // the scene's part as written, the ball's at its initial state (its pose, no velocity)
  EXPECT_EQ(m->key_qpos[0], 0.5);
  EXPECT_EQ(m->key_qpos[1], 7);
  EXPECT_EQ(m->key_qpos[2], 8);
  EXPECT_EQ(m->key_qpos[3], 9);
  for (int i = 1; i < m->nq; ++i) EXPECT_EQ(m->key_qpos[i], m->qpos0[i]) << "qpos " << i;
  EXPECT_EQ(m->key_qvel[0], 0.25);
  for (int i = 1; i < m->nv; ++i) EXPECT_EQ(m->key_qvel[i], 0) << "qvel " << i;
  EXPECT_EQ(m->key_ctrl[0], 0.125);
  EXPECT_EQ(m->key_mpos[0], 4);
  // the key that gave nothing is MuJoCo's default: the model's initial state
  EXPECT_EQ(m->key_time[1], 1);
  for (int i = 0; i < m->nq; ++i) EXPECT_EQ(m->key_qpos[m->nq + i], m->qpos0[i]) << "qpos " << i;

  // a second entity after the first, and back to the scene alone
  Model two = compile_scene(scene.scene(), {spawned.entities()[0], entity("other", k_edit_ball)}, true);
  EXPECT_EQ(two.model()->nq, 1 + 7 + 7);
  EXPECT_EQ(two.model()->key_qpos[0], 0.5);
  Model alone = compile_scene(scene.scene(), {}, false);
  EXPECT_EQ(alone.model()->nq, 1);
  EXPECT_EQ(alone.model()->key_qpos[0], 0.5);
}

TEST(ModelEditTest, DoesNotCompileGivesMujocosMessage) {
  Model scene = Model::load_file(testing::demo_scene());
  try {
    compile_scene(scene.scene(), {entity("ball", "<body><geom type='sphere' size='0.1' material='nope'/></body>")},
                  true);
    FAIL() << "compiled";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("material"), std::string::npos) << e.what();
  }
}

TEST(ModelEditTest, StateOfTheSceneAndOfSurvivingEntitiesIsCarriedAcross) {
  Model scene = Model::load_file(testing::demo_scene());
  EntityPose at_a, at_b;
  at_a.position = {1, 0, 1};
  at_b.position = {0, 1, 1};
  Model two = compile_scene(scene.scene(), {entity("a", k_edit_ball, at_a)}, true);
  std::vector<SpawnedEntity> with_b = two.entities();
  with_b.push_back(entity("b", k_edit_ball, at_b));
  two = compile_scene(scene.scene(), with_b, true);
  // a moved state: the robot, and b
  mjData* d = two.data();
  const mjModel* m = two.model();
  d->time = 12.5;
  d->qpos[m->jnt_qposadr[two.joint_id("robot_root")]] = 4.0;
  const int b_root = m->jnt_qposadr[m->body_jntadr[two.body_id("b")]];
  d->qpos[b_root + 2] = 3.0;
  d->qvel[m->jnt_dofadr[m->body_jntadr[two.body_id("b")]]] = 0.25;
  d->ctrl[two.actuator_id("robot_left_motor")] = 7.0;

  // delete a: b moves forward in every array, and keeps its state
  Model only_b = compile_scene(scene.scene(), {two.entities()[1]}, false);
  carry_state(two, only_b, ModelRemap::between(two.model(), only_b.model(), two.body_id("a"), false));
  const mjModel* m2 = only_b.model();
  const mjData* d2 = only_b.data();
  EXPECT_EQ(d2->time, 12.5);
  EXPECT_EQ(d2->qpos[m2->jnt_qposadr[only_b.joint_id("robot_root")]], 4.0);
  EXPECT_EQ(d2->ctrl[only_b.actuator_id("robot_left_motor")], 7.0);
  const int b_root2 = m2->jnt_qposadr[m2->body_jntadr[only_b.body_id("b")]];
  EXPECT_LT(b_root2, b_root);
  EXPECT_EQ(d2->qpos[b_root2 + 2], 3.0);
  EXPECT_EQ(d2->qvel[m2->jnt_dofadr[m2->body_jntadr[only_b.body_id("b")]]], 0.25);
  EXPECT_EQ(only_b.body_id("a"), -1);
}

TEST(ModelEditTest, SceneRelativeIncludesResolveAndTheSceneDirectoryIsNotWritten) {
  const auto dir = std::filesystem::temp_directory_path() / ("simgate_model_edit_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "parts.xml") << "<mujoco><body name='part'><geom type='sphere' size='.1'/></body></mujoco>";
  std::ofstream(dir / "scene.xml") << "<mujoco model='parts'><worldbody><include file='parts.xml'/></worldbody></mujoco>";
  Model scene = Model::load_file((dir / "scene.xml").string());
  // the file changes after loading: recompilations start from the text first read
  std::ofstream(dir / "scene.xml") << "<mujoco/>";
  Model spawned = compile_scene(scene.scene(), {entity("ball", k_edit_ball)}, true);
  EXPECT_GE(spawned.body_id("part"), 0);
  EXPECT_GE(spawned.body_id("ball"), 0);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()), 2);
  std::filesystem::remove_all(dir);
}

// ModelRemap checks what it maps: survivors keep their names, the counts add up.
TEST(ModelEditTest, ARemapBetweenModelsThatDoNotLineUpIsRefused) {
  Model scene = Model::load_file(testing::demo_scene());
  Model other = Model::load_string(
      "<mujoco><worldbody><body name='a'><freejoint/><geom size='.1'/></body></worldbody></mujoco>");
  // nothing removed, nothing appended: the same model maps onto itself
  const ModelRemap same = ModelRemap::between(scene.model(), scene.model(), -1, false);
  EXPECT_FALSE(same.moves_ids());
  // a body of another name where the robot should be
  try {
    ModelRemap::between(scene.model(), other.model(), -1, true);
    FAIL() << "unrelated models were remapped";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("'robot' is not where expected"), std::string::npos) << e.what();
  }
  // the crates removed, but the new model still holds them: the counts do not add up
  try {
    ModelRemap::between(scene.model(), scene.model(), scene.body_id("crate1"), false);
    FAIL() << "a removal the new model does not show was remapped";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("expected"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace simgate::sim
