// ModelEdit: a model's spec edited at run time (model_edit.h): fragments checked and placed,
// attached after the scene whose ids stay, bodies deleted with what refers to them, state
// carried across through the remap (model_remap.h), which refuses models that do not line up.
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

// `model` with `fragment` spawned as `name` at `pose`.
Model spawned(const Model& model, const std::string& name, const std::string& fragment,
              EntityPose pose = {}) {
  return with_entity(EditBase::of(model), name, entity_document(fragment, name, pose));
}

// `model` without its body `name`.
Model deleted(const Model& model, const std::string& name) {
  return without_body(EditBase::of(model), model.body_id(name), name);
}

// `fragment` refused, the message naming the parameter and containing `why`.
void expect_refused(const std::string& fragment, const std::string& why) {
  try {
    entity_mjcf(fragment, "e", {});
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
  const std::string sections = entity_mjcf(k_edit_ball, "ball", pose);
  EXPECT_NE(sections.find("<mujoco><worldbody><body name=\"ball\""), std::string::npos) << sections;
  EXPECT_NE(sections.find("pos=\"1 2 0.5\""), std::string::npos) << sections;
  EXPECT_NE(sections.find("quat=\"0 0 0 1\""), std::string::npos) << sections;
  // one orientation only: the fragment's euler gave way to the pose's quaternion
  EXPECT_EQ(sections.find("euler"), std::string::npos) << sections;
}

TEST(ModelEditTest, WithoutOrientationTheFragmentKeepsItsOwn) {
  const std::string sections = entity_mjcf(k_edit_ball, "ball", {});
  EXPECT_NE(sections.find("euler=\"0 0 90\""), std::string::npos) << sections;
}

TEST(ModelEditTest, MujocoFragmentKeepsItsSections) {
  const std::string sections = entity_mjcf(R"(<mujoco>
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
  expect_refused("<mujoco><option timestep='1'/><worldbody><body/></worldbody></mujoco>",
                 "<option> cannot be spawned");
  expect_refused("<mujoco><keyframe/><worldbody><body/></worldbody></mujoco>",
                 "<keyframe> cannot be spawned");
  expect_refused("<mujoco><worldbody><body/><body/></worldbody></mujoco>", "exactly one <body>");
  expect_refused("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>", "exactly one <body>");
  expect_refused("<mujoco><asset/></mujoco>", "needs a <worldbody>");
  expect_refused("<body><include file='other.xml'/></body>", "<include> is not allowed");
  expect_refused(
      "<mujoco><asset><mesh file='/etc/passwd'/></asset><worldbody><body/></worldbody></mujoco>",
      "without '..'");
  expect_refused(
      "<mujoco><asset><texture "
      "fileup='../../up.png'/></asset><worldbody><body/></worldbody></mujoco>",
      "without '..'");
}

TEST(ModelEditTest, SpawnedEntityComesAfterTheSceneWhoseIdsStay) {
  Model scene = Model::load_file(testing::demo_scene());
  Model with_ball = spawned(scene, "ball", k_edit_ball);
  const mjModel* before = scene.model();
  const mjModel* after = with_ball.model();
  // every object of the scene keeps its id and name
  for (auto [type, n] : {std::pair{mjOBJ_BODY, before->nbody},
                         {mjOBJ_JOINT, before->njnt},
                         {mjOBJ_GEOM, before->ngeom},
                         {mjOBJ_ACTUATOR, before->nu},
                         {mjOBJ_SENSOR, before->nsensor}}) {
    for (int id = 0; id < n; ++id) {
      const char* was = mj_id2name(before, type, id);
      const char* is = mj_id2name(after, type, id);
      EXPECT_EQ(was ? std::string(was) : "", is ? std::string(is) : "")
          << "object type " << type << " id " << id;
    }
  }
  EXPECT_EQ(with_ball.body_id("ball"), before->nbody);
  ASSERT_EQ(with_ball.entities().size(), 1u);
  EXPECT_EQ(with_ball.entities()[0].counts.nbody, 1);
  EXPECT_EQ(with_ball.entities()[0].counts.nq, 7);
  EXPECT_EQ(with_ball.entities()[0].counts.nv, 6);
  // the edited model keeps the scene's name and options
  EXPECT_STREQ(after->names, "simgate-demo");
  EXPECT_EQ(after->opt.integrator, before->opt.integrator);
  EXPECT_EQ(after->opt.timestep, before->opt.timestep);
}

// MuJoCo extends the scene's keyframes with the entity's initial state, and shortens them
// again when a body goes: a scene with keyframes takes spawns and deletes.
TEST(ModelEditTest, AKeyframeSceneTakesAnEntityItsKeysExtendedWithTheEntitysInitialState) {
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
  Model with_ball = spawned(scene, "ball", k_edit_ball, pose);
  const mjModel* m = with_ball.model();
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
  EXPECT_EQ(m->key_time[1], 1);

  // a second entity after the first, then the arm deleted: the keys lose its qpos
  Model two = spawned(with_ball, "other", k_edit_ball);
  EXPECT_EQ(two.model()->nq, 1 + 7 + 7);
  EXPECT_EQ(two.model()->key_qpos[0], 0.5);
  Model armless = deleted(two, "arm");
  ASSERT_EQ(armless.model()->nq, 7 + 7);
  EXPECT_EQ(armless.model()->nkey, 2);
  EXPECT_EQ(armless.model()->key_qpos[0], 7);
  EXPECT_EQ(armless.model()->nu, 0);  // the motor on its hinge went with it
}

TEST(ModelEditTest, DoesNotCompileGivesMujocosMessage) {
  Model scene = Model::load_file(testing::demo_scene());
  try {
    spawned(scene, "ball", "<body><geom type='sphere' size='0.1' material='nope'/></body>");
    FAIL() << "compiled";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("material"), std::string::npos) << e.what();
  }
  // a joint name the scene has
  try {
    spawned(scene, "ball",
            "<body><joint name='robot_root' type='hinge'/><geom size='0.1'/></body>");
    FAIL() << "compiled";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("robot_root"), std::string::npos) << e.what();
  }
}

TEST(ModelEditTest, StateOfTheSceneAndOfSurvivingEntitiesIsCarriedAcross) {
  Model scene = Model::load_file(testing::demo_scene());
  EntityPose at_a, at_b;
  at_a.position = {1, 0, 1};
  at_b.position = {0, 1, 1};
  Model two = spawned(spawned(scene, "a", k_edit_ball, at_a), "b", k_edit_ball, at_b);
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
  Model only_b = deleted(two, "a");
  carry_state(two, only_b,
              ModelRemap::between(two.model(), only_b.model(), two.body_id("a"), false));
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
  ASSERT_EQ(only_b.entities().size(), 1u);
  EXPECT_EQ(only_b.entities()[0].name, "b");
}

// Spawning and deleting the same entity again and again leaves the spec as it was: no
// frame, no body left behind (the bench spawns and deletes thousands of times).
TEST(ModelEditTest, SpawnAndDeleteLeaveNothingBehindInTheSpec) {
  Model scene = Model::load_file(testing::demo_scene());
  auto count = [](const Model& model, mjtObj type) {
    int n = 0;
    for (mjsElement* e = mjs_firstElement(model.spec().get(), type); e;
         e = mjs_nextElement(model.spec().get(), e))
      ++n;
    return n;
  };
  Model model = deleted(spawned(scene, "ball", k_edit_ball), "ball");
  for (int round = 0; round < 3; ++round)
    model = deleted(spawned(model, "ball", k_edit_ball), "ball");
  EXPECT_EQ(count(model, mjOBJ_FRAME), count(scene, mjOBJ_FRAME));
  EXPECT_EQ(count(model, mjOBJ_BODY), count(scene, mjOBJ_BODY));
  EXPECT_EQ(model.model()->nbody, scene.model()->nbody);
  EXPECT_TRUE(model.entities().empty());
}

// MuJoCo 4 keeps each actuator's activations where the actuator is (actuator_actadr), not
// last as 2.2.2 did: a filter actuator before a motor keeps its activation across an edit.
TEST(ModelEditTest, AnActivationIsCarriedAcrossWhereverItsActuatorIs) {
  Model scene = Model::load_string(R"(<mujoco>
    <worldbody><body name="arm"><joint name="hinge"/><joint name="twist" axis="1 0 0"/>
      <geom type="capsule" size=".05" fromto="0 0 0 .3 0 0"/></body></worldbody>
    <actuator>
      <general name="filtered" joint="hinge" dyntype="filter" dynprm="0.5"/>
      <motor name="plain" joint="twist"/>
      <general name="integrated" joint="twist" dyntype="integrator"/>
    </actuator>
  </mujoco>)");
  scene.data()->act[scene.model()->actuator_actadr[scene.actuator_id("filtered")]] = 0.75;
  scene.data()->act[scene.model()->actuator_actadr[scene.actuator_id("integrated")]] = -0.5;
  Model with_ball = spawned(scene, "ball", k_edit_ball);
  carry_state(scene, with_ball, ModelRemap::between(scene.model(), with_ball.model(), -1, true));
  const mjModel* m = with_ball.model();
  EXPECT_EQ(with_ball.data()->act[m->actuator_actadr[with_ball.actuator_id("filtered")]], 0.75);
  EXPECT_EQ(with_ball.data()->act[m->actuator_actadr[with_ball.actuator_id("integrated")]], -0.5);
}

// Edits start from the model's spec: the scene file is not read again (a file changed since
// does not leak in), nothing is written beside it, and a fragment's meshes resolve where the
// scene's do (its directory and meshdir).
TEST(ModelEditTest, EditsStartFromTheSpecAndFragmentFilesResolveAsTheScenes) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("simgate_model_edit_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "assets");
  std::ofstream(dir / "parts.xml")
      << "<mujoco><body name='part'><geom type='sphere' size='.1'/></body></mujoco>";
  std::ofstream(dir / "assets" / "tetra.obj")
      << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n";
  std::ofstream(dir / "scene.xml") << "<mujoco model='parts'><compiler meshdir='assets'/>"
                                      "<worldbody><include file='parts.xml'/></worldbody></mujoco>";
  Model scene = Model::load_file((dir / "scene.xml").string());
  std::ofstream(dir / "scene.xml") << "<mujoco/>";
  Model with_tetra = spawned(
      scene, "tetra",
      "<mujoco><asset><mesh name='tetra' file='tetra.obj'/></asset>"
      "<worldbody><body><freejoint/><geom type='mesh' mesh='tetra'/></body></worldbody></mujoco>");
  EXPECT_GE(with_tetra.body_id("part"), 0);
  EXPECT_GE(with_tetra.body_id("tetra"), 0);
  EXPECT_EQ(with_tetra.model()->nmesh, 1);
  // a body of the included file can be deleted too
  Model partless = deleted(with_tetra, "part");
  EXPECT_EQ(partless.body_id("part"), -1);
  EXPECT_GE(partless.body_id("tetra"), 0);
  std::size_t files = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    files += entry.is_regular_file();
  EXPECT_EQ(files, 3u);
  std::filesystem::remove_all(dir);
}

// ModelRemap checks what it maps: survivors keep their names, the counts add up.
TEST(ModelEditTest, ARemapBetweenModelsThatDoNotLineUpIsRefused) {
  Model scene = Model::load_file(testing::demo_scene());
  Model other = Model::load_string(
      "<mujoco><worldbody><body name='a'><freejoint/><geom "
      "size='.1'/></body></worldbody></mujoco>");
  // nothing removed, nothing appended: the same model maps onto itself
  const ModelRemap same = ModelRemap::between(scene.model(), scene.model(), -1, false);
  EXPECT_FALSE(same.moves_ids());
  // a body of another name where the robot should be
  try {
    ModelRemap::between(scene.model(), other.model(), -1, true);
    FAIL() << "unrelated models were remapped";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("'robot' is not where expected"), std::string::npos)
        << e.what();
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
