#!/usr/bin/env python3
"""How much of the hip girth's error is its level: the avatar's girth at the truth's
hip level beside its girth at its own.

For each subject of a synthetic set, measures the true body (`SUBJECT.truth/mesh.obj`)
and the station's avatar (`FITS/SUBJECT/avatar.obj`, from `fitstation replay REC --out
FITS/SUBJECT`) with `fitstation measure --json` (shared/spec/measurements.md: the hip is
the torso girth where the torso reaches furthest back between the crotch and the waist)
and prints per subject:

  err:        the avatar's hip girth minus the truth's (mm), each at its own level;
  levels:     the truth's and the avatar's hip level (m) and each as a share of its own
              crotch-to-waist span;
  at truth:   the avatar's torso girth at the truth's hip level minus the truth's hip
              girth (mm): the error the section alone makes;
  back flat:  how far behind the truth's back at the avatar's level its furthest point
              lies (mm): under a pixel of the side camera (3-4 mm at 2.6 m) the level
              cannot be seen.

then the mean absolute value of `err` and of `at truth`.

Usage: python3 tools/hip_level.py SET_DIR FITS_DIR [FITSTATION_BINARY]
(numpy; the binary defaults to target/release/fitstation)
"""
import json
import os
import subprocess
import sys

import numpy as np


def measure(binary, mesh):
    out = subprocess.run([binary, "measure", "--json", mesh], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr.strip())
    return json.loads(out.stdout)


def profile(m):
    """(height m, back z m, girth mm) rows of the torso profile."""
    return np.array([[p["height_m"], p["back_z_m"], p["girth_mm"]] for p in m["torso_profile"]])


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    set_dir, fits = sys.argv[1], sys.argv[2]
    binary = sys.argv[3] if len(sys.argv) > 3 else "target/release/fitstation"
    errs, at_truth = [], []
    for name in sorted(os.listdir(fits)):
        truth_mesh = os.path.join(set_dir, name + ".truth", "mesh.obj")
        avatar = os.path.join(fits, name, "avatar.obj")
        if not (os.path.exists(truth_mesh) and os.path.exists(avatar)):
            continue
        try:
            t, a = measure(binary, truth_mesh), measure(binary, avatar)
        except (RuntimeError, json.JSONDecodeError) as e:
            print(f"{name}: not measured ({e})")
            continue
        tl, al = t["levels_m"], a["levels_m"]
        if "hip_m" not in tl or "hip_m" not in al:
            print(f"{name}: no hip level")
            continue
        tp, ap = profile(t), profile(a)
        hip_t = t["measurements_mm"]["hip_girth"]
        err = a["measurements_mm"]["hip_girth"] - hip_t
        same = np.interp(tl["hip_m"], ap[:, 0], ap[:, 2]) - hip_t
        zone = tp[(tp[:, 0] >= tl["crotch_m"]) & (tp[:, 0] <= tl["waist_m"])]
        flat = (np.interp(al["hip_m"], tp[:, 0], tp[:, 1]) - zone[:, 1].min()) * 1000

        def share(levels):
            span = levels["waist_m"] - levels["crotch_m"]
            return (levels["hip_m"] - levels["crotch_m"]) / span if span > 0 else float("nan")

        print(
            f"{name}  err {err:+6.1f}  levels truth {tl['hip_m']:.3f} ({share(tl):.2f}) "
            f"avatar {al['hip_m']:.3f} ({share(al):.2f})  at truth {same:+6.1f}  "
            f"back flat {flat:4.1f}"
        )
        errs.append(err)
        at_truth.append(same)
    if errs:
        print(
            f"{len(errs)} subjects: MAE at own level {np.mean(np.abs(errs)):.1f} mm, "
            f"at the truth's level {np.mean(np.abs(at_truth)):.1f} mm"
        )


if __name__ == "__main__":
    main()
