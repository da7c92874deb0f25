// simgate/sim/state_hash.h — fingerprints of the simulation's state, step by step, for the
// flight recorder (issue #39): a replay that takes the same inputs at the same steps must
// reach the same state bit for bit, and where it does not, the fingerprints say at which step
// and in which quantity it first differs.
//
// The state is MuJoCo's integration state (mjSTATE_INTEGRATION: everything the next step
// reads, physics_state.h). Each of its quantities the model has (time, qpos, qvel, act,
// history, warmstart, ctrl, qfrc_applied, xfrc_applied, eq_active, mocap_pos, mocap_quat,
// userdata, plugin, plastic: mjtState's order; those of size 0 are left out) gets a 32-bit
// hash of its bytes: two states that differ anywhere differ in some quantity's hash (but for a
// chance of 2^-32 per quantity). Bytes, not values: -0.0 and 0.0, or two NaNs, differ.
//
// Threads: whoever holds the simulation lock (it reads mjData); a StateHasher belongs to one
// thread at a time.
#ifndef SIMGATE_SIM_STATE_HASH_H_
#define SIMGATE_SIM_STATE_HASH_H_

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

namespace simgate::sim {

class StateHasher {
 public:
  // The quantities `m` has.
  explicit StateHasher(const mjModel* m);

  // Their names, in the order hash() writes them ("time", "qpos", ...).
  const std::vector<std::string>& quantities() const { return names_; }
  // Whether this hasher was made for a model of `m`'s sizes (a spawn changes them: make a
  // new one).
  bool fits(const mjModel* m) const;
  // Hashes `d`'s state: one value per quantity, into `out` (quantities().size() of them).
  void hash(const mjModel* m, const mjData* d, std::span<std::uint32_t> out);
  // The same of a state captured before (mj_getState, mjSTATE_INTEGRATION: state_size()
  // values), on any thread (a recorder copies the state under the lock, hashes it off it).
  void hash_state(std::span<const mjtNum> state, std::span<std::uint32_t> out) const;
  std::size_t state_size() const { return size_; }

 private:
  struct Part {
    std::size_t begin = 0, end = 0;  // in values_, mjtNum units
  };
  std::vector<std::string> names_;
  std::vector<Part> parts_;
  std::size_t size_ = 0;        // mj_stateSize(m, mjSTATE_INTEGRATION)
  std::vector<mjtNum> values_;  // the state, as mj_getState writes it
};

// One 32-bit hash of the bytes of `values` (a quantity's), and a 64-bit one of a step's
// quantity hashes (what a replay compares first).
std::uint32_t hash_values(std::span<const mjtNum> values);
std::uint64_t combine_hashes(std::span<const std::uint32_t> hashes);
// A 64-bit fingerprint of a compiled model (its MJB image, mj_saveModel): two compilations
// of the same files by the same MuJoCo give the same one.
std::uint64_t model_hash(const mjModel* m);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_STATE_HASH_H_
