// simgate/sim/mujoco_compat.h — the MuJoCo calls whose form changed between Debian 12's MuJoCo
// 2.2.2 and the current release (the PyPI wheel, cmake/mujoco-version.txt), one inline
// function each, so that sim/ builds on both while issue #36 moves simgate to the current
// release. When 2.2.2 is dropped, each function's body becomes its #else branch, or the call
// it wraps replaces it at its call sites.
//
// SIMGATE_MUJOCO_LEGACY is 1 on MuJoCo 2.x (mjVERSION_HEADER 222: three digits), 0 from
// 3.0 on (major * 1000000 + minor * 1000 + patch).
#ifndef SIMGATE_SIM_MUJOCO_COMPAT_H_
#define SIMGATE_SIM_MUJOCO_COMPAT_H_

#include <cstring>
#include <string>

#include <mujoco/mujoco.h>

#if mjVERSION_HEADER < 1000
#define SIMGATE_MUJOCO_LEGACY 1
#else
#define SIMGATE_MUJOCO_LEGACY 0
#endif

namespace simgate::sim::compat {

// Adds `text` to `vfs` as the file `name`; false when it cannot (full, or the name taken).
// 2.2.2's VFS is a fixed table of files written in place; 3.x's is opaque and copies a buffer.
inline bool vfs_add(mjVFS* vfs, const char* name, const std::string& text) {
#if SIMGATE_MUJOCO_LEGACY
  if (mj_makeEmptyFileVFS(vfs, name, static_cast<int>(text.size())) != 0) return false;
  std::memcpy(vfs->filedata[mj_findFileVFS(vfs, name)], text.data(), text.size());
  return true;
#else
  return mj_addBufferVFS(vfs, name, text.data(), static_cast<int>(text.size())) == 0;
#endif
}

// Whether `vfs` holds the file `name`.
inline bool vfs_contains(mjVFS* vfs, const char* name) {
#if SIMGATE_MUJOCO_LEGACY
  return mj_findFileVFS(vfs, name) >= 0;
#else
  return mj_containsBufferVFS(vfs, name) != 0;
#endif
}

// mj_ray without the surface normal that 3.x added as a last (nullable) output.
inline mjtNum ray(const mjModel* m, const mjData* d, const mjtNum pnt[3], const mjtNum vec[3],
                  const mjtByte* geomgroup, mjtByte flg_static, int bodyexclude, int geomid[1]) {
#if SIMGATE_MUJOCO_LEGACY
  return mj_ray(m, d, pnt, vec, geomgroup, flg_static, bodyexclude, geomid);
#else
  return mj_ray(m, d, pnt, vec, geomgroup, flg_static, bodyexclude, geomid, nullptr);
#endif
}

}  // namespace simgate::sim::compat

#endif  // SIMGATE_SIM_MUJOCO_COMPAT_H_
