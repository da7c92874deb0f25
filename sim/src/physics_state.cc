#include "simgate/sim/physics_state.h"

#include <algorithm>
#include <cstring>
#include <utility>

namespace simgate::sim {

namespace {

// mjSTATE_INTEGRATION: time, qpos, qvel, act, the history buffers, the plastic state, the
// plugins' state, ctrl, the applied forces, eq_active, the mocap poses, userdata and the
// warm start: "everything required to reproduce the next step" (mjtState).
constexpr int k_signature = mjSTATE_INTEGRATION;

std::size_t state_size(const mjModel* m) {
  return static_cast<std::size_t>(mj_stateSize(m, k_signature));
}

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

PhysicsState PhysicsState::from_values(std::vector<mjtNum> values, std::uint64_t generation) {
  PhysicsState state;
  state.time_ = values.empty() ? 0 : values[0];  // mjSTATE_TIME comes first
  state.values_ = std::move(values);
  state.generation_ = generation;
  state.captured_ = true;
  return state;
}

bool PhysicsState::fits(const mjModel* m, std::uint64_t generation) const {
  return captured_ && generation_ == generation && values_.size() == state_size(m);
}

void PhysicsState::apply(const mjModel* m, mjData* d) const {
  mj_setState(m, d, values_.data(), k_signature);
}

void PhysicsState::apply_warmstart(const mjModel* m, mjData* d) const {
  mj_setState(m, d, values_.data() + warmstart_offset(m), mjSTATE_WARMSTART);
}

void EvaluatedState::lay_out(const mjModel* m) {
  elements_.clear();
  std::size_t offset = 1;  // values_[0]: the time
  const auto add = [&](mjtNum* mjData::* array, int count, bool input) {
    if (count > 0) elements_.push_back({array, offset, static_cast<std::size_t>(count), input});
    offset += static_cast<std::size_t>(std::max(count, 0));
  };
  add(&mjData::qpos, m->nq, false);
  add(&mjData::qvel, m->nv, false);
  add(&mjData::act, m->na, false);
  add(&mjData::mocap_pos, 3 * m->nmocap, false);
  add(&mjData::mocap_quat, 4 * m->nmocap, false);
  add(&mjData::ctrl, m->nu, true);
  add(&mjData::qfrc_applied, m->nv, true);
  add(&mjData::xfrc_applied, 6 * m->nbody, true);
  add(&mjData::qacc_warmstart, m->nv, true);
  through_get_state_ = offset;
  for (int bit = 0; bit < mjNSTATE; ++bit) {  // mj_getState's order: the elements' bits
    const int element = 1 << bit;
    if ((k_through_get_state & element) == 0) continue;
    add(nullptr, mj_stateSize(m, element), (k_inputs & element) != 0);
  }
  values_.resize(offset);
}

void EvaluatedState::capture(const mjModel* m, const mjData* d, std::uint64_t generation) {
  if (m != model_ || generation != generation_ || values_.empty()) {
    lay_out(m);
    model_ = m;
    generation_ = generation;
  }
  values_[0] = d->time;
  for (const Element& e : elements_)
    if (e.array) std::memcpy(&values_[e.offset], d->*e.array, e.size * sizeof(mjtNum));
  if (through_get_state_ < values_.size())
    mj_getState(m, d, &values_[through_get_state_], k_through_get_state);
}

EvaluatedState::Current EvaluatedState::current(const mjModel* m, const mjData* d,
                                                std::uint64_t generation) {
  if (m != model_ || generation != generation_ ||
      std::memcmp(&values_[0], &d->time, sizeof(mjtNum)) != 0)
    return Current::nothing;
  if (through_get_state_ < values_.size()) {  // mj_getState's elements as they are now
    now_.resize(values_.size() - through_get_state_);
    mj_getState(m, d, now_.data(), k_through_get_state);
  }
  bool inputs_same = true;
  for (const Element& e : elements_) {
    const mjtNum* now = e.array ? d->*e.array : now_.data() + (e.offset - through_get_state_);
    if (std::memcmp(now, &values_[e.offset], e.size * sizeof(mjtNum)) == 0) continue;
    if (!e.input) return Current::nothing;
    inputs_same = false;
  }
  return inputs_same ? Current::all : Current::positions;
}

}  // namespace simgate::sim
