#!/usr/bin/env bash
# scripts/lib.sh's timings (scripts/test, .ci/run, docs/building.md): timed records each stage
# and keeps its command's exit status; print_timings writes the one line .ci/run sums;
# slowest_build_steps lists only what the last build ran, slowest first; slowest_tests reads
# ctest's cost data.
#   timings_test.sh SOURCE_DIR
set -euo pipefail
source "$1/scripts/lib.sh"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# timed: the stage is recorded, with its name (spaces allowed), also when its command fails
timed build sleep 0.2
status=0
timed "fuzz run" sh -c 'exit 3' || status=$?
[ "$status" -eq 3 ] || fail "timed returned $status, not the command's 3"
[ ${#SIMGATE_STAGES[@]} -eq 2 ] || fail "stages recorded: ${SIMGATE_STAGES[*]}"
[[ "${SIMGATE_STAGES[0]}" =~ ^build\ 0\.[2-9]$ ]] || fail "first stage: '${SIMGATE_STAGES[0]}'"
[[ "${SIMGATE_STAGES[1]}" =~ ^fuzz\ run\ [0-9]+\.[0-9]$ ]] || fail "second stage: '${SIMGATE_STAGES[1]}'"

# print_timings: on stderr, and appended to SIMGATE_TIMINGS_FILE
SIMGATE_STAGES=("packages 1.5" "build 100.0" "fuzz run 20.3")
SIMGATE_TIMINGS_FILE=$work/timings print_timings address 2>"$work/stderr"
expected="address: packages 1.5 s, build 100.0 s, fuzz run 20.3 s, total 121.8 s"
[ "$(cat "$work/timings")" = "$expected" ] || fail "timings file: '$(cat "$work/timings")', expected '$expected'"
grep -qF "timings $expected" "$work/stderr" || fail "not printed: $(cat "$work/stderr")"

# slowest_build_steps: from ninja's log, only the outputs written since the build started
mkdir -p "$work/build"
printf '# ninja log v5\n0\t9000\t100\told.o\tx\n0\t1500\t300\tfast.o\ty\n500\t4500\t400\tslow.o\tz\n' >"$work/build/.ninja_log"
SIMGATE_BUILD_STARTED_NS=200
steps=$(slowest_build_steps "$work/build")
[ "$(awk '{print $3}' <<<"$steps" | tr '\n' ' ')" = "slow.o fast.o " ] || fail "build steps: $steps"
grep -q '^ *4.0 s  slow.o$' <<<"$steps" || fail "seconds of slow.o: $steps"

# slowest_tests: ctest's cost data, up to its "---" line
mkdir -p "$work/build/Testing/Temporary"
printf 'Quick 1 0.5\nSlow 2 12.25\nMiddle 1 3\n---\nFailedTest\n' >"$work/build/Testing/Temporary/CTestCostData.txt"
tests=$(cd "$work/build" && slowest_tests 2)
[ "$(awk '{print $3}' <<<"$tests" | tr '\n' ' ')" = "Slow Middle " ] || fail "tests: $tests"
# ... also from a suite of thousands of tests, under pipefail (a head ending the pipe early
# made sort die of SIGPIPE, and scripts/test with it)
for i in $(seq 1 5000); do echo "Suite.ATestWithAFairlyLongNameNumber$i 1 0.$i"; done >"$work/build/Testing/Temporary/CTestCostData.txt"
tests=$(cd "$work/build" && slowest_tests 3) || fail "slowest_tests failed ($?) on 5000 tests"
[ "$(wc -l <<<"$tests")" -eq 3 ] || fail "5000 tests: $tests"
echo "timings: stages, summary line, build steps and tests as expected"
