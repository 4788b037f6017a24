#!/usr/bin/env bash
# The whole test suite on ARM under qemu-user, for aarch64 and armv7 (cargo
# runners in .cargo/config.toml; binfmt_misc entries from cross/install.sh
# let tests spawn the ARM binary). Tests read ../shared/data and run ffmpeg
# from the host file system as usual.
#
#   cross/test.sh                                # every test, both targets (what CI runs)
#   cross/test.sh build                          # only build both targets' test binaries
#   cross/test.sh run                            # only run what `build` built
#   cross/test.sh aarch64 [CARGO TEST ARGS...]   # plain cargo test for one target
#   cross/test.sh armv7 [CARGO TEST ARGS...]
#
# Release profile with the `v4l2` feature, as cross/build.sh builds: the
# test build reuses every dependency, and the `stature` binary the
# integration tests spawn is the one build.sh ships (built once, here or
# there, whichever runs first).
#
# Every test runs on both targets except these:
#   serial_sink_delivers_and_survives_a_stuck_reader (tests/sinks.rs):
#     qemu-user does not translate the TCGETS2 ioctl that serialport uses
#     on the pseudo-terminal ("Not a typewriter"). cross/vm-test.sh runs
#     this test binary, aarch64 and armv7, on a real arm64 kernel instead.
#   the end-to-end accuracy scores (suite: live_accuracy::, detect_sim::,
#     classify_eval::): they are about 60 % of the suite's time and, under
#     emulation, the long pole of CI. They measure the algorithm, not the
#     target: the integer pipeline is bit-exact across targets, and
#     cross/bitexact.sh checks that on a sample of the same inputs
#     (byte-identical report streams, heights included, for 1000 frames of
#     sim:plaza and the first frames of sim:busy and of the PETS clip;
#     the other sim scenes only as rendered clips),
#     so the host's scores hold on ARM. The renderer's own geometry
#     checks (suite: sim_geometry::, about 230 emulated CPU s on the two
#     targets) are left out for the same reason: bitexact.sh compares
#     every scene's rendered clip and truth byte for byte. Everything
#     target-specific still runs: detect_pets:: (the fast path against the
#     scalar path and the float reference on real video), the golden
#     features, allocation counts, soak, CLI, faults, sinks, MQTT.
#     CROSS_TEST_FULL=1 runs these too.
#
# How the run fits CI's time: one cargo invocation builds both targets'
# tests (one job queue for both), then the test binaries of both targets
# run side by side (CROSS_TEST_JOBS at once, longest first), each with
# its own log, so a long test in one binary never leaves a core idle while
# the other target waits. Per-binary wall and CPU seconds are printed;
# bench/RESULTS.md ("ARM builds") has the measured numbers.
set -euo pipefail
cd "$(dirname "$0")/.."
target_dir=${CARGO_TARGET_DIR:-target}

triple_of() {
    case $1 in
        aarch64) echo aarch64-unknown-linux-gnu ;;
        armv7) echo armv7-unknown-linux-gnueabihf ;;
        *) echo "cross/test.sh: unknown arch $1 (aarch64 or armv7)" >&2; exit 2 ;;
    esac
}

phase=${1:-all}
if [[ $phase != all && $phase != build && $phase != run ]]; then
    triple=$(triple_of "$1")
    shift
    echo "cross/test.sh: cargo test --release --features v4l2 --target $triple $*"
    exec cargo test --release --locked --features v4l2 --target "$triple" "$@"
fi

# The one test qemu-user cannot run, and the accuracy scores bitexact.sh
# carries over (see above).
qemu_skips=(--skip serial_sink_delivers_and_survives_a_stuck_reader)
if [[ ${CROSS_TEST_FULL:-0} != 1 ]]; then
    qemu_skips+=(--skip live_accuracy:: --skip detect_sim:: --skip classify_eval:: --skip sim_geometry::)
fi
# soak: the same warm-up and checks as the host's 20,000 frames, a shorter tail.
export SOAK_FRAMES=${SOAK_FRAMES:-2000}
# ...and its RSS is qemu's, translated-code cache included (tests/soak.rs):
# allocations stay at exactly 0, the RSS bound is looser than the host's 512 KiB.
export SOAK_RSS_SLACK_KIB=${SOAK_RSS_SLACK_KIB:-8192}
# The two longest sweeps, shortened the same way (about 30x their native
# time here; what a target could change shows on the first runs as well):
# the calibration's random cameras (f64 and libm: 4 of the host's 12, the
# same 4) and the SIGKILL-during-state-writes runs (each waits for its
# emulated start-up and first state write; the rename is the host
# kernel's under qemu-user: 6 of 20).
export CALIBRATE_TEST_CAMERAS=${CALIBRATE_TEST_CAMERAS:-4}
export FAULT_KILL_RUNS=${FAULT_KILL_RUNS:-6}
jobs_max=${CROSS_TEST_JOBS:-$(($(nproc) + 1))}
threads=${CROSS_TEST_THREADS:-2}

# --- build both targets' test binaries in one cargo run.
triples=(aarch64-unknown-linux-gnu armv7-unknown-linux-gnueabihf)
list=$target_dir/cross-cache/test-binaries
mkdir -p "$(dirname "$list")"
if [[ $phase != run ]]; then
t0=$(date +%s)
cargo test --release --locked --features v4l2 "${triples[@]/#/--target=}" --no-run \
    --message-format=json-render-diagnostics |
    python3 -c '
import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("profile", {}).get("test") and m.get("executable"):
        t = m["target"]
        # The lib and the binary are both "stature": its unit tests get the suffix -bin.
        name = t["name"] + ("-bin" if t["kind"] == ["bin"] else "")
        triple = next(p for p in m["executable"].split("/") if p.endswith(("-gnu", "-gnueabihf")))
        print(triple, name, m["executable"])
' >"$list"
echo "cross/test.sh: test binaries built in $(($(date +%s) - t0)) s:"
sed 's/^/  /' "$list"
fi
[[ $phase != build ]] || exit 0
[[ -s $list ]] || { echo "cross/test.sh: no test binaries listed in $list: run cross/test.sh build" >&2; exit 1; }

# --- run them, longest first (measured order; armv7 is the slower target),
# CROSS_TEST_JOBS at once.
order() { # NAME -> rank (lower runs first)
    case $1 in
        suite) echo 0 ;; soak) echo 1 ;; stature) echo 2 ;; alloc_free) echo 3 ;;
        *) echo 4 ;;
    esac
}
logs=$target_dir/cross-cache/test-logs
rm -rf "$logs"
mkdir -p "$logs"
runner_of() {
    case $1 in
        aarch64-*) echo "env QEMU_LD_PREFIX=/usr/aarch64-linux-gnu qemu-aarch64-static" ;;
        armv7-*) echo "env QEMU_LD_PREFIX=/usr/arm-linux-gnueabihf qemu-arm-static" ;;
    esac
}
run_one() { # TRIPLE NAME EXE
    local log=$logs/$1.$2.log
    local rc=0 n=$threads
    # The binaries that count the whole process's allocations run their one
    # test on the harness's main thread: with more threads the harness
    # itself allocates while the test runs (its "has been running for over
    # 60 seconds" notice), which a slow emulated run reaches.
    case $2 in alloc_free | soak) n=1 ;; esac
    # shellcheck disable=SC2046
    /usr/bin/time -f "%e %U %S" -o "$log.time" \
        $(runner_of "$1") "$3" --test-threads="$n" "${qemu_skips[@]}" >"$log" 2>&1 || rc=$?
    read -r wall user sys < <(tail -1 "$log.time")
    printf 'cross/test.sh: %-32s %-11s %s in %4.0f s wall, %4.0f s CPU\n' "$1" "$2" \
        "$([[ $rc -eq 0 ]] && echo ok || echo "FAILED ($rc)")" "$wall" "$(awk "BEGIN {print $user + $sys}")"
    echo "$rc" >"$log.rc"
}
t1=$(date +%s)
while read -r rank triple name exe; do
    run_one "$triple" "$name" "$exe" &
    while (($(jobs -rp | wc -l) >= jobs_max)); do wait -n || true; done
done < <(while read -r triple name exe; do
    echo "$(order "$name") $triple $name $exe"
done <"$list" | sort -k1,1n -k2,2r)
wait

failed=0
for rc in "$logs"/*.rc; do
    if [[ $(cat "$rc") != 0 ]]; then
        failed=1
        log=${rc%.rc}
        echo "=== $(basename "$log" .log) failed; its log:"
        grep -E "^test .*FAILED|panicked|^failures:|test result" "$log" | head -40
        echo "(full log: $log)"
    fi
done
summary=$(grep -h "^test result" "$logs"/*.log | awk '{p += $4; f += $6; i += $8} END {print p " passed, " f " failed, " i " ignored"}')
echo "cross/test.sh: $summary; emulated runs took $(($(date +%s) - t1)) s wall"
[[ $failed -eq 0 ]] || { echo "cross/test.sh: FAIL" >&2; exit 1; }
