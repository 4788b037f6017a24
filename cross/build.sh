#!/usr/bin/env bash
# Release binaries for the boards:
#   aarch64-unknown-linux-gnu      Raspberry Pi 4 / Zero 2 (64-bit OS), most Cortex-A53+ SoCs
#   armv7-unknown-linux-gnueabihf  32-bit ARMv7 hard-float boards
#   aarch64-unknown-linux-musl     fully static aarch64 (minimal images, the vivid VM test)
# Output: $CARGO_TARGET_DIR/<target>/release/stature (default target dir ./target),
# with the `v4l2` feature (camera capture) that board builds need.
#
#   cross/build.sh                 # all three
#   cross/build.sh aarch64-unknown-linux-gnu
set -euo pipefail
cd "$(dirname "$0")/.."
targets=("$@")
if [[ ${#targets[@]} -eq 0 ]]; then
    targets=(aarch64-unknown-linux-gnu armv7-unknown-linux-gnueabihf aarch64-unknown-linux-musl)
fi
target_dir=${CARGO_TARGET_DIR:-target}
# One cargo run for every target: one job queue, so while one target's
# `stature` crate compiles or links (long single-threaded steps) the other
# core builds another target, instead of idling through three runs in turn.
target_args=()
for t in "${targets[@]}"; do target_args+=(--target "$t"); done
echo "cross/build.sh: ${targets[*]}"
cargo build --release --locked --features v4l2 "${target_args[@]}" --bin stature
for t in "${targets[@]}"; do
    bin=$target_dir/$t/release/stature
    # Size as shipped: the release profile keeps line tables (debug = 1) for
    # backtraces; `strip` drops them for the board if space is tight.
    echo "cross/build.sh: $bin $(stat -c %s "$bin") bytes ($(file -b "$bin" | cut -d, -f1-2))"
done
