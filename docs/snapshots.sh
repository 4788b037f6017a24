#!/usr/bin/env bash
# Regenerates the installer snapshots shown in the README:
#   docs/snapshot-sim-plaza.png  `stature snapshot` on the built-in plaza scene
#                                (stops once the calibration is confident enough
#                                to measure, or at the end of the clip)
#   docs/snapshot-pets.png       `stature run --snapshot` on the PETS 2009 S2.L1
#                                clip (written at the end of the clip)
# Needs ffmpeg and ../shared/data beside the repository. Run from anywhere:
#   docs/snapshots.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin=${CARGO_TARGET_DIR:-target}/release/stature
"$bin" snapshot --source 'sim:plaza?seed=1' --out docs/snapshot-sim-plaza.png -q >/dev/null
pets=../shared/data/pets2009-s2l1/vtest.avi
test -f "$pets" || { echo "$pets is missing" >&2; exit 1; }
ffmpeg -nostdin -v error -i "$pets" -f yuv4mpegpipe -pix_fmt yuv420p - \
  | "$bin" run --source y4m:- --snapshot docs/snapshot-pets.png -q >/dev/null
echo "wrote docs/snapshot-sim-plaza.png docs/snapshot-pets.png"
