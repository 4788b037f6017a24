#!/usr/bin/env bash
# The test suite on ARM under qemu-user (cargo runners in .cargo/config.toml;
# binfmt_misc entries from cross/install.sh let tests spawn the ARM binary).
# Tests read ../shared/data and run ffmpeg from the host file system as usual.
#
#   cross/test.sh                          # full suite on aarch64, see below for armv7
#   cross/test.sh aarch64 [CARGO TEST ARGS...]
#   cross/test.sh armv7 [CARGO TEST ARGS...]
#   CROSS_TEST_ARMV7=full cross/test.sh    # full suite on armv7 too
#
# By default armv7 runs the library's unit tests and the fast integration
# tests (everything but the heavy data-set ones) — the 32-bit specific risks
# are in the arithmetic (usize = 32 bits, overflow in pixel/offset maths) and
# are covered there; the whole suite under qemu-arm costs much more CI time
# than it buys (numbers in bench/RESULTS.md, "ARM builds").
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
    echo "cross/test.sh: cargo test --target $triple $*"
    cargo test --locked --target "$triple" "$@"
}

if [[ $# -gt 0 ]]; then
    run "$@"
    exit
fi
run aarch64
if [[ "${CROSS_TEST_ARMV7:-lib}" == full ]]; then
    run armv7
else
    run armv7 --lib --bins --test board_profiles
fi
