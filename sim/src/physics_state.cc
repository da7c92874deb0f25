#include "simgate/sim/physics_state.h"

#include <cstring>

#include "simgate/sim/mujoco_compat.h"

namespace simgate::sim {

#if SIMGATE_MUJOCO_LEGACY
namespace {

// One mjData array of the state, and its length in the model.
struct StateArray {
  mjtNum* mjData::*field;
  int (*size)(const mjModel*);
};

// What the next step reads, besides time (MuJoCo 2.2.2's mj_step inputs).
const StateArray k_state_arrays[] = {
    {&mjData::qpos, [](const mjModel* m) { return m->nq; }},
    {&mjData::qvel, [](const mjModel* m) { return m->nv; }},
    {&mjData::act, [](const mjModel* m) { return m->na; }},
    {&mjData::ctrl, [](const mjModel* m) { return m->nu; }},
    {&mjData::qacc_warmstart, [](const mjModel* m) { return m->nv; }},
    {&mjData::qfrc_applied, [](const mjModel* m) { return m->nv; }},
    {&mjData::xfrc_applied, [](const mjModel* m) { return 6 * m->nbody; }},
    {&mjData::mocap_pos, [](const mjModel* m) { return 3 * m->nmocap; }},
    {&mjData::mocap_quat, [](const mjModel* m) { return 4 * m->nmocap; }},
    {&mjData::userdata, [](const mjModel* m) { return m->nuserdata; }},
};

std::size_t state_size(const mjModel* m) {
  std::size_t n = 0;
  for (const auto& a : k_state_arrays) n += static_cast<std::size_t>(a.size(m));
  return n;
}

std::size_t warmstart_offset(const mjModel* m) {
  std::size_t offset = 0;
  for (const auto& a : k_state_arrays) {
    if (a.field == &mjData::qacc_warmstart) break;
    offset += static_cast<std::size_t>(a.size(m));
  }
  return offset;
}

}  // namespace

void PhysicsState::capture(const mjModel* m, const mjData* d, std::uint64_t generation) {
  values_.resize(state_size(m));  // no allocation when it held the same model's
  mjtNum* out = values_.data();
  for (const auto& a : k_state_arrays) {
    const auto n = static_cast<std::size_t>(a.size(m));
    std::memcpy(out, d->*a.field, sizeof(mjtNum) * n);
    out += n;
  }
  time_ = d->time;
  generation_ = generation;
  captured_ = true;
}

bool PhysicsState::fits(const mjModel* m, std::uint64_t generation) const {
  return captured_ && generation_ == generation && values_.size() == state_size(m);
}

void PhysicsState::apply(const mjModel* m, mjData* d) const {
  d->time = time_;
  const mjtNum* in = values_.data();
  for (const auto& a : k_state_arrays) {
    const auto n = static_cast<std::size_t>(a.size(m));
    std::memcpy(d->*a.field, in, sizeof(mjtNum) * n);
    in += n;
  }
}

void PhysicsState::apply_warmstart(const mjModel* m, mjData* d) const {
  std::memcpy(d->qacc_warmstart, values_.data() + warmstart_offset(m), sizeof(mjtNum) * static_cast<std::size_t>(m->nv));
}

#else  // MuJoCo 3.x and later: its own definition of what the next step reads

namespace {

// mjSTATE_INTEGRATION: time, qpos, qvel, act, the history buffers, the plastic state, the
// plugins' state, ctrl, the applied forces, eq_active, the mocap poses, userdata and the
// warm start: "everything required to reproduce the next step" (mjtState).
constexpr int k_signature = mjSTATE_INTEGRATION;

std::size_t state_size(const mjModel* m) { return static_cast<std::size_t>(mj_stateSize(m, k_signature)); }

// The components are laid out in the order of their mjtState bits: the warm start follows
// those of the lower bits.
std::size_t warmstart_offset(const mjModel* m) {
  return static_cast<std::size_t>(mj_stateSize(m, k_signature & (mjSTATE_WARMSTART - 1)));
}

}  // namespace

void PhysicsState::capture(const mjModel* m, const mjData* d, std::uint64_t generation) {
  values_.resize(state_size(m));  // no allocation when it held the same model's
  mj_getState(m, d, values_.data(), k_signature);
  time_ = d->time;
  generation_ = generation;
  captured_ = true;
}

bool PhysicsState::fits(const mjModel* m, std::uint64_t generation) const {
  return captured_ && generation_ == generation && values_.size() == state_size(m);
}

void PhysicsState::apply(const mjModel* m, mjData* d) const { mj_setState(m, d, values_.data(), k_signature); }

void PhysicsState::apply_warmstart(const mjModel* m, mjData* d) const {
  mj_setState(m, d, values_.data() + warmstart_offset(m), mjSTATE_WARMSTART);
}

#endif

}  // namespace simgate::sim
