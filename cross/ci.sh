#!/usr/bin/env bash
# The ARM part of CI (called by .ci/run after the host build and tests, with
# the same CARGO_TARGET_DIR so nothing is built twice):
#   install -> three release binaries -> both targets' test binaries (the
#   aarch64 and armv7 `stature` binaries the tests spawn are build.sh's)
#   -> side by side: the suite under qemu-user on both targets
#   (cross/test.sh run; what it leaves out, and why, is in its header),
#   bit-exact report streams across targets, and the vivid VM test on the
#   musl binary (which also runs the serial-sink test qemu-user cannot).
# Everything after the builds is CPU-bound emulation: run together, no core
# idles while one long test finishes. Each step prints its wall and CPU
# time; the totals are in bench/RESULTS.md ("ARM builds").
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$PWD/target}

t0=$(date +%s)
# Wall and CPU time per step: on a shared machine the CPU seconds are the
# stable number (an idle 2-core CI machine needs about half of them as wall).
step() {
    local name=$1
    shift
    echo "=== cross/ci.sh: $name"
    /usr/bin/time -f "=== cross/ci.sh: $name took %e s wall, %U s user + %S s sys CPU" "$@"
}
step install bash cross/install.sh
step build bash cross/build.sh
step test-build bash cross/test.sh build

logs=$CARGO_TARGET_DIR/cross-cache
mkdir -p "$logs"
step test-run bash cross/test.sh run >"$logs/test-run.log" 2>&1 &
test_pid=$!
status=0
step bitexact bash cross/bitexact.sh || status=1
STATURE_BIN=$CARGO_TARGET_DIR/aarch64-unknown-linux-musl/release/stature \
    step vm-test bash cross/vm-test.sh || status=1
echo "=== cross/ci.sh: waiting for the emulated test runs"
test_status=0
wait "$test_pid" || test_status=$?
cat "$logs/test-run.log"
[[ $test_status -eq 0 ]] || status=1
[[ $status -eq 0 ]] || { echo "=== cross/ci.sh: FAILED after $(($(date +%s) - t0)) s" >&2; exit 1; }
echo "=== cross/ci.sh: all ARM checks passed in $(($(date +%s) - t0)) s"
