#include "simgate/sim/state_hash.h"

#include <array>
#include <bit>
#include <cstring>
#include <utility>
#include <vector>

namespace simgate::sim {

namespace {

// mjSTATE_INTEGRATION's parts, in the order of their bits (how mj_getState lays them out)
constexpr std::array<std::pair<int, const char*>, 15> k_parts = {{
    {mjSTATE_TIME, "time"},
    {mjSTATE_QPOS, "qpos"},
    {mjSTATE_QVEL, "qvel"},
    {mjSTATE_ACT, "act"},
    {mjSTATE_HISTORY, "history"},
    {mjSTATE_WARMSTART, "warmstart"},
    {mjSTATE_CTRL, "ctrl"},
    {mjSTATE_QFRC_APPLIED, "qfrc_applied"},
    {mjSTATE_XFRC_APPLIED, "xfrc_applied"},
    {mjSTATE_EQ_ACTIVE, "eq_active"},
    {mjSTATE_MOCAP_POS, "mocap_pos"},
    {mjSTATE_MOCAP_QUAT, "mocap_quat"},
    {mjSTATE_USERDATA, "userdata"},
    {mjSTATE_PLUGIN, "plugin"},
    {mjSTATE_PLASTIC, "plastic"},
}};
static_assert((mjSTATE_TIME | mjSTATE_QPOS | mjSTATE_QVEL | mjSTATE_ACT | mjSTATE_HISTORY |
               mjSTATE_WARMSTART | mjSTATE_CTRL | mjSTATE_QFRC_APPLIED | mjSTATE_XFRC_APPLIED |
               mjSTATE_EQ_ACTIVE | mjSTATE_MOCAP_POS | mjSTATE_MOCAP_QUAT | mjSTATE_USERDATA |
               mjSTATE_PLUGIN | mjSTATE_PLASTIC) == mjSTATE_INTEGRATION,
              "every part of MuJoCo's integration state is hashed");

// 64-bit mixing of one word (the finalizer of splitmix64)
std::uint64_t mix(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}

}  // namespace

std::uint32_t hash_values(std::span<const mjtNum> values) {
  // each word: an xor, a rotation and a multiplication by an odd number, three bijections of
  // h, so that two arrays differing in any one word never meet again; one mix at the end
  // spreads every bit over the 32 kept (a step's quantities hash in well under a microsecond)
  std::uint64_t h = 0x9e3779b97f4a7c15ULL ^ values.size();
  for (mjtNum v : values) {
    std::uint64_t bits = 0;
    static_assert(sizeof(bits) == sizeof(v));
    std::memcpy(&bits, &v, sizeof bits);
    h = std::rotl(h ^ bits, 29) * 0xbf58476d1ce4e5b9ULL;
  }
  h = mix(h);
  return static_cast<std::uint32_t>(h ^ (h >> 32));
}

std::uint64_t combine_hashes(std::span<const std::uint32_t> hashes) {
  std::uint64_t h = 0x6a09e667f3bcc909ULL ^ hashes.size();
  for (std::uint32_t v : hashes) h = mix(h ^ v);
  return h;
}

std::uint64_t model_hash(const mjModel* m) {
  const int size = mj_sizeModel(m);
  std::vector<std::uint8_t> image(static_cast<std::size_t>(size));
  mj_saveModel(m, nullptr, image.data(), size);
  std::uint64_t h = 0x243f6a8885a308d3ULL ^ image.size();
  std::size_t i = 0;
  for (; i + 8 <= image.size(); i += 8) {
    std::uint64_t word = 0;
    std::memcpy(&word, image.data() + i, 8);
    h = mix(h ^ word);
  }
  for (; i < image.size(); ++i) h = mix(h ^ image[i]);
  return h;
}

StateHasher::StateHasher(const mjModel* m)
    : size_(static_cast<std::size_t>(mj_stateSize(m, mjSTATE_INTEGRATION))), values_(size_) {
  std::size_t begin = 0;
  for (const auto& [bit, name] : k_parts) {
    const auto n = static_cast<std::size_t>(mj_stateSize(m, bit));
    if (n > 0) {
      names_.emplace_back(name);
      parts_.push_back({begin, begin + n});
    }
    begin += n;
  }
}

bool StateHasher::fits(const mjModel* m) const {
  return size_ == static_cast<std::size_t>(mj_stateSize(m, mjSTATE_INTEGRATION));
}

void StateHasher::hash(const mjModel* m, const mjData* d, std::span<std::uint32_t> out) {
  mj_getState(m, d, values_.data(), mjSTATE_INTEGRATION);
  hash_state(values_, out);
}

void StateHasher::hash_state(std::span<const mjtNum> state, std::span<std::uint32_t> out) const {
  for (std::size_t i = 0; i < parts_.size() && i < out.size(); ++i)
    out[i] = hash_values(state.subspan(parts_[i].begin, parts_[i].end - parts_[i].begin));
}

}  // namespace simgate::sim
