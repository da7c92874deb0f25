# Shared by scripts/run and scripts/test: install what is missing, then configure and build.
# Sourced, not executed.

SIMGATE_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

# Debian 12 packages the build, the tests and the end-to-end clients need.
SIMGATE_PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libboost-dev libcli11-dev nlohmann-json3-dev libeigen3-dev libmujoco-dev
  cyclonedds-dev cyclonedds-tools
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-morse-simulator
  iproute2 procps
)
# node and npm run the third-party JSON-RPC clients; any install will do (Debian's or
# NodeSource's, which bundles npm and conflicts with Debian's npm package)

log() { printf '\033[1m[simgate]\033[0m %s\n' "$*" >&2; }

ensure_packages() {
  local missing=() p
  for p in "${SIMGATE_PACKAGES[@]}"; do
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

# configure_and_build BUILD_DIR [cmake args...]
configure_and_build() {
  local build_dir=$1; shift
  if [ ! -f "$build_dir/build.ninja" ]; then
    cmake -S "$SIMGATE_ROOT" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
  else
    cmake "$build_dir" "$@" >/dev/null
  fi
  cmake --build "$build_dir"
}
