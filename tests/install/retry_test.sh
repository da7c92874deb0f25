#!/usr/bin/env bash
# scripts/lib.sh's retry_failed_tests_once, on small ctest projects of its own: a test that
# fails once and then passes is retried and passes; a test with a sanitizer report in its
# output is not retried; a test that always fails still fails.
#   retry_test.sh SOURCE_DIR
set -euo pipefail
source "$1/scripts/lib.sh"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# A ctest project in $work/<name> with the given add_test lines; prints its build directory.
project() {
  local dir=$work/$1
  shift
  mkdir -p "$dir"
  {
    echo 'cmake_minimum_required(VERSION 3.20)'
    echo 'project(retry NONE)'
    echo 'enable_testing()'
    printf '%s\n' "$@"
  } > "$dir/CMakeLists.txt"
  cmake -S "$dir" -B "$dir/build" > /dev/null
  echo "$dir/build"
}
fail() { echo "FAIL: $*" >&2; exit 1; }

# fails the first time (no marker yet), passes the second
flaky="add_test(NAME Suite.FailsOnce COMMAND sh -c \"if [ -e $work/marker ]; then exit 0; fi; touch $work/marker; echo 'Expected: 2, actual: 1'; exit 1\")"
cd "$(project flaky "$flaky" 'add_test(NAME Suite.Passes COMMAND true)')"
! ctest -j 2 > /dev/null 2>&1 || fail "the flaky test passed its first run"
retry_failed_tests_once > retry.out 2>&1 || { cat retry.out; fail "a test that passes alone was not retried"; }
grep -q "passed when retried alone.*Suite.FailsOnce" retry.out || fail "the retried test is not named"

# a sanitizer report: failed at once, never rerun (the marker would make it pass)
rm -f "$work/marker"
race="add_test(NAME Suite.Race COMMAND sh -c \"if [ -e $work/marker ]; then exit 0; fi; touch $work/marker; echo 'WARNING: ThreadSanitizer: data race (pid=1)'; exit 66\")"
cd "$(project race "$race")"
! ctest > /dev/null 2>&1 || fail "the racy test passed its first run"
if retry_failed_tests_once > retry.out 2>&1; then cat retry.out; fail "a sanitizer report was retried"; fi
grep -q "Suite.Race failed with a sanitizer report: not retried" retry.out || fail "the reason is not given"

# a test that always fails fails after its retry
cd "$(project always 'add_test(NAME Suite.Always COMMAND false)')"
! ctest > /dev/null 2>&1 || fail "false passed"
if retry_failed_tests_once > retry.out 2>&1; then cat retry.out; fail "a test that always fails passed"; fi

# nothing failed (no list of failed tests): nothing to retry, a failure stands
cd "$(project none 'add_test(NAME Suite.Passes COMMAND true)')"
ctest > /dev/null 2>&1 || fail "true failed"
if retry_failed_tests_once > retry.out 2>&1; then fail "a run without failed tests counted as retried"; fi
echo "retry_failed_tests_once: all cases behave"
