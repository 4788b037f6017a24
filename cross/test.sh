#!/usr/bin/env bash
# The test suite on ARM under qemu-user (cargo runners in .cargo/config.toml;
# binfmt_misc entries from cross/install.sh let tests spawn the ARM binary).
# Tests read ../shared/data and run ffmpeg from the host file system as usual.
#
#   cross/test.sh                          # aarch64: everything; armv7: see below
#   cross/test.sh aarch64 [CARGO TEST ARGS...]
#   cross/test.sh armv7 [CARGO TEST ARGS...]
#   CROSS_TEST_ARMV7=full cross/test.sh    # armv7: everything too
#
# Release profile with the `v4l2` feature, as the host CI tests and as
# cross/build.sh builds: the tests reuse every dependency build.sh compiled.
# On armv7 the tests that decode the PETS video (dataset::require_shared_data)
# are skipped (STATURE_SKIP_DATA_TESTS); all other unit and integration tests
# run. They re-check algorithm accuracy on long clips, which on armv7 is
# already implied by cross/bitexact.sh (the armv7 binary's reports on PETS
# frames are byte-identical to the host's); the 32-bit risks (usize overflow
# in pixel and offset maths) are in the unit and synthetic tests, which run.
# Numbers: bench/RESULTS.md, "ARM builds".
set -euo pipefail
cd "$(dirname "$0")/.."

run() {
    local arch=$1; shift
    local triple
    case $arch in
        aarch64) triple=aarch64-unknown-linux-gnu ;;
        armv7) triple=armv7-unknown-linux-gnueabihf ;;
        *) echo "cross/test.sh: unknown arch $arch (aarch64 or armv7)" >&2; exit 2 ;;
    esac
    echo "cross/test.sh: cargo test --release --features v4l2 --target $triple $*"
    cargo test --release --locked --features v4l2 --target "$triple" "$@"
}

if [[ $# -gt 0 ]]; then
    run "$@"
    exit
fi
run aarch64
if [[ "${CROSS_TEST_ARMV7:-lib}" == full ]]; then
    run armv7
else
    STATURE_SKIP_DATA_TESTS=1 run armv7
fi
