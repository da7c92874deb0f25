#include "simgate/sim/physics_state.h"

#include <cstring>

namespace simgate::sim {

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

}  // namespace simgate::sim
