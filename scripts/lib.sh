# Shared by scripts/run and scripts/test: install what is missing, then configure and build.
# Sourced, not executed.

SIMGATE_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

# Debian 12 packages: what building and running the simulation needs (scripts/run), and
# what the test suite and benchmarks need on top (scripts/test).
SIMGATE_RUNTIME_PACKAGES=(
  build-essential cmake ninja-build pkg-config ccache
  libboost-dev libcli11-dev nlohmann-json3-dev libeigen3-dev libtinyxml2-dev
  python3 python3-venv
  cyclonedds-dev cyclonedds-tools
  libegl-dev libegl1 libgl1-mesa-dri zlib1g-dev
  libzstd-dev liblz4-dev
  telnet
)
SIMGATE_TEST_PACKAGES=(
  git libgtest-dev libgmock-dev libbenchmark-dev
  libmujoco-samples
  python3-morse-simulator python3-jsonschema
  iproute2 procps util-linux
  clang-14 libclang-rt-14-dev llvm-14
  chromium
)
# ccache: the compiler launcher when present (cmake/SimgateBuildSpeed.cmake, docs/building.md):
# a rebuild of the same sources, in this clone or another, takes its objects from the cache
# cameras (sim/src/renderer.cc, image_codec.cc): libegl-dev to build against EGL (headers,
# libEGL.so; MuJoCo's own GL loader finds the GL functions through the EGL the process has
# loaded), libegl1 and libgl1-mesa-dri for Mesa's EGL and its llvmpipe renderer (no
# display, no GPU needed),
# zlib1g-dev for the PNG images' deflate. Without them at run time the cameras answer
# FAILED and the rest runs.
# libzstd-dev and liblz4-dev: the MCAP recordings' chunk compression (protocols/mcap; zlib's
# crc32 for their CRCs)
# python3 and python3-venv: ensure_mujoco's private virtualenv, whose pip installs the pinned
# official MuJoCo (below; Debian's libmujoco-dev, 2.2.2, is no longer used)
# libmujoco-samples: Debian's sample models (/usr/share/mujoco/model) the sim tests run on
# (those the current MuJoCo loads; the others must be refused with its message)
# clang-14 and its runtime libraries build the fuzz targets (libFuzzer, tests/fuzz), llvm-14's
# llvm-symbolizer puts file and line in their crash reports (scripts/fuzz, docs/fuzzing.md)
# chromium: the web app's browser test (tests/web) drives Debian's headless Chromium
# (/usr/bin/chromium) with npm's playwright-core; skipped (77) without it
# node and npm build the web app (web/: three.js from npm, pinned by its lock) and run the
# third-party JSON-RPC clients and the browser test; any install will do (Debian's or
# NodeSource's, which bundles npm and conflicts with Debian's npm package), so they are
# checked as commands, not as packages, for the runtime build too

log() { printf '\033[1m[simgate]\033[0m %s\n' "$*" >&2; }

# ensure_packages runtime|test: installs what is missing (as root), or prints the command
ensure_packages() {
  local missing=() p wanted=("${SIMGATE_RUNTIME_PACKAGES[@]}")
  [ "${1:-test}" = test ] && wanted+=("${SIMGATE_TEST_PACKAGES[@]}")
  for p in "${wanted[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  command -v node >/dev/null || missing+=(nodejs)
  command -v npm >/dev/null || missing+=(npm)
  [ ${#missing[@]} -eq 0 ] && return 0
  if [ "$(id -u)" -eq 0 ]; then
    log "installing: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    log "missing Debian packages: ${missing[*]}"
    log "run: sudo apt-get install -y ${missing[*]}"
    exit 1
  fi
}

# ---- the official MuJoCo (issue #36): the C library, headers and engine plugins of the PyPI
# wheel, at the version pinned in cmake/mujoco-version.txt (the one place it is named).
# From 4.0 the `mujoco` package is a meta-package; the C library lives in `mujoco-core`.
# Installed once per version under the user's cache, shared by every clone and worktree:
#   ${XDG_CACHE_HOME:-~/.cache}/simgate/mujoco-<version>/mujoco/{include/mujoco,libmujoco.so.<version>,plugin}
# which is what CMake takes as MUJOCO_DIR. pip runs from a private virtualenv beside it
# (needs Debian's python3-venv), never the system Python's; --no-deps: numpy and the rest
# serve the Python bindings, which simgate does not use.
SIMGATE_MUJOCO_VERSION=$(<"$SIMGATE_ROOT/cmake/mujoco-version.txt")
SIMGATE_MUJOCO_CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/simgate
SIMGATE_MUJOCO_DIR=$SIMGATE_MUJOCO_CACHE/mujoco-$SIMGATE_MUJOCO_VERSION/mujoco

# pip_install_into [--for PYTHON] TARGET SPEC FILE...: installs the wheel SPEC ("name==version";
# several, separated by spaces, go into the same TARGET) into the directory TARGET with the
# private virtualenv's pip (made on first use), unless it is there already; it is there when
# TARGET holds every FILE (paths below TARGET). --for PYTHON: wheels for that interpreter's
# version (the one that will import them), not the virtualenv's. Into a fresh directory renamed
# into place: a run interrupted half way leaves no directory that looks installed, and two runs
# at once do not mix their files. Prints nothing when it is there.
pip_install_into() {
  local for_python=() version
  if [ "$1" = --for ]; then
    version=$("$2" -c 'import sys; print("%d.%d" % sys.version_info[:2])') ||
      { log "pip_install_into: cannot run $2"; return 1; }
    for_python=(--python-version "$version")
    shift 2
  fi
  local target=$1 spec=$2 venv=$SIMGATE_MUJOCO_CACHE/pip-venv tmp file specs; shift 2
  read -ra specs <<<"$spec"
  for file in "$@"; do [ -e "$target/$file" ] || break; done
  [ -e "$target/$file" ] && return 0
  mkdir -p "$SIMGATE_MUJOCO_CACHE"
  if [ ! -x "$venv/bin/pip" ]; then
    python3 -m venv "$venv" || { log "python3 -m venv failed (Debian: apt-get install python3-venv)"; return 1; }
  fi
  log "installing $spec (PyPI) into ${target/#$HOME/\~}"
  tmp=$(mktemp -d "$target.XXXXXX")
  if ! "$venv/bin/pip" install --quiet --disable-pip-version-check --no-compile --no-deps --only-binary=:all: \
       ${for_python[@]+"${for_python[@]}"} --target "$tmp" "${specs[@]}"; then
    rm -rf "$tmp"; log "pip could not install $spec"; return 1
  fi
  for file in "$@"; do
    [ -e "$tmp/$file" ] || { rm -rf "$tmp"; log "$spec: no $file in the wheel"; return 1; }
  done
  mv -T "$tmp" "$target" 2>/dev/null || rm -rf "$tmp"   # lost a race: the other run's copy stays
}

# ensure_mujoco: installs the pinned wheel unless it is there; prints nothing when it is
ensure_mujoco() {
  pip_install_into "$SIMGATE_MUJOCO_CACHE/mujoco-$SIMGATE_MUJOCO_VERSION" "mujoco-core==$SIMGATE_MUJOCO_VERSION" \
    "mujoco/libmujoco.so.$SIMGATE_MUJOCO_VERSION" mujoco/include/mujoco/mujoco.h
}

# ---- clang-format (scripts/format, the FormatCheck test): the version pinned here, from PyPI's
# clang-format wheel (Debian 12's clang-format-14 formats some constructs differently), in the
# same private virtualenv as MuJoCo's pip, installed once per version under the user's cache.
SIMGATE_CLANG_FORMAT_VERSION=19.1.7
SIMGATE_CLANG_FORMAT=$SIMGATE_MUJOCO_CACHE/clang-format-$SIMGATE_CLANG_FORMAT_VERSION/clang_format/data/bin/clang-format

# ensure_clang_format: installs the pinned clang-format unless it is there
ensure_clang_format() {
  pip_install_into "$SIMGATE_MUJOCO_CACHE/clang-format-$SIMGATE_CLANG_FORMAT_VERSION" \
    "clang-format==$SIMGATE_CLANG_FORMAT_VERSION" clang_format/data/bin/clang-format
}

# ---- Python test clients (libraries nobody on the team wrote, run by the tests with Debian's
# /usr/bin/python3): each pypi-requirements.txt under tests/ pins its packages ("name==version"
# a line, # comments), installed together (binary wheels for /usr/bin/python3, no dependencies
# but those pinned) once per set of pins under the user's cache, in a directory named after them:
#   ${XDG_CACHE_HOME:-~/.cache}/simgate/python-<name>-<version>_<name>-<version>...
# which the test's CMakeLists.txt names the same way (tests/mcap: PyPI's mcap, with zstandard
# and lz4 for its chunks). Skipped (77) by the tests without it.
ensure_python_test_clients() {
  local requirements specs spec name files joined
  while IFS= read -r requirements; do
    mapfile -t specs < <(grep -v '^#' "$requirements" | grep .)
    [ ${#specs[@]} -gt 0 ] || continue
    files=()
    for spec in "${specs[@]}"; do
      name=${spec%%==*}
      files+=("${name//-/_}-${spec#*==}.dist-info")
    done
    joined=$(IFS=_; echo "${specs[*]}")
    pip_install_into --for /usr/bin/python3 "$SIMGATE_MUJOCO_CACHE/python-${joined//==/-}" \
      "${specs[*]}" "${files[@]}" || return 1
  done < <(find "$SIMGATE_ROOT/tests" -name pypi-requirements.txt -not -path '*/node_modules/*' 2>/dev/null)
}

# ---- the Rust test client (tests/ros2/rust: simgate_ros2_rust_probe, a ROS 2 node written with
# crates.io's ros2-client on RustDDS; tests/ros2/test_ros2_rust_client.py runs it), built with
# rustup's cargo, every crate pinned by its Cargo.lock (--locked), once per version of its
# sources, into the user's cache:
#   ${XDG_CACHE_HOME:-~/.cache}/simgate/rust-ros2-probe-<hash>/simgate_ros2_rust_probe
# <hash>: the first 16 hex digits of the SHA-256 of the hex SHA-256s of the files below, one
# after the other, which tests/ros2/CMakeLists.txt computes the same way (SIMGATE_ROS2_RUST_PROBE).
# Cargo's build directory (rust-ros2-probe-target beside it) keeps the compiled crates, so a
# change to the probe's own code rebuilds only that. Without cargo, or when cargo fails, nothing
# is installed and the test E2E.ros2_clients fails saying so.
SIMGATE_RUST_PROBE_FILES=(Cargo.toml Cargo.lock src/main.rs)

# rust_test_client_path: where ensure_rust_test_client puts the probe (printed)
rust_test_client_path() {
  local file sums="" sum
  for file in "${SIMGATE_RUST_PROBE_FILES[@]}"; do
    sum=$(sha256sum <"$SIMGATE_ROOT/tests/ros2/rust/$file") || return 1
    sums+=${sum%% *}
  done
  sum=$(printf '%s' "$sums" | sha256sum)
  echo "$SIMGATE_MUJOCO_CACHE/rust-ros2-probe-${sum:0:16}/simgate_ros2_rust_probe"
}

# ensure_rust_test_client: builds the probe unless it is there; prints nothing when it is
ensure_rust_test_client() {
  local path dir tmp cargo target=$SIMGATE_MUJOCO_CACHE/rust-ros2-probe-target
  path=$(rust_test_client_path) || return 1
  [ -x "$path" ] && return 0
  dir=$(dirname "$path")
  cargo=$(command -v cargo || echo "${CARGO_HOME:-$HOME/.cargo}/bin/cargo")
  if [ ! -x "$cargo" ]; then
    log "no cargo (rustup's): the Rust ROS 2 test client (tests/ros2/rust) is not built"
    return 1
  fi
  log "building the Rust ROS 2 test client (tests/ros2/rust, crates.io) into ${dir/#$HOME/\~}"
  mkdir -p "$SIMGATE_MUJOCO_CACHE"
  if ! CARGO_TARGET_DIR=$target "$cargo" build --release --locked --quiet \
       --manifest-path "$SIMGATE_ROOT/tests/ros2/rust/Cargo.toml"; then
    log "cargo could not build tests/ros2/rust"
    return 1
  fi
  # into a fresh directory renamed into place, as pip_install_into does
  tmp=$(mktemp -d "$dir.XXXXXX")
  if ! cp "$target/release/simgate_ros2_rust_probe" "$tmp/"; then
    rm -rf "$tmp"; return 1
  fi
  mv -T "$tmp" "$dir" 2>/dev/null || rm -rf "$tmp"   # lost a race: the other run's copy stays
}

# npm test clients (JSON-RPC libraries nobody on the team wrote): every package.json under tests/ and bench/
ensure_node_modules() {
  local manifest dir
  while IFS= read -r manifest; do
    dir=$(dirname "$manifest")
    if [ ! -d "$dir/node_modules" ] || [ "$manifest" -nt "$dir/node_modules" ]; then
      log "npm install in ${dir#"$SIMGATE_ROOT"/}"
      (cd "$dir" && npm install --no-audit --no-fund --loglevel=error >/dev/null && touch node_modules)
    fi
  done < <(find "$SIMGATE_ROOT/tests" "$SIMGATE_ROOT/bench" -name package.json -not -path '*/node_modules/*' 2>/dev/null)
}

# ---- timings: every stage of a run timed (scripts/test prints them; docs/building.md)
SIMGATE_STAGES=()        # "name seconds", in order
# timed NAME COMMAND...: runs COMMAND, records how long it took under NAME (also when it
# fails), returns its status
timed() {
  local name=$1 start status=0; shift
  start=$(date +%s.%N)
  "$@" || status=$?
  SIMGATE_STAGES+=("$name $(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN {printf "%.1f", e - s}')")
  return $status
}
# print_timings LABEL: one line with every stage and the total; appended to
# $SIMGATE_TIMINGS_FILE too when it is set (.ci/run sums its stages from it)
print_timings() {
  local line="$1:" total=0 stage name seconds
  for stage in "${SIMGATE_STAGES[@]}"; do
    name=${stage% *} seconds=${stage##* }
    line+=" $name ${seconds} s,"
    total=$(awk -v t="$total" -v s="$seconds" 'BEGIN {printf "%.1f", t + s}')
  done
  line+=" total ${total} s"
  log "timings $line"
  [ -z "${SIMGATE_TIMINGS_FILE:-}" ] || echo "$line" >>"$SIMGATE_TIMINGS_FILE"
}
# (The lists end with awk, not head: head would leave sort writing into a closed pipe, and
# under pipefail its SIGPIPE would end the calling script.)
# slowest_build_steps BUILD_DIR [N]: the N slowest steps (compiles, links) of the last
# configure_and_build of BUILD_DIR, from ninja's log (outputs written since it started)
slowest_build_steps() {
  local log=$1/.ninja_log
  [ -f "$log" ] || return 0
  awk -F'\t' -v since="${SIMGATE_BUILD_STARTED_NS:-0}" '!/^#/ && $3 >= since {printf "%8.1f s  %s\n", ($2 - $1) / 1000, $4}' "$log" |
    sort -rn | awk -v n="${2:-15}" 'NR <= n'
}

# slowest_tests [N]: in a build directory after ctest, the N tests that took longest (ctest's
# cost data: each test's mean time over its runs in this build directory)
slowest_tests() {
  local costs=Testing/Temporary/CTestCostData.txt
  [ -f "$costs" ] || return 0
  awk '/^---/ {exit} NF == 3 {printf "%8.1f s  %s\n", $3, $1}' "$costs" | sort -rn | awk -v n="${1:-15}" 'NR <= n'
}

# configure_and_build BUILD_DIR [cmake args...] [-- targets...]: the stages "configure"
# (only when the build directory is new or arguments are given) and "build"
configure_and_build() {
  local build_dir=$1 args=() targets=(); shift
  while [ $# -gt 0 ]; do
    if [ "$1" = -- ]; then shift; targets=("$@"); break; fi
    args+=("$1"); shift
  done
  if [ ! -f "$build_dir/build.ninja" ]; then
    timed configure cmake -S "$SIMGATE_ROOT" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${args[@]}" >/dev/null
  elif [ ${#args[@]} -gt 0 ]; then
    timed configure cmake "$build_dir" "${args[@]}" >/dev/null
  fi
  SIMGATE_BUILD_STARTED_NS=$(date +%s%N)
  timed build cmake --build "$build_dir" ${targets[@]+--target "${targets[@]}"}
}

# After a failed ctest run in the build directory: when every failed test failed without a
# sanitizer report, runs them once more, one at a time, and succeeds if they all pass then.
retry_failed_tests_once() {
  local failed=Testing/Temporary/LastTestsFailed.log output=Testing/Temporary/LastTest.log name names=()
  [ -s "$failed" ] || return 1
  while IFS=: read -r _ name; do names+=("$name"); done < "$failed"
  for name in "${names[@]}"; do
    # the test's section of ctest's log: from its "Testing:" line to its "end time" line
    if awk -v n="$name" 'index($0, "Testing: ") && substr($0, index($0, "Testing: ") + 9) == n {on = 1}
                         on {print} on && index($0, "\"" n "\" end time") == 1 {exit}' "$output" |
      grep -qE 'ERROR: (AddressSanitizer|LeakSanitizer)|WARNING: ThreadSanitizer|runtime error:|UndefinedBehaviorSanitizer'; then
      log "$name failed with a sanitizer report: not retried"
      return 1
    fi
  done
  log "retrying once, alone, what failed without a sanitizer report: ${names[*]}"
  ctest --output-on-failure -j 1 --timeout 300 --rerun-failed || return $?
  log "passed when retried alone (a failure under load, to look into): ${names[*]}"
}
