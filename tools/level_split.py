#!/usr/bin/env python3
"""How much of a torso girth's error is its level: each girth at the avatar's own level
against the avatar's girth at the truth's level.

For every subject of a synthetic set, reads `fitstation measure --json` of the station's
avatar and of the true body, and prints per torso girth (chest, waist, hip):

  own level:   the avatar's reported girth minus the truth's (what `eval` scores);
  truth level: the avatar's torso girth at the height where the spec put the truth's
               level, minus the truth's girth (what the fit got wrong in the section
               itself, the level aside), from the avatar's torso profile (2 mm steps);
  dlev:        the avatar's level minus the truth's, mm.

Then per set the MAE / bias / worst of both, and for the hip the truth's own plateau:
the span of heights whose back lies within 1 mm of its furthest point between the crotch
and waist levels, and the range of the truth's girths over it (the spec's hip level
is the furthest point back: where the back is that flat, a millimetre decides it), and the
hip each subject would get over the levels it may be at, the avatar's girths weighted by
`exp(-(z - z_back) / r)` as the station weights them (`station::uncertainty`,
`hip_girth_over_levels_mm`), with the weights taken from the avatar's own back and from the
truth's (as if the side view showed the person's back exactly), r 2, 3 and 5 mm.

Inputs: the set (`synth-set` output) and a folder of `SUBJECT.m.json` files, each the
avatar's `fitstation measure AVATAR --json`; the truth's is read from
`SUBJECT.truth/m.json`, made on first use with the `fitstation` binary given.

Usage: python3 tools/level_split.py FITSTATION SET_DIR MEASURES_DIR
   e.g. for s in out/judge_ansur/subject_??; do n=$(basename $s);
          target/release/fitstation replay $s --out out/fits/$n;
          target/release/fitstation measure out/fits/$n/avatar.obj --json > out/fits/$n.m.json; done
        python3 tools/level_split.py target/release/fitstation out/judge_ansur out/fits
"""
import glob
import json
import math
import os
import subprocess
import sys

LEVELS = [("chest_girth", "chest_m"), ("waist_girth", "waist_m"), ("hip_girth", "hip_m")]


def girth_at(profile, y):
    return min(profile, key=lambda p: abs(p["height_m"] - y))["girth_mm"]


def truth_measures(fitstation, set_dir, subject):
    path = os.path.join(set_dir, f"{subject}.truth", "m.json")
    if not os.path.exists(path):
        mesh = os.path.join(set_dir, f"{subject}.truth", "mesh.obj")
        out = subprocess.run([fitstation, "measure", mesh, "--json"], check=True,
                             capture_output=True, text=True).stdout
        with open(path, "w") as f:
            f.write(out)
    with open(path) as f:
        return json.load(f)


def plateau(t, tol_m=0.001):
    lv = t["levels_m"]
    band = [p for p in t["torso_profile"] if lv["crotch_m"] <= p["height_m"] <= lv["waist_m"]]
    if not band:
        return None
    back = min(p["back_z_m"] for p in band)
    flat = [p for p in band if p["back_z_m"] <= back + tol_m]
    hs = [p["height_m"] for p in flat]
    gs = [p["girth_mm"] for p in flat]
    return 1000 * (max(hs) - min(hs)), max(gs) - min(gs)


def hip_over_levels(avatar, weights_from, resolution_m):
    """The avatar's torso girths between the crotch and waist levels of `weights_from`,
    weighted by how near that body's back at each height is to its furthest point."""
    lv = weights_from["levels_m"]
    band = [p for p in weights_from["torso_profile"] if lv["crotch_m"] <= p["height_m"] <= lv["waist_m"]]
    if not band:
        return None
    back = min(p["back_z_m"] for p in band)
    sw = sg = 0.0
    for p in band:
        w = math.exp(-(p["back_z_m"] - back) / resolution_m)
        sw += w
        sg += w * girth_at(avatar["torso_profile"], p["height_m"])
    return sg / sw


def summary(v):
    return f"{sum(map(abs, v)) / len(v):5.1f} / {sum(v) / len(v):+5.1f} / {max(v, key=abs):+4.0f}"


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    fitstation, set_dir, measures = sys.argv[1:]
    errs = {g: ([], []) for g, _ in LEVELS}
    spans = []
    weighted = {}
    for mf in sorted(glob.glob(os.path.join(measures, "subject_*.m.json"))):
        subject = os.path.basename(mf)[: -len(".m.json")]
        with open(mf) as f:
            try:
                a = json.load(f)
            except json.JSONDecodeError:
                print(f"{subject}: no avatar measures")
                continue
        t = truth_measures(fitstation, set_dir, subject)
        line = subject
        for g, lev in LEVELS:
            own = a["measurements_mm"][g] - t["measurements_mm"][g]
            at_truth = girth_at(a["torso_profile"], t["levels_m"][lev]) - t["measurements_mm"][g]
            dlev = 1000 * (a["levels_m"][lev] - t["levels_m"][lev])
            errs[g][0].append(own)
            errs[g][1].append(at_truth)
            line += f" | {g[:5]} {own:+6.1f} truth level {at_truth:+6.1f} dlev {dlev:+4.0f}"
        p = plateau(t)
        if p:
            spans.append(p)
        for r in (0.002, 0.003, 0.005):
            for name, body in (("avatar's back", a), ("truth's back", t)):
                h = hip_over_levels(a, body, r)
                if h is not None:
                    weighted.setdefault((name, r), []).append(h - t["measurements_mm"]["hip_girth"])
        print(line)
    if not spans:
        return
    print("MAE / bias / worst mm        own level              truth level")
    for g, (own, at_truth) in errs.items():
        print(f"{g:16s} {summary(own):>24s} {summary(at_truth):>24s}")
    hs = sorted(s for s, _ in spans)
    gs = sorted(g for _, g in spans)
    print(f"truth's hip plateau (back within 1 mm): height span median {hs[len(hs) // 2]:.0f} mm "
          f"(max {hs[-1]:.0f}), girth range over it median {gs[len(gs) // 2]:.0f} mm (max {gs[-1]:.0f})")
    for (name, r), v in sorted(weighted.items()):
        print(f"hip over the levels, weights from the {name:14s} r {1000 * r:.0f} mm: {summary(v)}")


if __name__ == "__main__":
    main()
