#!/usr/bin/env python3
"""Where a fitted avatar's thigh girths go wrong: its thigh sections beside the truth's.

For each subject of a synthetic set, slices the true body (`SUBJECT.truth/mesh.obj`) and
the station's avatar (`FITS/SUBJECT/avatar.obj`, from `fitstation replay REC --out
FITS/SUBJECT`) at 1, 2, 3, 5 and 8 cm under the truth's crotch (the band the spec's thigh
girth is the largest girth of, `shared/spec/measurements.md`) and prints per thigh:

  truth:  the thigh loop's breadth (x extent), its back and front (z, mm) and its convex
          hull perimeter (mm);
  avatar: the avatar's breadth minus the truth's, its back minus the truth's (+: in front
          of the person's back, the thigh too shallow there), its front minus the truth's
          (+: ahead of it) and its hull minus the truth's.

Then over all subjects and both thighs, per height: the median and mean of each
difference, and how many thighs have their back more than 5 mm in front of the truth's.

A thigh loop is the slice's loop on that side of the body's median x, at least 6 cm wide
(a hand hanging beside the thigh is narrower), the largest if several. A sketch next to
`fitstation measure` (no bisection): for finding where to look, not for reporting accuracy.

Usage: python3 tools/thigh_slices.py SET_DIR FITS_DIR [SUBJECT ...]   (all subjects of
FITS_DIR when none are named; numpy and scipy)
   e.g. for s in out/dev_ansur/subject_??; do n=$(basename $s);
          target/release/fitstation replay $s --out out/fits/$n; done
        python3 tools/thigh_slices.py out/dev_ansur out/fits
"""
import os
import sys

import numpy as np
from scipy.spatial import ConvexHull

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from slice_compare import load_subject, loops  # noqa: E402

DEPTHS_CM = (1, 2, 3, 5, 8)
MIN_WIDTH_M = 0.06


def thighs(verts, tris, y, cx):
    """{'L': (x min, x max, z min, z max, hull), 'R': ...} of the thigh loops at y."""
    out = {}
    all_loops = loops(verts, tris, y)
    for side, on_side in (("L", lambda g: g[:, 0].mean() > cx), ("R", lambda g: g[:, 0].mean() < cx)):
        cands = [g for g in all_loops if on_side(g) and np.ptp(g[:, 0]) > MIN_WIDTH_M]
        if not cands:
            continue
        g = max(cands, key=lambda g: np.ptp(g[:, 0]) * np.ptp(g[:, 2]))
        try:
            hull = ConvexHull(g[:, [0, 2]]).area
        except Exception:
            continue
        out[side] = (g[:, 0].min(), g[:, 0].max(), g[:, 2].min(), g[:, 2].max(), hull)
    return out


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    set_dir, fits = sys.argv[1], sys.argv[2]
    subjects = sys.argv[3:] or sorted(
        d for d in os.listdir(fits) if os.path.isfile(os.path.join(fits, d, "avatar.obj"))
    )
    rows = {cm: [] for cm in DEPTHS_CM}
    for s in subjects:
        name, truth, (vt, ft), (va, fa) = load_subject(set_dir, fits, s)
        crotch = truth["landmarks"]["crotch"][1]
        cxt, cxa = np.median(vt[:, 0]), np.median(va[:, 0])
        m = truth["measurements_mm"]
        print(f"{name}: crotch {crotch:.3f} m, true thigh girths {m.get('thigh_girth_left', float('nan')):.0f} / "
              f"{m.get('thigh_girth_right', float('nan')):.0f} mm")
        for cm in DEPTHS_CM:
            y = crotch - cm / 100.0
            t_all, a_all = thighs(vt, ft, y, cxt), thighs(va, fa, y, cxa)
            for side in "LR":
                if side not in t_all or side not in a_all:
                    continue
                t, a = t_all[side], a_all[side]
                d = (
                    1000 * ((a[1] - a[0]) - (t[1] - t[0])),
                    1000 * (a[2] - t[2]),
                    1000 * (a[3] - t[3]),
                    1000 * (a[4] - t[4]),
                )
                rows[cm].append(d)
                print(f"  -{cm} cm {side}: truth breadth {1000 * (t[1] - t[0]):.0f} back {1000 * t[2]:.0f} "
                      f"front {1000 * t[3]:.0f} hull {1000 * t[4]:.0f} | avatar breadth {d[0]:+.0f} "
                      f"back {d[1]:+.0f} front {d[2]:+.0f} hull {d[3]:+.0f}")
    print()
    print("avatar minus truth, mm (median / mean) over every thigh; back +: in front of the person's")
    print(f"{'under crotch':>12} {'n':>4} {'breadth':>13} {'back':>13} {'front':>13} {'hull':>13} {'back > +5':>10}")
    for cm in DEPTHS_CM:
        r = np.array(rows[cm])
        if len(r) == 0:
            continue
        cells = " ".join(f"{np.median(r[:, k]):+6.1f}/{np.mean(r[:, k]):+6.1f}" for k in range(4))
        print(f"{cm:>9} cm {len(r):4d} {cells} {int(np.sum(r[:, 1] > 5)):>6d}")


if __name__ == "__main__":
    main()
