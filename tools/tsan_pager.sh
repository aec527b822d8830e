#!/usr/bin/env bash
# Builds the runtime unit tests with ThreadSanitizer in a separate build
# directory and runs the pager tests (strip logic, the threaded pager and
# the fast random-walk stress test with two lock-free readers).
#
#   tools/tsan_pager.sh [BUILD_DIR]      (default /tmp/tsan; JOBS=N for N compile jobs)
#
# Exit status: 0 when every test passed and ThreadSanitizer reported
# nothing, 1 otherwise, 2 when the build failed.
set -euo pipefail

src="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-/tmp/tsan}"
log="$build/tsan_pager.log"

cmake -S "$src" -B "$build" -G Ninja \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS=-fsanitize=thread \
  -DSANDTABLE_BENCH=OFF >/dev/null
# JOBS: parallel compile jobs (default 2: the machines here are shared).
cmake --build "$build" --target sandtable_paging_test -j "${JOBS:-2}" || exit 2

# halt_on_error=0: run every test and count every report.
status=0
TSAN_OPTIONS="halt_on_error=0 second_deadlock_stack=1 ${TSAN_OPTIONS:-}" \
  "$build/runtime/sandtable_paging_test" \
  --gtest_filter='StripPlanner.*:NeededSet.*:Pager.*:PagerStress.*' 2>&1 | tee "$log" || status=1
reports=$(grep -c 'WARNING: ThreadSanitizer' "$log" || true)
echo "tsan_pager: ThreadSanitizer reports: $reports (log: $log)"
if [ "$reports" != "0" ]; then status=1; fi
exit "$status"
