#!/usr/bin/env bash
# Numbers for bench/RESULTS.md ("ARM builds"): release binary sizes and the
# peak RSS of the aarch64 binary on a 1280x720 clip under qemu-user.
# Needs cross/build.sh first. Not part of CI (it only reports).
#
#   cross/measure.sh
set -euo pipefail
cd "$(dirname "$0")/.."
T=${CARGO_TARGET_DIR:-target}
work=$T/cross-cache/measure
mkdir -p "$work"

echo "## binary sizes (bytes): as built (line tables kept), stripped"
for t in aarch64-unknown-linux-gnu armv7-unknown-linux-gnueabihf aarch64-unknown-linux-musl; do
    b=$T/$t/release/stature
    case $t in
        aarch64*) strip=aarch64-linux-gnu-strip ;;
        armv7*) strip=arm-linux-gnueabihf-strip ;;
    esac
    $strip -o "$work/stature-$t.stripped" "$b"
    echo "$t $(stat -c %s "$b") $(stat -c %s "$work/stature-$t.stripped")"
done

# 1280x720 clip: PETS 2009 S2.L1 scaled up (real people) when the shared data
# is there, else ffmpeg's testsrc2.
clip=$work/clip-1280x720.y4m
if [[ ! -s $clip ]]; then
    if [[ -f ../shared/data/pets2009-s2l1/vtest.avi ]]; then
        ffmpeg -nostdin -v error -i ../shared/data/pets2009-s2l1/vtest.avi -frames:v 300 \
            -vf scale=1280:720 -pix_fmt yuv420p -f yuv4mpegpipe -y "$clip"
    else
        ffmpeg -nostdin -v error -f lavfi -i "testsrc2=size=1280x720:rate=25" -frames:v 300 \
            -pix_fmt yuv420p -f yuv4mpegpipe -y "$clip"
    fi
fi
rss() { /usr/bin/time -f "%M" "$@" 2>&1 >/dev/null | tail -1; }
bin=$T/aarch64-unknown-linux-gnu/release/stature
q=(env QEMU_LD_PREFIX=/usr/aarch64-linux-gnu qemu-aarch64-static)
echo "## peak RSS (KiB), 300 frames 1280x720 from $(basename "$clip")"
echo "qemu-user aarch64 run: $(rss "${q[@]}" "$bin" run --quiet --source "y4m:$clip" --report file:/dev/null)"
echo "qemu-user aarch64 baseline (--version): $(rss "${q[@]}" "$bin" --version)"
if [[ -x $T/release/stature ]]; then
    echo "host x86_64 run: $(rss "$T/release/stature" run --quiet --source "y4m:$clip" --report file:/dev/null)"
fi
