#!/usr/bin/env bash
# The ARM part of CI (called by .ci/run after the host build and tests, with
# the same CARGO_TARGET_DIR so nothing is built twice):
#   install -> three release binaries -> test suite under qemu-user, release
#   profile reusing the binaries' dependency builds (aarch64 everything,
#   armv7 all but the PETS data-set tests; see cross/test.sh) -> bit-exact
#   report streams across targets -> vivid VM test on the musl binary.
# Each step prints its wall time; the total is in bench/RESULTS.md.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$PWD/target}

t0=$(date +%s)
# Wall and CPU time per step: on a shared machine the CPU seconds are the
# stable number (an idle 2-core CI machine needs about half of them as wall).
step() {
    local name=$1; shift
    echo "=== cross/ci.sh: $name"
    /usr/bin/time -f "=== cross/ci.sh: $name took %e s wall, %U s user + %S s sys CPU" "$@"
}
step install bash cross/install.sh
step build bash cross/build.sh
step test bash cross/test.sh
step bitexact bash cross/bitexact.sh
STATURE_BIN=$CARGO_TARGET_DIR/aarch64-unknown-linux-musl/release/stature \
    step vm-test bash cross/vm-test.sh
echo "=== cross/ci.sh: all ARM checks passed in $(($(date +%s) - t0)) s"
