#!/usr/bin/env python3
"""Questions about the records cross/deploy-test.sh's workstation received.

usage: deploy_check.py UDP_JSONL QUERY [ARGS...]

  count TYPE N              exit 0 when at least N records of TYPE arrived
  n TYPE                    print how many records of TYPE arrived
  hello-mode W H FORMAT     exit 0 when the last hello is W x H in FORMAT
  last TYPE                 print the last record of TYPE (shortened)
  after-last-hello STATE    exit 0 when a status after the last hello says source STATE
  after-reconnecting STATE  ... and a later one says STATE
  summary                   print counts per type and per source state

Lines that are not JSON records count as failures of `summary` (a datagram
split or merged on the way would show up here).
"""
import json
import sys

path, query, args = sys.argv[1], sys.argv[2], sys.argv[3:]
records, bad = [], []
with open(path, errors="replace") as f:
    for line in f:
        line = line.strip()
        if not line:
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            bad.append(line)


def of(kind):
    return [r for r in records if r.get("type") == kind]


def since_last_hello():
    last = max((i for i, r in enumerate(records) if r.get("type") == "hello"), default=None)
    return [] if last is None else records[last + 1 :]


def states(rs):
    return [r.get("source") for r in rs if r.get("type") == "status"]


if query == "count":
    sys.exit(0 if len(of(args[0])) >= int(args[1]) else 1)
elif query == "n":
    print(len(of(args[0])))
elif query == "hello-mode":
    h = of("hello")
    ok = bool(h) and (h[-1].get("width"), h[-1].get("height")) == (int(args[0]), int(args[1]))
    sys.exit(0 if ok and args[2] in h[-1].get("source", "") else 1)
elif query == "last":
    rs = of(args[0])
    print(json.dumps(rs[-1], separators=(",", ":"))[:160] if rs else "none")
elif query == "after-last-hello":
    sys.exit(0 if args[0] in states(since_last_hello()) else 1)
elif query == "after-reconnecting":
    s = states(since_last_hello())
    i = s.index("reconnecting") if "reconnecting" in s else None
    sys.exit(0 if i is not None and args[0] in s[i + 1 :] else 1)
elif query == "summary":
    counts = {}
    for r in records:
        counts[r.get("type")] = counts.get(r.get("type"), 0) + 1
    seen = []
    for s in states(records):
        if not seen or seen[-1] != s:
            seen.append(s)
    print(f"deploy-test: {len(records)} records on the workstation {counts}; source states in order: {' -> '.join(seen)}")
    if bad:
        print(f"deploy-test: {len(bad)} lines are not JSON records, e.g. {bad[0][:80]!r}")
        sys.exit(1)
else:
    sys.exit(f"deploy_check.py: unknown query {query}")
