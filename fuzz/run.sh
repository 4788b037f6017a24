#!/usr/bin/env bash
# Runs every cargo-fuzz target for a bounded time from the committed seed
# corpus. Crashes are saved under fuzz/artifacts/ and fail the run; once
# fixed, copy the input to fuzz/regressions/<target>/: tests/suite/fuzz_corpus.rs
# replays it (and the seed corpus) through the same check on every test run.
#   fuzz/run.sh [SECONDS_PER_TARGET]   (default 60)
set -euo pipefail
cd "$(dirname "$0")"
secs=${1:-${FUZZ_SECONDS:-60}}
rustup toolchain list | grep -q nightly || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
targets=$(cargo +nightly fuzz list)
cargo +nightly fuzz build -O
for t in $targets; do
  # Work on a scratch copy: new inputs found in CI are not committed.
  work=$(mktemp -d)
  cp -r "corpus/$t/." "$work/" 2>/dev/null || true
  echo "fuzz $t for ${secs}s"
  cargo +nightly fuzz run -O "$t" "$work" -- -max_total_time="$secs" -rss_limit_mb=2048 -print_final_stats=1 2>&1 \
    | grep -E 'stat::number_of_executed_units|Done|ERROR|panicked|SUMMARY' || true
  test -z "$(ls artifacts/$t 2>/dev/null)" || { echo "fuzz target $t found a crash: fuzz/artifacts/$t" >&2; exit 1; }
  rm -rf "$work"
done
