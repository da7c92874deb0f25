#include "simgate/sim/physics_state.h"

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

void EvaluatedState::capture(const mjModel* m, const mjData* d, std::uint64_t generation) {
  if (m != model_ || generation != generation_ || elements_.empty()) {
    elements_.clear();
    std::size_t offset = 0;
    for (int bit = 0; bit < mjNSTATE; ++bit) {
      const int element = 1 << bit;
      if (((k_positions | k_inputs) & element) == 0) continue;
      const auto size = static_cast<std::size_t>(mj_stateSize(m, element));
      if (size > 0) elements_.push_back({offset, size, (k_inputs & element) != 0});
      offset += size;
    }
    values_.resize(offset);
    model_ = m;
    generation_ = generation;
  }
  mj_getState(m, d, values_.data(), k_positions | k_inputs);
}

EvaluatedState::Current EvaluatedState::current(const mjModel* m, const mjData* d,
                                                std::uint64_t generation) {
  if (m != model_ || generation != generation_) return Current::nothing;
  now_.resize(values_.size());
  mj_getState(m, d, now_.data(), k_positions | k_inputs);
  bool inputs_same = true;
  for (const Element& e : elements_) {
    if (std::memcmp(now_.data() + e.offset, values_.data() + e.offset, e.size * sizeof(mjtNum)) ==
        0)
      continue;
    if (!e.input) return Current::nothing;
    inputs_same = false;
  }
  return inputs_same ? Current::all : Current::positions;
}

}  // namespace simgate::sim
