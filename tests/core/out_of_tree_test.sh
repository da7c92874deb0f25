#!/usr/bin/env bash
# Installs this build into a temporary prefix, builds tests/core/out_of_tree against it with
# find_package(simgate), and loads the result with plugin_probe.
#   out_of_tree_test.sh BUILD_DIR SOURCE_DIR PLUGIN_PROBE [SANITIZE]
set -euo pipefail
build_dir=$1 source_dir=$2 probe=$3 sanitize=${4:-}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cmake --install "$build_dir" --prefix "$work/prefix" >/dev/null
flags=""
case "$sanitize" in
  address) flags="-fsanitize=address,undefined" ;;
  thread) flags="-fsanitize=thread" ;;
esac
cmake -S "$source_dir" -B "$work/build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_MODULE_LINKER_FLAGS="$flags" >/dev/null
cmake --build "$work/build" >/dev/null
plugin=$(find "$work/build" -name libsimgate_transport_hello.so | head -n 1)
[ -n "$plugin" ] || { echo "plugin not built"; exit 1; }
out=$("$probe" "$plugin" "$work/outcome.json")
echo "$out"
[ "$out" = '{"status":"SUCCESS","value":3}' ] || { echo "unexpected outcome"; exit 1; }
echo "out-of-tree plugin loaded and served test_component.add"
