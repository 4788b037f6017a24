#!/bin/sh
# Side by side: stature's detect stage and OpenCV's MOG2 (BackgroundSubtractorMOG2,
# history 500, varThreshold 16, shadows on) on the same PETS-derived frames:
# ns/frame and, with valgrind present, instructions per pixel, and the ratios.
# OpenCV comes from PyPI (opencv-python-headless) in a venv under the target
# dir; without Python, pip or network the comparison is skipped with a message.
#
#   bench/mog2_compare.sh [WIDTHxHEIGHT]     (default 640x480)
set -eu
SIZE=${1:-640x480}
WARM=30
N=10
ROOT=$(cd "$(dirname "$0")/.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
VENV=$TARGET/mog2-venv
OUT=$TARGET/mog2-frames
mkdir -p "$OUT"

if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import cv2" 2>/dev/null; then
    if ! python3 -m venv "$VENV" >/dev/null 2>&1 ||
        ! "$VENV/bin/pip" install -q opencv-python-headless >/dev/null 2>&1; then
        echo "mog2_compare: skipped (no python3 venv or opencv-python-headless from PyPI)"
        exit 0
    fi
fi

cd "$ROOT"
cargo bench --bench detect --no-run -q 2>/dev/null
BIN=$(ls -t "$TARGET"/release/deps/detect-* | grep -v '\.d$' | head -1)
"$BIN" --size "$SIZE" --warm $WARM --frames $N --dump "$OUT" | tee "$OUT/ours.txt"
Y4M="$OUT/frames_$SIZE.y4m"
PY="$VENV/bin/python $ROOT/bench/mog2_compare.py"
$PY "$Y4M" $WARM $N bgr | tee "$OUT/mog2_bgr.txt"
$PY "$Y4M" $WARM $N gray | tee "$OUT/mog2_gray.txt"
PX=$(echo "$SIZE" | awk -Fx '{print $1*$2}')
OURS_NS=$(awk '/total/{print $2}' "$OUT/ours.txt")
for m in bgr gray; do
    NS=$(awk '{print $(NF-1)}' "$OUT/mog2_$m.txt")
    awk -v a="$NS" -v b="$OURS_NS" -v m=$m 'BEGIN{printf "time ratio MOG2 %s / stature: %.1f\n", m, a/b}'
done

if ! command -v valgrind >/dev/null; then
    echo "mog2_compare: valgrind missing, instruction counts skipped"
    exit 0
fi
count() { # total instructions of a command under callgrind
    valgrind --tool=callgrind --callgrind-out-file="$OUT/cg.tmp" "$@" >/dev/null 2>&1
    callgrind_annotate "$OUT/cg.tmp" 2>/dev/null | awk '/PROGRAM TOTALS/{gsub(",","",$1); print $1}'
}
# Ours: only the measured loop.
valgrind --tool=callgrind --callgrind-out-file="$OUT/cg.ours" --toggle-collect='*measured*' \
    "$BIN" --size "$SIZE" --warm $WARM --frames $N >/dev/null 2>&1
OURS=$(callgrind_annotate "$OUT/cg.ours" 2>/dev/null | awk '/PROGRAM TOTALS/{gsub(",","",$1); print $1}')
awk -v i="$OURS" -v px="$PX" -v n=$N 'BEGIN{printf "stature detect: %.1f instructions/pixel\n", i/(px*n)}'
for m in bgr gray; do
    # OpenCV: the run with N measured frames minus the same run with none.
    FULL=$(count $VENV/bin/python "$ROOT/bench/mog2_compare.py" "$Y4M" $WARM $N $m)
    BASE=$(count $VENV/bin/python "$ROOT/bench/mog2_compare.py" "$Y4M" $WARM 0 $m)
    awk -v f="$FULL" -v b="$BASE" -v o="$OURS" -v px="$PX" -v n=$N -v m=$m 'BEGIN{
        printf "OpenCV MOG2 %s: %.1f instructions/pixel, ratio MOG2/stature %.1f\n",
            m, (f-b)/(px*n), (f-b)/o }'
done
