#!/usr/bin/env python3
"""Did a change move the girths, or did the draw? Two `fitstation eval --json` runs of the
same sets (the same recordings, before and after a change) compared subject by subject.

On 24 subjects a girth's MAE moves by several millimetres from one draw of subjects to
the next (`eval` prints each MAE's 90 % interval), so two builds judged on different draws
cannot be told apart by a millimetre or two. On the same recordings the two builds' errors
are paired: per set and girth this prints both MAEs, their difference (after - before) and
the 90 % interval of that difference over draws of the set's subjects with replacement
(a paired percentile bootstrap, 4000 draws, seeded), the subjects whose error moved most,
and the summed MAE over the torso girths and thighs. An interval that holds 0 is a change
the draw could have made.

Usage: python3 tools/paired.py BEFORE.json AFTER.json [SET ...]
   e.g. target/release/fitstation eval --json --set ansur=out/dev_ansur > before.json
        (change, rebuild)
        target/release/fitstation eval --json --set ansur=out/dev_ansur > after.json
        python3 tools/paired.py before.json after.json
"""
import json
import random
import sys

GIRTHS = ["chest_girth", "waist_girth", "hip_girth", "thigh_girth_left", "thigh_girth_right"]
DRAWS = 4000
SEED = 20261129


def errors(run, set_name):
    out = {}
    for row in run["sets"][set_name]["rows"]:
        for m in row["measurements"]:
            if m.get("error_mm") is not None:
                out[(row["subject"], m["name"])] = m["error_mm"]
    return out


def interval(pairs, rng):
    n = len(pairs)
    diffs = []
    for _ in range(DRAWS):
        s = 0.0
        for _ in range(n):
            a, b = pairs[rng.randrange(n)]
            s += abs(b) - abs(a)
        diffs.append(s / n)
    diffs.sort()
    return diffs[int(0.05 * (DRAWS - 1))], diffs[int(0.95 * (DRAWS - 1))]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        before = json.load(f)
    with open(sys.argv[2]) as f:
        after = json.load(f)
    sets = sys.argv[3:] or [s for s in before["sets"] if s in after["sets"]]
    rng = random.Random(SEED)
    print(f"{'set':12s} {'girth':18s} {'n':>3s} {'MAE before':>10s} {'after':>6s} {'change':>7s} "
          f"{'90 % interval':>15s}  most moved (after - before |error|)")
    for s in sets:
        eb, ea = errors(before, s), errors(after, s)
        total = []
        for g in GIRTHS:
            keys = sorted(k for k in eb if k[1] == g and k in ea)
            if not keys:
                continue
            pairs = [(eb[k], ea[k]) for k in keys]
            total.append((keys, pairs))
            n = len(pairs)
            mb = sum(abs(a) for a, _ in pairs) / n
            ma = sum(abs(b) for _, b in pairs) / n
            lo, hi = interval(pairs, rng)
            moved = sorted(keys, key=lambda k: abs(abs(ea[k]) - abs(eb[k])), reverse=True)[:2]
            most = ", ".join(f"{k[0]} {eb[k]:+.0f}->{ea[k]:+.0f}" for k in moved)
            print(f"{s:12s} {g:18s} {n:3d} {mb:10.1f} {ma:6.1f} {ma - mb:+7.1f} "
                  f"{lo:+7.1f}..{hi:+.1f}  {most}")
        if total:
            # Summed over girths: per subject the sum of its girths' |errors|.
            by_subject = {}
            for keys, pairs in total:
                for k, (a, b) in zip(keys, pairs):
                    acc = by_subject.setdefault(k[0], [0.0, 0.0])
                    acc[0] += abs(a)
                    acc[1] += abs(b)
            pairs = list(by_subject.values())
            n = len(pairs)
            mb = sum(a for a, _ in pairs) / n
            ma = sum(b for _, b in pairs) / n
            lo, hi = interval(pairs, rng)
            print(f"{s:12s} {'all five girths':18s} {n:3d} {mb:10.1f} {ma:6.1f} {ma - mb:+7.1f} "
                  f"{lo:+7.1f}..{hi:+.1f}")


if __name__ == "__main__":
    main()
