#!/usr/bin/env python3
"""Checks what cross/vm-test.sh's guest produced (run by that script).

usage: vm_check.py OUT_DIR FRAMES

OUT_DIR holds the virtio-serial captures: reports.jsonl (part 1 records),
stderr.log (stature's log), marks.log (the guest script's milestones) and
udp.jsonl (part 2 records received over UDP by the deployed service).
"""
import json
import sys
from pathlib import Path

out = Path(sys.argv[1])
frames = int(sys.argv[2])
failures = []


def check(cond, what):
    print(("  ok   " if cond else "  FAIL ") + what)
    if not cond:
        failures.append(what)


def records(path):
    recs = []
    for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        try:
            recs.append(json.loads(line))
        except json.JSONDecodeError:
            failures.append(f"{path.name}:{n} is not a JSON record: {line[:80]!r}")
    return recs


marks = (out / "marks.log").read_text(errors="replace")
log = (out / "stderr.log").read_text(errors="replace")

print("part 1: capture from vivid with an unplug/replug")
recs = records(out / "reports.jsonl")
check(bool(recs), f"{len(recs)} records from the guest")
hello = recs[0] if recs else {}
check(hello.get("type") == "hello", "first record is hello")
check(
    (hello.get("width"), hello.get("height")) == (640, 480),
    f"negotiated size 640x480 (hello says {hello.get('width')}x{hello.get('height')})",
)
check(
    "YUYV" in hello.get("source", "") and "vivid" in hello.get("source", "").lower(),
    f"negotiated format YUYV on vivid (hello source {hello.get('source')!r})",
)
check("streaming 640x480 YUYV" in log, "log shows the negotiated mode")
status = [r for r in recs if r.get("type") == "status"]
states = [s["source"] for s in status]
check(len(status) >= 5, f"{len(status)} status records")
first_lost = next((i for i, s in enumerate(states) if s != "streaming"), None)
check(
    first_lost is not None and states[first_lost] == "reconnecting",
    "a status record reports the source reconnecting after the unplug",
)
before = status[: first_lost if first_lost is not None else len(status)]
allocs_before = [s["allocations"] for s in before]
check(
    len(before) >= 2 and all(a == 0 for a in allocs_before),
    f"steady state before the unplug allocates nothing (allocations {allocs_before})",
)
resumed = (
    [i for i, s in enumerate(states) if i > first_lost and s == "streaming"]
    if first_lost is not None
    else []
)
check(len(resumed) >= 2, f"{len(resumed)} streaming status records after the replug")
after = [status[i]["allocations"] for i in resumed]
# Reconnecting allocates (device paths, the new stream's buffer table); once
# streaming again the count must stand still.
check(
    len(after) >= 2 and len(set(after[1:])) == 1,
    f"steady state after the reconnect allocates nothing more (allocations {after})",
)
check("reconnected on /dev/video" in log, "log shows the reconnect")
bye = recs[-1] if recs else {}
check(
    bye.get("type") == "bye" and bye.get("frames") == frames,
    f"bye after {frames} frames (last record {bye})",
)
frames_seq = [s["frames"] for s in status]
check(frames_seq == sorted(frames_seq), "frame counts never go back")
check("stature exit 0" in marks, "stature exited 0")

print("part 1b: the armv7 build on the same device (32-bit compat ioctls)")
arm = records(out / "armv7.jsonl")
ahello = next((r for r in arm if r.get("type") == "hello"), {})
check(
    (ahello.get("width"), ahello.get("height")) == (640, 480) and "YUYV" in ahello.get("source", ""),
    f"armv7 negotiated 640x480 YUYV (hello {ahello})",
)
abye = next((r for r in arm if r.get("type") == "bye"), {})
check(abye.get("frames") == 50, f"armv7 captured 50 frames (bye {abye})")
astatus = [r["allocations"] for r in arm if r.get("type") == "status"]
check(bool(astatus) and all(a == 0 for a in astatus), f"armv7 steady state allocates nothing ({astatus})")
check("armv7 exit 0" in marks, "armv7 build exited 0")

if "serial test skipped" in marks:
    print("  skip serial-sink test (no aarch64 test binary)")
else:
    check("serial test exit 0" in marks,
          "serial sink test (aarch64 build) passes over a pseudo-terminal on the arm64 kernel")
    check("serial test armv7 exit 0" in marks,
          "serial sink test (armv7 build) passes over a pseudo-terminal on the arm64 kernel (compat)")
    check(log.count("test result: ok. 1 passed") == 2, "both serial test runs report 1 passed")

print("part 2: deployed with board/install.sh, run as the service user")
check("install exit 0" in marks, "board/install.sh succeeded")
check("uid=" in marks and "video" in marks.split("user:")[-1].split("\n")[0],
      "user stature exists and is in group video")
udp = records(out / "udp.jsonl")
uhello = next((r for r in udp if r.get("type") == "hello"), {})
check(
    (uhello.get("width"), uhello.get("height")) == (1280, 720),
    f"rpi4 profile's 1280x720 negotiated (hello {uhello.get('width')}x{uhello.get('height')})",
)
ubye = next((r for r in udp if r.get("type") == "bye"), {})
check(ubye.get("frames") == 60, f"60 frames reported over UDP (bye {ubye})")
check("board profile rpi4-aarch64" in log, "log names the board profile")
check("service run exit 0" in marks, "service command exited 0")
# Peak RSS of the 1280x720 service run (VmHWM polled in the guest).
hwm = [l.split()[-2] for l in marks.splitlines() if "peak RSS VmHWM" in l and l.endswith("kB")]
check(bool(hwm), f"peak RSS measured in the guest ({hwm} kB)")
if hwm:
    kib = int(hwm[-1])
    print(f"  peak RSS at 1280x720 YUYV on aarch64 (vivid, 60 frames): {kib} KiB = {kib / 1024:.1f} MiB")
    check(kib <= 32 * 1024, "peak RSS within the 32 MiB target at 1280x720")

if failures:
    print(f"vm-test: FAIL: {len(failures)} check(s) failed", file=sys.stderr)
    for f in failures:
        print("  - " + f, file=sys.stderr)
    sys.exit(1)
print("vm-test: all checks passed")
