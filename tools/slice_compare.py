#!/usr/bin/env python3
"""Where a fitted avatar's girths go wrong: its torso sections beside the truth's.

For each subject of a synthetic set, slices the true body (`SUBJECT.truth/mesh.obj`) and
the station's avatar (`FITS/SUBJECT/avatar.obj`, from `fitstation replay REC --out
FITS/SUBJECT`) at the truth's chest level (the largest torso girth from the armpit down
0.1 x stature, `shared/spec/measurements.md`), hip level (where the torso reaches
furthest back between the crotch and the crotch + 0.25 x stature) and waist level (the
smallest torso girth between crotch + 0.1 x stature and armpit - 0.05 x stature, as
tools/section_fullness.py), and prints per level:

  truth:  the level, the torso loop's breadth (x extent), depth (z extent) and convex hull
          perimeter (mm);
  same y: the avatar's breadth, depth and hull at the truth's level, minus the truth's
          (what the fit got wrong in the section itself), and both sections' fullness
          (hull over the ellipse of the section's own breadth and depth: with the
          extents right, a hull error is the section's shape);
  own y:  the avatar's own level (how far from the truth's) and its hull there, minus the
          truth's (what the level adds: a flat buttock leaves the hip's level open);
  back:   (hip only) how far behind its furthest point the truth's back lies at the
          avatar's level, and the avatar's at the truth's (mm): within a pixel of the side
          camera (2-3 mm) the level cannot be seen.

The torso loop is the slice's loop that straddles the body's median x (the loop's points
joined through the mesh edges they cut), the widest if several do. Approximate next to
`fitstation measure` (no bisection of the levels, a 4 mm grid): for finding where to
look, not for reporting accuracy.

Usage: python3 tools/slice_compare.py SET_DIR FITS_DIR SUBJECT [SUBJECT ...]
   e.g. python3 tools/slice_compare.py out/dev_ansur out/fits 00 03 17
(numpy and scipy)
"""
import json
import os
import sys

import numpy as np
from scipy.spatial import ConvexHull

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from measure_spec import read_obj as load_obj  # noqa: E402


def loops(verts, tris, y):
    """The closed loops of the slice at height y, as arrays of points."""
    ys = verts[:, 1]
    above = ys[tris] > y
    crossing = tris[above.any(1) & ~above.all(1)]
    parent, points = {}, {}

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for tri in crossing:
        keys = []
        for i in range(3):
            a, b = tri[i], tri[(i + 1) % 3]
            if (ys[a] > y) != (ys[b] > y):
                k = (min(a, b), max(a, b))
                if k not in points:
                    p, q = verts[a], verts[b]
                    points[k] = p + (y - p[1]) / (q[1] - p[1]) * (q - p)
                    parent[k] = k
                keys.append(k)
        if len(keys) == 2:
            ra, rb = find(keys[0]), find(keys[1])
            if ra != rb:
                parent[ra] = rb
    groups = {}
    for k, p in points.items():
        groups.setdefault(find(k), []).append(p)
    return [np.array(g) for g in groups.values() if len(g) >= 3]


def torso(verts, tris, y, cx):
    all_loops = loops(verts, tris, y)
    straddling = [g for g in all_loops if g[:, 0].min() < cx < g[:, 0].max()] or all_loops
    if not straddling:
        return None
    return max(straddling, key=lambda g: np.ptp(g[:, 0]) * np.ptp(g[:, 2]))


def section(verts, tris, y, cx):
    """(breadth mm, depth mm, hull perimeter mm, back z m) of the torso loop, or None."""
    t = torso(verts, tris, y, cx)
    if t is None or len(t) < 3:
        return None
    try:
        hull = ConvexHull(t[:, [0, 2]]).area
    except Exception:
        return None
    return np.ptp(t[:, 0]) * 1000, np.ptp(t[:, 2]) * 1000, hull * 1000, t[:, 2].min()


def scan(verts, tris, lo, hi, cx, key):
    best = None
    for y in np.arange(lo, hi, 0.004):
        s = section(verts, tris, y, cx)
        if s is not None and (best is None or key(s) < key(best[1])):
            best = (y, s)
    return best


def fullness(breadth, depth, hull):
    """Hull perimeter over the Ramanujan perimeter of the ellipse of breadth and depth."""
    a, c = breadth / 2.0, depth / 2.0
    return hull / (np.pi * (3.0 * (a + c) - np.sqrt((3.0 * a + c) * (a + 3.0 * c))))


def load_subject(set_dir, fits_dir, subject):
    """(name, truth.json, (truth vertices, triangles), (avatar vertices, triangles)) of a
    subject ("07" or "subject_07") of a synthetic set and its fits folder."""
    name = subject if subject.startswith("subject_") else f"subject_{subject}"
    truth_dir = os.path.join(set_dir, name + ".truth")
    with open(os.path.join(truth_dir, "truth.json")) as f:
        truth = json.load(f)
    return (
        name,
        truth,
        load_obj(os.path.join(truth_dir, "mesh.obj")),
        load_obj(os.path.join(fits_dir, name, "avatar.obj")),
    )


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    set_dir, fits_dir, subjects = sys.argv[1], sys.argv[2], sys.argv[3:]
    for s in subjects:
        name, truth, (vt, ft), (va, fa) = load_subject(set_dir, fits_dir, s)
        cxt, cxa = np.median(vt[:, 0]), np.median(va[:, 0])
        stature = truth["measurements_mm"]["stature"] / 1000
        lm = truth["landmarks"]
        armpit = 0.5 * (lm["left_armpit"][1] + lm["right_armpit"][1])
        crotch = lm["crotch"][1]
        print(name)
        for what, lo, hi, key in [
            ("chest", armpit - 0.1 * stature, armpit - 0.004, lambda x: -x[2]),
            ("hip", crotch + 0.01, crotch + 0.25 * stature, lambda x: x[3]),
            ("waist", crotch + 0.1 * stature, armpit - 0.05 * stature, lambda x: x[2]),
        ]:
            t = scan(vt, ft, lo, hi, cxt, key)
            a = scan(va, fa, lo, hi, cxa, key)
            if t is None or a is None:
                print(f"  {what}: no torso loop")
                continue
            (yt, (w, d, h, zt)), (ya, (_, _, ha, za)) = t, a
            same = section(va, fa, yt, cxa)
            line = f"  {what}: truth y {yt:.3f} breadth {w:.0f} depth {d:.0f} hull {h:.0f}"
            if same is not None:
                line += f" | same y: {same[0] - w:+.0f} {same[1] - d:+.0f} hull {same[2] - h:+.0f}"
                line += f" full {fullness(w, d, h):.3f} vs {fullness(*same[:3]):.3f}"
            line += f" | own y {ya - yt:+.3f}: hull {ha - h:+.0f}"
            if what == "hip":
                tb = section(vt, ft, ya, cxt)
                if tb is not None and same is not None:
                    line += f" | back: truth {1000 * (tb[3] - zt):+.1f}, avatar {1000 * (same[3] - za):+.1f}"
            print(line)


if __name__ == "__main__":
    main()
