#!/usr/bin/env bash
# Runs every cargo-fuzz target for a bounded time from the committed seed
# corpus. Crashes are saved under fuzz/artifacts/ and fail the run; once
# fixed, copy the input to fuzz/regressions/<target>/: tests/suite/fuzz_corpus.rs
# replays it (and the seed corpus) through the same check on every test run.
#   fuzz/run.sh [SECONDS_PER_TARGET]   (default 60; CI runs 30)
#
# Build: cargo-fuzz's default profile (release with debug assertions and
# overflow checks: an integer overflow in a parser is a crash) and no
# sanitizer: the fuzzed code is safe Rust (#![deny(unsafe_code)] everywhere
# but the counting allocator and one sigaction query in src/main.rs, which
# is not fuzzed), so AddressSanitizer would find nothing a panic does not,
# at twice the build and run time. Unbounded allocation is
# caught by -malloc_limit_mb. -seed=1: the same inputs on every run.
set -euo pipefail
cd "$(dirname "$0")"
secs=${1:-${FUZZ_SECONDS:-60}}
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
targets=$(cargo +nightly fuzz list)
cargo +nightly fuzz build -s none
for t in $targets; do
  # Work on a scratch copy: new inputs found in CI are not committed.
  work=$(mktemp -d)
  cp -r "corpus/$t/." "$work/"
  echo "fuzz $t for ${secs}s"
  status=0
  cargo +nightly fuzz run -s none "$t" "$work" -- -max_total_time="$secs" -seed=1 \
    -rss_limit_mb=2048 -malloc_limit_mb=512 -print_final_stats=1 >"$work.log" 2>&1 || status=$?
  grep -E 'stat::number_of_executed_units|stat::new_units_added' "$work.log" || true
  if [ "$status" -ne 0 ] || [ -n "$(ls "artifacts/$t" 2>/dev/null)" ]; then
    tail -40 "$work.log"
    echo "fuzz target $t failed (exit $status); crash inputs, if any: fuzz/artifacts/$t" >&2
    exit 1
  fi
  rm -rf "$work" "$work.log"
done
