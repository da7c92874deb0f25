#!/usr/bin/env bash
# What scripts/run needs is the runtime only: its package list names no test package, and a
# build directory configured as scripts/run configures a new one (no tests, no benchmarks)
# configures with GoogleTest, Google Benchmark and Python not to be found, and its
# simgate_runtime target builds simgate and every transport plugin of the tree, nothing else.
#   runtime_build_test.sh SOURCE_DIR
set -euo pipefail
source_dir=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# the package lists
# shellcheck source=/dev/null
source "$source_dir/scripts/lib.sh"
# (python3 and python3-venv are the runtime's: ensure_mujoco's pip installs MuJoCo with them)
for p in "${SIMGATE_RUNTIME_PACKAGES[@]}"; do
  case "$p" in
    libgtest-dev|libgmock-dev|libbenchmark-dev|nodejs|npm)
      echo "scripts/run would install the test package $p"; exit 1 ;;
  esac
  for t in "${SIMGATE_TEST_PACKAGES[@]}"; do
    [ "$p" != "$t" ] || { echo "scripts/run would install the test package $p"; exit 1; }
  done
done
grep -q '^ensure_mujoco' "$source_dir/scripts/run" || { echo "scripts/run does not install the pinned MuJoCo"; exit 1; }
grep -q '^ensure_packages runtime$' "$source_dir/scripts/run" || { echo "scripts/run does not ask for the runtime packages only"; exit 1; }
grep -q -- '-- simgate_runtime' "$source_dir/scripts/run" || { echo "scripts/run does not build simgate_runtime"; exit 1; }

# configure as scripts/run does, with the test packages made unfindable
cmake -S "$source_dir" -B "$work/build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DSIMGATE_BUILD_TESTS=OFF -DSIMGATE_BUILD_BENCH=OFF \
  -DCMAKE_DISABLE_FIND_PACKAGE_GTest=ON -DCMAKE_DISABLE_FIND_PACKAGE_benchmark=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_Python3=ON >"$work/configure.log" 2>&1 ||
  { cat "$work/configure.log"; echo "the runtime build does not configure without the test packages"; exit 1; }

# nothing even looked for them (CMake lists the switches nobody used)
for package in GTest benchmark; do
  grep -q "CMAKE_DISABLE_FIND_PACKAGE_$package" "$work/configure.log" ||
    { echo "the runtime build looks for $package"; exit 1; }
done

# the unity batches (cmake/SimgateBuildSpeed.cmake) name their sources by relative paths, so
# that ccache's base_dir reuses a build of the same sources in a clone elsewhere
batches=$(find "$work/build" -name '*_unity_*.cc')
[ -n "$batches" ] || { echo "no unity batches in a default configure"; exit 1; }
if grep -l '^#include "/' $batches; then echo "unity batches that include by absolute path (above)"; exit 1; fi
grep -q '^#include "\.\./.*/sim/src/model\.cc"$' "$work/build/sim/simgate_sim_unity_0.cc" ||
  { cat "$work/build/sim/simgate_sim_unity_0.cc"; echo "sim's first batch does not include sim/src/model.cc"; exit 1; }

# what simgate_runtime builds
plan=$(ninja -C "$work/build" -n simgate_runtime)
for wanted in bin/simgate plugins/libsimgate_transport_socket.so plugins/libsimgate_transport_jsonrpc.so \
              plugins/libsimgate_transport_websocket.so plugins/libsimgate_transport_dds.so; do
  grep -q "Linking .* $wanted\$" <<<"$plan" || { echo "simgate_runtime does not build $wanted"; exit 1; }
done
# and the web app the demo's websocket transport serves (web/CMakeLists.txt)
grep -q "web/index.html" <<<"$plan" || { echo "simgate_runtime does not build the web app"; exit 1; }
if grep -qiE 'gtest|benchmark|_test|tests/' <<<"$plan"; then
  grep -iE 'gtest|benchmark|_test|tests/' <<<"$plan" | head -5
  echo "simgate_runtime builds test code"; exit 1
fi

# the pinned MuJoCo (cmake/mujoco-version.txt) from the cache scripts/run installs it into,
# also in a build directory configured before on another MuJoCo (Debian's, before issue
# #36: the files it found stay cached, with no MUJOCO_DIR; it kept them, and failed to build)
pinned=$(<"$source_dir/cmake/mujoco-version.txt")
grep -q "^MUJOCO_LIBRARY:FILEPATH=.*/mujoco-$pinned/mujoco/libmujoco.so" "$work/build/CMakeCache.txt" ||
  { grep '^MUJOCO_' "$work/build/CMakeCache.txt"; echo "not built on the pinned MuJoCo $pinned"; exit 1; }
cmake "$work/build" -DMUJOCO_LIBRARY:FILEPATH=/usr/lib/x86_64-linux-gnu/libmujoco.so.2.2.2 \
  -DMUJOCO_INCLUDE_DIR:PATH=/usr/include -DSIMGATE_MUJOCO_SEARCHED_DIR= >"$work/reconfigure.log" 2>&1 ||
  { cat "$work/reconfigure.log"; echo "reconfiguring a build directory of Debian's MuJoCo failed"; exit 1; }
grep -q "^MUJOCO_LIBRARY:FILEPATH=.*/mujoco-$pinned/mujoco/libmujoco.so" "$work/build/CMakeCache.txt" ||
  { grep '^MUJOCO_' "$work/build/CMakeCache.txt"; echo "a build directory of Debian's MuJoCo kept it"; exit 1; }

echo "runtime build: no test package, $(grep -c Linking <<<"$plan") links, simgate, 4 plugins and the web app, MuJoCo $pinned"
