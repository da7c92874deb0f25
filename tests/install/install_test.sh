#!/usr/bin/env bash
# The newcomer's path: `cmake --install` this build into a temporary prefix (<tmp>/opt/simgate),
# then, with the build and source trees hidden (an empty tmpfs mounted over each in a private
# mount namespace) and from an unrelated directory (/), run the *installed* simgate:
# --version, `check` of every shipped config, `run` of the installed demo (a copy beside it
# with port 0) and one `simgate call` to it, then `simulation quit`. Also: RUNPATHs of the
# installed binaries (relative, never the build tree), a program built with nothing but
# `pkg-config --cflags --libs simgate`, the prefix moved elsewhere still working, and a
# component library built out of tree against it, loaded by a config and called.
#   install_test.sh BUILD_DIR SOURCE_DIR CXX VERSION BINDIR LIBDIR DATADIR [SANITIZE]
# Exits 77 (skipped) only when this machine allows no private mount namespace.
set -euo pipefail
build_dir=$(realpath "$1") source_dir=$(realpath "$2") cxx=$3 version=$4
bindir=$5 libdir=$6 datadir=$7 sanitize=${8:-}
here=$(cd "$(dirname "$0")" && pwd)

fail() { echo "FAILED: $*" >&2; exit 1; }

work=$(realpath "$(mktemp -d)")
trap 'rm -rf "$work"' EXIT
case "$work/" in
  "$build_dir"/* | "$source_dir"/*) fail "the temporary directory $work is inside the trees it must hide" ;;
esac
prefix=$work/opt/simgate

# --- install -----------------------------------------------------------------------------
timeout 300 cmake --install "$build_dir" --prefix "$prefix" >"$work/install.log" ||
  { cat "$work/install.log"; fail "cmake --install"; }
for f in "$bindir/simgate" \
         "$libdir/libsimgate_core.so" "$libdir/libsimgate_sim.so" "$libdir/libsimgate_clients.so" \
         "$libdir/simgate/plugins/libsimgate_transport_socket.so" \
         "$libdir/simgate/plugins/libsimgate_transport_jsonrpc.so" \
         include/simgate/core/plugin.h include/simgate/sim/simulation.h include/simgate/client/client.h \
         "$libdir/cmake/simgate/simgateConfig.cmake" "$libdir/cmake/simgate/simgateTargets.cmake" \
         "$libdir/pkgconfig/simgate.pc" "$libdir/pkgconfig/simgate-core.pc" \
         "$libdir/pkgconfig/simgate-sim.pc" "$libdir/pkgconfig/simgate-clients.pc" \
         "$datadir/simgate/config/demo.json" "$datadir/simgate/config/all-transports.json" \
         "$datadir/simgate/config/scenes/demo.xml" "$datadir/simgate/config/dds/loopback.xml" \
         "$datadir/doc/simgate/LICENSE" "$datadir/doc/simgate/README.md" \
         "$datadir/doc/simgate/docs/configuration.md" "$datadir/doc/simgate/docs/cli.md" \
         "$datadir/doc/simgate/docs/transports/socket.md" "$datadir/doc/simgate/docs/world/snapshot.md" \
         "$libdir/simgate/plugins/libsimgate_transport_websocket.so" \
         "$datadir/simgate/web/index.html" "$datadir/simgate/web/app.js" \
         "$datadir/simgate/web/vendor/three.module.js" "$datadir/simgate/web/vendor/OrbitControls.js"; do
  [ -e "$prefix/$f" ] || fail "not installed: $f"
done
# every file of the web app's source (app.js, the ES modules it imports, style.css): one left
# out of web/CMakeLists.txt's app_files would fail the page's imports in the browser
for f in "$source_dir"/web/*.js "$source_dir"/web/*.css; do
  f=$datadir/simgate/web/$(basename "$f")
  [ -e "$prefix/$f" ] || fail "not installed: $f (missing from web/CMakeLists.txt's app_files?)"
done
echo "installed into $prefix"
# every page a message of the code cites ("docs/configuration.md") is in share/doc/simgate
cited=$(grep -rhoE 'docs/[A-Za-z0-9_/.-]+[.]md' "$source_dir"/{core,kit,sim,plugins,clients,gateway} \
          --include='*.cc' --include='*.h' | sort -u)
[ -n "$cited" ] || fail "no docs/*.md cited in the sources: the pattern is wrong"
for doc in $cited; do
  [ -e "$prefix/$datadir/doc/simgate/$doc" ] || fail "not installed: $doc (cited by the code's messages)"
done
echo "installed the $(wc -w <<<"$cited") pages the code's messages cite"

# --- RUNPATH: present, relative to the file ($ORIGIN), never the build or source tree ----
elves=("$prefix/$bindir/simgate")
# (the MuJoCo the tree carries, its library and engine plugins, is not simgate's: the library
# needs nothing but libc, the plugins find it loaded already)
while IFS= read -r -d '' f; do elves+=("$f"); done < <(find "$prefix/$libdir" -name '*.so*' -not -name 'libmujoco.so*' \
  -not -path "$prefix/$libdir/mujoco_plugin/*" -type f -print0)
ls "$prefix/$libdir/mujoco_plugin/"*.so >/dev/null 2>&1 || fail "not installed: MuJoCo's engine plugins in $libdir/mujoco_plugin"
for f in "${elves[@]}"; do
  dynamic=$(readelf -d "$f")
  runpath=$(sed -n 's/.*(RUNPATH).*\[\(.*\)\]/\1/p' <<<"$dynamic")
  [ -n "$runpath" ] || fail "$f has no RUNPATH"
  ! grep -q '(RPATH)' <<<"$dynamic" || fail "$f has an RPATH (searched before LD_LIBRARY_PATH): $dynamic"
  [[ $runpath == *'$ORIGIN'* ]] || fail "$f: RUNPATH '$runpath' is not relative to the file"
  case ":$runpath:" in
    *"$build_dir"* | *"$source_dir"*) fail "$f: RUNPATH '$runpath' names the build or source tree" ;;
  esac
  echo "RUNPATH ${f#"$prefix"/}: $runpath"
done

# --- what runs hidden from the trees -----------------------------------------------------
config_dir=$prefix/$datadir/simgate/config
# the demo on a port the kernel picks, beside the installed demo so its scene resolves the same
sed -E 's/"port": (4000|8090|8765|8808)/"port": 0/' "$config_dir/demo.json" >"$config_dir/install-test-demo.json"
grep -q '"port": 0' "$config_dir/install-test-demo.json" || fail "demo.json has no \"port\": 4000 to replace"
! grep -qE '"port": (4000|8090|8765|8808)' "$config_dir/install-test-demo.json" || fail "demo.json's ports were not all replaced"

# sanitizer suppression files live in the source tree, which is about to disappear
for var in ASAN_OPTIONS LSAN_OPTIONS TSAN_OPTIONS UBSAN_OPTIONS; do
  value=${!var:-}
  [[ $value == *suppressions=* ]] || continue
  file=$(sed -E 's/.*suppressions=([^:]*).*/\1/' <<<"$value")
  [ -f "$file" ] || continue
  cp "$file" "$work/$var.supp"
  export "$var=${value/suppressions=$file/suppressions=$work/$var.supp}"
done
cp "$here/pkg_config_probe.cc" "$work/"
# a model using an engine plugin (mujoco.pid): the installed tree's own plugins must load it
cp "$source_dir/tests/models/current_mujoco.xml" "$work/"
# the MuJoCo the build used (the wheel in the user's cache) is hidden too: the installed tree
# runs on the copy it carries
mujoco_used=$(dirname "$(sed -n 's/^MUJOCO_LIBRARY:[A-Z]*=//p' "$build_dir/CMakeCache.txt")")
cp "$source_dir/docs/examples/odometer_library.cc" "$work/"

# a private mount namespace: as root, or as an unprivileged user through a user namespace
mkdir "$work/mount-probe"
hide=()
for candidate in "unshare --mount --propagation private" \
                 "unshare --user --map-root-user --mount --propagation private"; do
  # shellcheck disable=SC2086
  if timeout 30 $candidate sh -c "mount -t tmpfs simgate-probe '$work/mount-probe'" 2>/dev/null; then
    read -r -a hide <<<"$candidate"
    break
  fi
done
if [ ${#hide[@]} -eq 0 ]; then
  echo "SKIPPED: this machine allows no private mount namespace (unshare --mount, as root or with" \
       "a user namespace), so the build tree cannot be hidden from the installed simgate"
  exit 77
fi
echo "hiding $build_dir and $source_dir with: ${hide[*]}"

export BUILD_DIR=$build_dir SOURCE_DIR=$source_dir WORK=$work PREFIX=$prefix VERSION=$version
export BINDIR=$bindir LIBDIR=$libdir DATADIR=$datadir CXX_COMPILER=$cxx SANITIZE=$sanitize MUJOCO_USED=$mujoco_used
timeout 420 "${hide[@]}" bash -s <<'INNER'
set -euo pipefail
fail() { echo "FAILED: $*" >&2; exit 1; }
mount -t tmpfs -o size=1m simgate-hidden-build "$BUILD_DIR"
mount -t tmpfs -o size=1m simgate-hidden-source "$SOURCE_DIR"
[ ! -e "$BUILD_DIR/CMakeCache.txt" ] && [ ! -e "$SOURCE_DIR/CMakeLists.txt" ] || fail "the trees are not hidden"
# (only a MuJoCo directory of its own: never a system library directory)
if [ -d "$MUJOCO_USED" ] && [[ $(basename "$MUJOCO_USED") == *mujoco* ]]; then
  mount -t tmpfs -o size=1m simgate-hidden-mujoco "$MUJOCO_USED"
  echo "hid the MuJoCo the build used: $MUJOCO_USED"
fi
cd /
unset SIMGATE_PLUGIN_PATH LD_LIBRARY_PATH CYCLONEDDS_URI

# everything the installed simgate does, from a prefix at $1
exercise() {
  local prefix=$1 simgate=$1/$BINDIR/simgate config_dir=$1/$DATADIR/simgate/config
  local out
  out=$(timeout 30 "$simgate" --version) || fail "simgate --version"
  [[ $out == *"$VERSION"* ]] || fail "simgate --version printed '$out', expected $VERSION"
  echo "$prefix: simgate --version: $out"
  for config in "$config_dir"/*.json; do
    # a config naming a transport this build did not install (dds without Cyclone) is not checked
    local missing=""
    for plugin in $(grep -o '"plugin": *"[a-z0-9]*"' "$config" | sed 's/.*"\([a-z0-9]*\)"$/\1/'); do
      [ -f "$prefix/$LIBDIR/simgate/plugins/libsimgate_transport_$plugin.so" ] || missing=$plugin
    done
    if [ -n "$missing" ]; then
      echo "$config: not checked, transport '$missing' not installed"
      continue
    fi
    timeout 60 "$simgate" check "$config" || fail "simgate check $config"
  done
  out=$(timeout 60 "$simgate" check --model "$WORK/current_mujoco.xml" 2>&1) ||
    fail "simgate check --model current_mujoco.xml (MuJoCo's PID plugin from $LIBDIR/mujoco_plugin): $out"
  echo "$prefix: a model using MuJoCo's PID actuator plugin: $out"
}
# The web app answers GET / from the installed share/simgate/web (the build tree's is hidden):
# the websocket transport's ws:// endpoint of the running `simgate run` ($run) in
# $WORK/endpoints.json (the foxglove transport's is a ws:// one too).
check_web_app() {
  local web_port page
  web_port=$(grep -o '"websocket":\["ws://127\.0\.0\.1:[0-9]*' "$WORK/endpoints.json" | head -n 1 | sed 's/.*://')
  [ -n "$web_port" ] || { kill "$run"; cat "$WORK/endpoints.json"; fail "no ws endpoint"; }
  page=$(timeout 30 bash -c 'exec 3<>/dev/tcp/127.0.0.1/$0; printf "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n" >&3; cat <&3' "$web_port") ||
    { kill "$run"; fail "GET / on the websocket transport"; }
  grep -q '^HTTP/1.1 200' <<<"$page" && grep -q '<title>simgate</title>' <<<"$page" ||
    { kill "$run"; echo "$page" | head -n 20; fail "GET / did not answer the installed index.html"; }
  echo "GET http://127.0.0.1:$web_port/: the installed web app's index.html"
}

# --- run the installed demo from /opt/simgate-like prefix, one call, quit -----------------
exercise "$PREFIX"
simgate=$PREFIX/$BINDIR/simgate
timeout 120 "$simgate" run "$PREFIX/$DATADIR/simgate/config/install-test-demo.json" \
  --endpoints-file "$WORK/endpoints.json" >"$WORK/run.log" 2>&1 &
run=$!
# bounded wait for the endpoints file (written once every transport listens), or the run's end
for _ in $(seq 600); do
  [ -s "$WORK/endpoints.json" ] && break
  kill -0 "$run" 2>/dev/null || break
  sleep 0.1
done
if [ ! -s "$WORK/endpoints.json" ]; then
  kill "$run" 2>/dev/null || true
  wait "$run" || true
  cat "$WORK/run.log"
  fail "simgate run wrote no endpoints file"
fi
port=$(grep -o 'tcp://127\.0\.0\.1:[0-9]*' "$WORK/endpoints.json" | head -n 1 | sed 's/.*://')
[ -n "$port" ] || { kill "$run"; cat "$WORK/endpoints.json"; fail "no tcp endpoint"; }
robots=$(timeout 30 "$simgate" call --port "$port" simulation list_robots) || { kill "$run"; fail "simgate call"; }
echo "simgate call --port $port simulation list_robots: $robots"
[ "$robots" = '["robot","human"]' ] || { kill "$run"; fail "expected [\"robot\",\"human\"]"; }
check_web_app
timeout 30 "$simgate" call --port "$port" simulation quit || { kill "$run"; fail "simulation quit"; }
status=0
wait "$run" || status=$?
sed 's/^/  | /' "$WORK/run.log"
[ $status -eq 0 ] || fail "simgate run exited $status"
echo "simgate run of the installed demo: served one call, quit, exit 0"

# --- the prefix moved elsewhere still works (RUNPATH, plugins and pkg-config are relative) ---
moved=$WORK/moved/simgate
mkdir -p "$WORK/moved"
mv "$PREFIX" "$moved"
exercise "$moved"

# a program built with pkg-config alone, against the moved prefix
export PKG_CONFIG_PATH=$moved/$LIBDIR/pkgconfig
flags=$(pkg-config --cflags --libs simgate) || fail "pkg-config --cflags --libs simgate"
echo "pkg-config --cflags --libs simgate: $flags"
case "$SANITIZE" in
  address) sanitize_flags=(-fsanitize=address,undefined) ;;
  thread) sanitize_flags=(-fsanitize=thread) ;;
  *) sanitize_flags=() ;;
esac
# shellcheck disable=SC2086
timeout 300 "$CXX_COMPILER" -std=c++20 "${sanitize_flags[@]}" -o "$WORK/pkg_config_probe" \
  "$WORK/pkg_config_probe.cc" $flags -Wl,-rpath,"$moved/$LIBDIR" || fail "building against pkg-config's flags"
out=$(timeout 30 "$WORK/pkg_config_probe") || fail "pkg_config_probe"
echo "$out"
last_dir=$(grep '^plugin dir: ' <<<"$out" | tail -n 1 | sed 's/^plugin dir: //')
[ "$last_dir" = "$moved/$LIBDIR/simgate/plugins" ] ||
  fail "libsimgate_core searches '$last_dir' last, expected its own prefix's $moved/$LIBDIR/simgate/plugins"
grep -q "client: no client for transport 'carrier-pigeon'" <<<"$out" || fail "clients library"

# the same program through the CMake package: find_package(simgate) gives core, sim, clients
mkdir "$WORK/cmake-consumer" "$WORK/cmake-core-only"
cat >"$WORK/cmake-consumer/CMakeLists.txt" <<'EOF'
cmake_minimum_required(VERSION 3.25)
project(simgate_consumer LANGUAGES CXX)
set(CMAKE_CXX_STANDARD 20)
find_package(simgate 0.1 REQUIRED)
add_executable(probe ../pkg_config_probe.cc)
target_link_libraries(probe PRIVATE simgate::core simgate::sim simgate::clients)
EOF
timeout 120 cmake -S "$WORK/cmake-consumer" -B "$WORK/cmake-consumer/build" -G Ninja \
  -DCMAKE_PREFIX_PATH="$moved" -DCMAKE_CXX_COMPILER="$CXX_COMPILER" \
  -DCMAKE_CXX_FLAGS="${sanitize_flags[*]}" -DCMAKE_EXE_LINKER_FLAGS="${sanitize_flags[*]}" >"$WORK/consumer.log" ||
  { cat "$WORK/consumer.log"; fail "find_package(simgate)"; }
timeout 300 cmake --build "$WORK/cmake-consumer/build" >>"$WORK/consumer.log" ||
  { cat "$WORK/consumer.log"; fail "building against simgate::core, simgate::sim, simgate::clients"; }
out=$(timeout 30 "$WORK/cmake-consumer/build/probe") || fail "the CMake-built probe"
grep -qx "plugin dir: $moved/$LIBDIR/simgate/plugins" <<<"$out" || fail "CMake-built probe: $out"
echo "find_package(simgate): a program linking simgate::core, simgate::sim and simgate::clients builds and runs"
# a transport plugin's project asks for core alone
cat >"$WORK/cmake-core-only/CMakeLists.txt" <<'EOF'
cmake_minimum_required(VERSION 3.25)
project(simgate_core_only LANGUAGES CXX)
find_package(simgate 0.1 REQUIRED COMPONENTS core)
if(NOT TARGET simgate::core OR simgate_sim_FOUND OR NOT COMMAND simgate_add_transport_plugin)
  message(FATAL_ERROR "COMPONENTS core: simgate::core and simgate_add_transport_plugin, sim not searched")
endif()
EOF
timeout 120 cmake -S "$WORK/cmake-core-only" -B "$WORK/cmake-core-only/build" -G Ninja \
  -DCMAKE_PREFIX_PATH="$moved" >"$WORK/core-only.log" || { cat "$WORK/core-only.log"; fail "COMPONENTS core"; }
echo "find_package(simgate COMPONENTS core): OK"

# a component library built out of tree (docs/writing-a-component.md), loaded by a config of
# the moved prefix's installed simgate, its component called (issue #18)
mkdir "$WORK/odometer"
cp "$WORK/odometer_library.cc" "$WORK/odometer/"
cat >"$WORK/odometer/CMakeLists.txt" <<'EOF'
cmake_minimum_required(VERSION 3.25)
project(odometer LANGUAGES CXX)
set(CMAKE_CXX_STANDARD 20)
find_package(simgate 0.1 REQUIRED COMPONENTS core sim)
simgate_add_component_library(odometer odometer_library.cc)
EOF
timeout 120 cmake -S "$WORK/odometer" -B "$WORK/odometer/build" -G Ninja \
  -DCMAKE_PREFIX_PATH="$moved" -DCMAKE_CXX_COMPILER="$CXX_COMPILER" \
  -DCMAKE_CXX_FLAGS="${sanitize_flags[*]}" -DCMAKE_MODULE_LINKER_FLAGS="${sanitize_flags[*]}" >"$WORK/odometer.log" ||
  { cat "$WORK/odometer.log"; fail "find_package(simgate COMPONENTS core sim) for a component library"; }
timeout 300 cmake --build "$WORK/odometer/build" >>"$WORK/odometer.log" ||
  { cat "$WORK/odometer.log"; fail "building the component library out of tree"; }
library=$WORK/odometer/build/libsimgate_components_odometer.so
[ -f "$library" ] || fail "no $library"
config_dir=$moved/$DATADIR/simgate/config
sed -e "s|\"scene\"|\"component_libraries\": [\"$library\"], \"scene\"|" \
    -e 's|{"name": "pose", "type": "pose"}|{"name": "pose", "type": "pose"}, {"name": "odometer", "type": "odometer"}|' \
    "$config_dir/install-test-demo.json" >"$config_dir/install-test-odometer.json"
grep -q '"type": "odometer"' "$config_dir/install-test-odometer.json" || fail "the demo config has no pose component to follow"
simgate=$moved/$BINDIR/simgate
timeout 60 "$simgate" check "$config_dir/install-test-odometer.json" || fail "simgate check with the component library"
rm -f "$WORK/endpoints.json"
timeout 120 "$simgate" run "$config_dir/install-test-odometer.json" --endpoints-file "$WORK/endpoints.json" \
  >"$WORK/odometer-run.log" 2>&1 &
run=$!
for _ in $(seq 600); do
  [ -s "$WORK/endpoints.json" ] && break
  kill -0 "$run" 2>/dev/null || break
  sleep 0.1
done
[ -s "$WORK/endpoints.json" ] || { kill "$run" 2>/dev/null; cat "$WORK/odometer-run.log"; fail "run with the component library"; }
port=$(grep -o 'tcp://127\.0\.0\.1:[0-9]*' "$WORK/endpoints.json" | head -n 1 | sed 's/.*://')
distance=$(timeout 30 "$simgate" call --port "$port" robot.odometer get_distance) ||
  { kill "$run"; cat "$WORK/odometer-run.log"; fail "calling the library's component"; }
echo "out-of-tree component library: robot.odometer get_distance = $distance"
check_web_app
timeout 30 "$simgate" call --port "$port" simulation quit || { kill "$run"; fail "simulation quit"; }
wait "$run" || { cat "$WORK/odometer-run.log"; fail "simgate run with the component library exited non-zero"; }
echo "installed tree: every check passed"
INNER
