#!/usr/bin/env python3
"""Summarise `live_eval` runs: the figures bench/RESULTS.md quotes for many runs.

    cargo run --release --example live_eval -- --scene all --seeds 1,2,3,4,5,6,7 > runs.txt
    python3 bench/live_summary.py runs.txt [more.txt ...]

Per file: |f| error median, mean and p90, runs within 3 % and 10 %; |tilt|
and |roll| median and p90 (degrees) and runs within 1 deg; prior-mode camera
height |error| median and mean; the median over runs of each run's height
|error| median and scale-free median; recall summed over runs (and over the
people seen alone, when the output has it); runs with no height; dog or car
heights. A run whose pipeline gave no estimate counts as
missing in f, tilt and roll (and is listed).
"""
import re
import statistics
import sys

HEAD = re.compile(r"^== (\w+):(\d+) .*true f\s+([\d.]+) tilt\s+([-\d.]+) roll\s+([-\d.]+) hc\s+([\d.]+)")
EST = re.compile(r"pipeline estimate: f ([\d.]+) tilt ([-\d.]+) roll ([-\d.]+) hc ([\d.]+)")
FIN = re.compile(
    r"pipeline final heights: (\d+) records of (\d+) people; \|err\| median ([\d.NaN]+) p90 ([\d.NaN]+) m, "
    r"mean signed ([-+\d.NaN]+) m; scale-free median ([\d.NaN]+) p90 ([\d.NaN]+); "
    r"recall \(seen >= 3 s\) (\d+)/(\d+); dog/car heights (\d+)"
)
ALONE = re.compile(r"recall of people seen >= 3 s alone .*: (\d+)/(\d+)")
WALKING = re.compile(r"recall of people seen >= 3 s walking[^:]*: (\d+)/(\d+)")


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


def summarise(path):
    runs, cur = [], None
    for line in open(path, encoding="utf-8"):
        m = HEAD.search(line)
        if m:
            cur = dict(name=f"{m[1]}:{m[2]}", f=float(m[3]), tilt=float(m[4]), roll=float(m[5]), hc=float(m[6]))
            runs.append(cur)
            continue
        if cur is None:
            continue
        m = EST.search(line)
        if m:
            cur["est"] = tuple(float(x) for x in m.groups())
        m = FIN.search(line)
        if m:
            cur["records"] = int(m[1])
            cur["h_med"] = float(m[3])
            cur["sf_med"] = float(m[6])
            cur["measured"], cur["eligible"] = int(m[8]), int(m[9])
            cur["nonperson"] = int(m[10])
        m = ALONE.search(line)
        if m:
            cur["measured_alone"], cur["eligible_alone"] = int(m[1]), int(m[2])
        m = WALKING.search(line)
        if m:
            cur["measured_walking"], cur["eligible_walking"] = int(m[1]), int(m[2])
    est = [r for r in runs if "est" in r]
    fe = [100.0 * (r["est"][0] / r["f"] - 1.0) for r in est]
    te = [abs(r["est"][1] - r["tilt"]) for r in est]
    re_ = [abs(r["est"][2] - r["roll"]) for r in est]
    he = [100.0 * (r["est"][3] / r["hc"] - 1.0) for r in est]
    withh = [r for r in runs if r.get("records", 0) > 0]
    afe = [abs(x) for x in fe]
    print(f"{path}: {len(runs)} runs, {len(est)} with an estimate")
    print(
        f"  |f| median {statistics.median(afe):.1f} % (p90 {pct(afe, 0.9):.1f} %), mean {statistics.mean(fe):+.1f} %, "
        f"within 3 % {sum(a <= 3 for a in afe)}, within 10 % {sum(a <= 10 for a in afe)}"
    )
    print(
        f"  |tilt| median {statistics.median(te):.2f} deg (p90 {pct(te, 0.9):.2f}), within 1 deg {sum(t <= 1 for t in te)}; "
        f"|roll| median {statistics.median(re_):.2f} deg (p90 {pct(re_, 0.9):.2f}), within 1 deg {sum(t <= 1 for t in re_)}"
    )
    print(f"  camera height |err| median {statistics.median(abs(x) for x in he):.1f} %, mean {statistics.mean(he):+.1f} %")
    if withh:
        print(
            f"  heights |err| median over runs {100 * statistics.median(r['h_med'] for r in withh):.1f} cm, "
            f"scale-free {100 * statistics.median(r['sf_med'] for r in withh):.2f} %"
        )
    print(
        f"  recall {sum(r.get('measured', 0) for r in runs)}/{sum(r.get('eligible', 0) for r in runs)}, "
        f"runs without heights {len(runs) - len(withh)} {[r['name'] for r in runs if r not in withh]}, "
        f"dog/car heights {sum(r.get('nonperson', 0) for r in runs)}"
    )
    if any("eligible_alone" in r for r in runs):
        print(
            f"  recall of people seen alone {sum(r.get('measured_alone', 0) for r in runs)}/"
            f"{sum(r.get('eligible_alone', 0) for r in runs)}"
        )
    if any("eligible_walking" in r for r in runs):
        print(
            f"  recall of people seen walking {sum(r.get('measured_walking', 0) for r in runs)}/"
            f"{sum(r.get('eligible_walking', 0) for r in runs)}"
        )


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for p in sys.argv[1:]:
        summarise(p)
