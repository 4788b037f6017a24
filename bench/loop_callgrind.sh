#!/usr/bin/env bash
# Instructions per pixel of each stage of the vision loop under callgrind.
#   bench/loop_callgrind.sh [bench/loop.rs args: --source URI --warm W --frames N ...]
# Counts only inside the bench's measured_frame (--toggle-collect), so
# start-up, warm-up and the source's decoding/rendering are left out, and
# splits the count by the bench's stage_* functions (inclusive counts from
# callgrind_annotate --inclusive=yes). With --calib-anchors it prints the
# instructions per refit of the calibrator alone instead.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v valgrind >/dev/null || { echo "valgrind not installed (apt-get install valgrind)" >&2; exit 2; }
bin=$(cargo bench --bench loop --no-run --message-format=json 2>/dev/null | python3 -c '
import json,sys
for line in sys.stdin:
    m=json.loads(line)
    if m.get("reason")=="compiler-artifact" and m.get("executable") and m["target"]["name"]=="loop":
        print(m["executable"])' | tail -1)
out=$(mktemp -d)
valgrind --tool=callgrind --toggle-collect='*measured*' --callgrind-out-file="$out/cg.out" \
    "$bin" "$@" > "$out/stdout" 2> "$out/stderr"
echo "callgrind output: $out/cg.out"
cat "$out/stdout"
callgrind_annotate --inclusive=yes --threshold=100 "$out/cg.out" > "$out/annotate" 2>/dev/null
python3 - "$out/annotate" "$out/stdout" <<'EOF'
import re, sys
ann, stdout = open(sys.argv[1]).read(), open(sys.argv[2]).read()
m = re.search(r"\((\d+)x(\d+)\), frames (\d+)\.\.(\d+)", stdout)
inc = {}
for line in ann.splitlines():
    f = re.match(r"\s*([\d,]+)\s+\([^)]*\)\s+(.*)", line)
    if not f:
        continue
    n, name = int(f.group(1).replace(",", "")), f.group(2)
    # The entry under the function's own file is its whole inclusive count
    # (the others are the parts inlined from other files, counted in it).
    s = re.match(r"bench/loop.rs:loop::(stage_\w+|measured_\w+)", name)
    if s:
        inc[s.group(1)] = inc.get(s.group(1), 0) + n
if "measured_refit" in inc:
    r = re.search(r"(\d+) refits", stdout)
    print(f"measured_refit: {inc['measured_refit']:,} instructions, {inc['measured_refit'] / max(1, int(r.group(1))):,.0f} per refit")
    sys.exit(0)
px = int(m.group(1)) * int(m.group(2))
frames = int(m.group(4)) - int(m.group(3))
total = inc.get("measured_frame", 0)
print(f"instructions in measured_frame: {total:,} over {frames} frames")
staged = 0
for s in ["detect", "classify", "track", "observe", "calibrate", "measure", "report"]:
    n = inc.get("stage_" + s, 0)
    staged += n
    print(f"{s:<10}: {n / frames / px:8.3f} instr/px {n / frames:14,.0f} instr/frame {100 * n / max(1, total):5.1f} %")
o = total - staged
print(f"{'other':<10}: {o / frames / px:8.3f} instr/px {o / frames:14,.0f} instr/frame {100 * o / max(1, total):5.1f} %")
print(f"{'total':<10}: {total / frames / px:8.3f} instr/px {total / frames:14,.0f} instr/frame")
EOF
