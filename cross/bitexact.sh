#!/usr/bin/env bash
# Bit-exactness across targets: the same Y4M input must give byte-identical
# report streams from the x86_64 host binary and the aarch64, armv7 and
# static aarch64-musl binaries (run under qemu-user). The only field allowed
# to differ is `status.fps` (frames per wall-clock second), set to 0 here.
#
#   cross/bitexact.sh                  # the binaries cross/build.sh and the host tests built
#   cross/bitexact.sh BIN BIN...       # explicit binaries (ARM ones run through binfmt/qemu)
#
# Inputs: a synthetic clip made with ffmpeg's testsrc2, the built-in
# simulated plaza (sim:plaza, long enough for heights), the first frames of
# the crowded 1280x720 sim:busy (its shadows, splits and merges), and the
# first frames of PETS 2009 S2.L1 from ../shared/data (required when
# CI=true). The renderer's output is compared for every built-in scene.
set -euo pipefail
cd "$(dirname "$0")/.."
T=${CARGO_TARGET_DIR:-target}
work=$T/cross-cache/bitexact
mkdir -p "$work"
frames=${BITEXACT_FRAMES:-150}
# The plaza runs long enough for the calibration to settle and heights to be
# reported: the whole float path (calibrate, measure) is compared, not just
# detection and tracking.
sim_frames=${BITEXACT_SIM_FRAMES:-1000}

die() { echo "bitexact: FAIL: $*" >&2; exit 1; }

bins=("$@")
if [[ ${#bins[@]} -eq 0 ]]; then
    # Host: the release binary if built, else the one `cargo test` built.
    if [[ -x $T/release/stature ]]; then bins+=("$T/release/stature")
    elif [[ -x $T/debug/stature ]]; then bins+=("$T/debug/stature")
    else
        cargo build --locked --release --bin stature
        bins+=("$T/release/stature")
    fi
    for t in aarch64-unknown-linux-gnu armv7-unknown-linux-gnueabihf aarch64-unknown-linux-musl; do
        for p in release debug; do
            [[ -x $T/$t/$p/stature ]] && bins+=("$T/$t/$p/stature")
        done
    done
fi
[[ ${#bins[@]} -ge 2 ]] || die "need at least two binaries, have: ${bins[*]}"

run_bin() { # BIN ARGS... (ARM binaries through qemu-user)
    local bin=$1
    shift
    case $(file -b "$bin") in
        *aarch64*) QEMU_LD_PREFIX=/usr/aarch64-linux-gnu qemu-aarch64-static "$bin" "$@" ;;
        *"ARM, EABI5"*) QEMU_LD_PREFIX=/usr/arm-linux-gnueabihf qemu-arm-static "$bin" "$@" ;;
        *) "$bin" "$@" ;;
    esac
}

run_one() { # BIN SOURCE -> normalised JSON Lines on stdout
    run_bin "$1" run --quiet --source "$2" --report stdout --format json |
        sed -E '/"type":"status"/ s/"fps":[^,}]*/"fps":0/'
}

inputs=()
synth=$work/testsrc2-320x240.y4m
if [[ ! -s $synth ]]; then
    ffmpeg -nostdin -v error -f lavfi -i "testsrc2=size=320x240:rate=25" \
        -frames:v "$frames" -pix_fmt yuv420p -f yuv4mpegpipe -y "$synth"
fi
inputs+=("y4m:$synth")
# The simulated plaza: rendered in integer/fixed point by design, so the
# frames themselves must be identical too (people walk: detection,
# tracking and calibration all run).
inputs+=("sim:plaza?seed=3&frames=$sim_frames")
# The crowded scene at 1280x720: cross/test.sh skips the accuracy tests that
# run it under emulation, so this is where its detection and tracking are
# compared across targets.
inputs+=("sim:busy?seed=1&frames=$frames")
pets=../shared/data/pets2009-s2l1/vtest.avi
if [[ -f $pets ]]; then
    clip=$work/pets-${frames}.y4m
    [[ -s $clip ]] || ffmpeg -nostdin -v error -i "$pets" -frames:v "$frames" \
        -f yuv4mpegpipe -pix_fmt yuv420p -y "$clip"
    inputs+=("y4m:$clip")
elif [[ "${CI:-}" == "true" ]]; then
    die "../shared/data/pets2009-s2l1/vtest.avi missing in CI"
else
    echo "bitexact: ../shared/data missing: synthetic input only"
fi

# Every run first, in parallel (each is single-threaded; ARM ones are
# emulated and slow), then the comparisons.
jobs_max=${BITEXACT_JOBS:-$(nproc)}
job() { # OUT CMD... -> stdout in OUT, exit status in OUT.status
    local out=$1
    shift
    ( set +e; "$@" >"$out" 2>"$out.err"; echo $? >"$out.status" ) &
    while (( $(jobs -rp | wc -l) >= jobs_max )); do wait -n || true; done
}
out_of() { echo "$work/$1.$(echo "$2" | tr / _)"; } # NAME BIN

# The renderer itself: `stature sim` must write the same clip and the same
# ground truth bytes everywhere (it is integer/fixed point by design), so the
# simulation tests' numbers carry over from the host to every target.
render() { # BIN SCENE OUT -> digest of clip and truth
    run_bin "$1" sim --scene "$2" --seed 5 --frames 40 --out "$3.y4m" --truth "$3.json" &&
        cat "$3.y4m" "$3.json" | sha256sum | cut -c1-16 && rm -f "$3.y4m"
}
scenes=(plaza low mid high wide busy)
for scene in "${scenes[@]}"; do
    for bin in "${bins[@]}"; do
        o=$(out_of "sim-$scene" "$bin")
        job "$o.sum" render "$bin" "$scene" "$o"
    done
done
name_of() { local n; n=$(basename "${1%%\?*}" .y4m); echo "${n//:/_}"; }
for input in "${inputs[@]}"; do
    for bin in "${bins[@]}"; do
        job "$(out_of "$(name_of "$input")" "$bin").jsonl" run_one "$bin" "$input"
    done
done
wait

fail=0
for scene in "${scenes[@]}"; do
    ref="" refbin=""
    for bin in "${bins[@]}"; do
        o=$(out_of "sim-$scene" "$bin").sum
        [[ $(cat "$o.status") == 0 ]] || die "$bin sim --scene $scene failed: $(tail -3 "$o.err")"
        sum=$(cat "$o")
        if [[ -z $ref ]]; then
            ref=$sum refbin=$bin
            echo "bitexact: stature sim --scene $scene: reference $bin (clip+truth sha256 $sum)"
        elif [[ $sum == "$ref" ]]; then
            echo "bitexact: stature sim --scene $scene: $bin identical"
        else
            echo "bitexact: stature sim --scene $scene: $bin DIFFERS from $refbin ($sum vs $ref)"
            fail=1
        fi
    done
done
for input in "${inputs[@]}"; do
    ref="" refbin=""
    for bin in "${bins[@]}"; do
        out=$(out_of "$(name_of "$input")" "$bin").jsonl
        [[ $(cat "$out.status") == 0 ]] || die "$bin failed on $input: $(tail -3 "$out.err")"
        [[ -s $out ]] || die "$bin wrote no records for $input"
        if [[ -z $ref ]]; then
            ref=$out refbin=$bin
            echo "bitexact: $input: reference $bin ($(wc -l <"$out") records, $(grep -c '"type":"height"' "$out" || true) heights)"
        elif cmp -s "$ref" "$out"; then
            echo "bitexact: $input: $bin identical"
        else
            echo "bitexact: $input: $bin DIFFERS from $refbin:"
            diff "$ref" "$out" | head -10
            fail=1
        fi
    done
done
[[ $fail -eq 0 ]] || die "report streams differ across targets"
echo "bitexact: ${#bins[@]} binaries x ${#inputs[@]} inputs byte-identical (status.fps normalised)"
