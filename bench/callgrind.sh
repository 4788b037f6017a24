#!/usr/bin/env bash
# Instruction count of a bench binary under callgrind (the whole run,
# start-up included; bench/loop_callgrind.sh gives the loop's instructions
# per pixel and stage).
#   bench/callgrind.sh BENCH [bench args...]
# Builds the bench in release (no target-cpu=native: valgrind cannot run
# AVX-512 and the product targets ARM), runs it under callgrind and prints
# the total instruction count and, per function, the top entries.
set -euo pipefail
cd "$(dirname "$0")/.."
bench=${1:?usage: bench/callgrind.sh BENCH [args]}; shift
command -v valgrind >/dev/null || { echo "valgrind not installed (apt-get install valgrind)" >&2; exit 2; }
bin=$(cargo bench --bench "$bench" --no-run --message-format=json 2>/dev/null | python3 -c '
import json,sys
for line in sys.stdin:
    m=json.loads(line)
    if m.get("reason")=="compiler-artifact" and m.get("executable") and m["target"]["name"]==sys.argv[1]:
        print(m["executable"])' "$bench" | tail -1)
out=$(mktemp -d)
valgrind --tool=callgrind --callgrind-out-file="$out/cg.out" "$bin" "$@" > "$out/stdout" 2> "$out/stderr"
cat "$out/stdout"
total=$(grep -E '^(summary|totals):' "$out/cg.out" | head -1 | awk '{print $2}')
echo "instructions: $total"
callgrind_annotate "$out/cg.out" 2>/dev/null | sed -n '/Ir/,$p' | head -25
