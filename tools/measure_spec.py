#!/usr/bin/env python3
"""A second, independent implementation of shared/spec/measurements.md (numpy only).

Usage: python3 tools/measure_spec.py MESH.obj
Prints JSON: {"measurements_mm": {...}, "levels_m": {...}}.

Written from the spec's text, not from src/measure: slices cut every triangle with
numpy, loops are the connected components of the cut segments (segments that share a
crossed mesh edge), girths are convex hull perimeters in (x, z). The grids follow the
same anchoring choices the spec leaves open as the station's (torso bands: crotch +
k 2 mm, then the armpit; thigh band: from its top down; a band's ends count as grid
points), so the two should agree to well under 1 mm. tests/suite/measure_python.rs runs it
on the committed template.
"""
import json
import sys

import numpy as np

GRID = 0.002
FINE = 0.00025
FINE_STEPS = 7
ON_PLANE = 1e-12


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append([float(t) for t in line.split()[1:4]])
            elif line.startswith("f "):
                idx = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
                for k in range(1, len(idx) - 1):
                    faces.append([idx[0], idx[k], idx[k + 1]])
    return np.array(verts, dtype=float), np.array(faces, dtype=np.int64)


def hull(points):
    """Convex hull (monotone chain) -> (perimeter, area, centroid_x, z_min)."""
    pts = sorted(set(map(tuple, points)))
    if len(pts) < 3:
        return None

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    h = np.array(lower[:-1] + upper[:-1])
    if len(h) < 3:
        return None
    q = np.roll(h, -1, axis=0)
    perimeter = float(np.sum(np.hypot(*(q - h).T)))
    o = h[0]
    hr, qr = h - o, q - o
    c = hr[:, 0] * qr[:, 1] - hr[:, 1] * qr[:, 0]
    area = 0.5 * float(c.sum())
    if area > 1e-18:
        cx = o[0] + float(np.sum((hr[:, 0] + qr[:, 0]) * c)) / (6 * area)
    else:
        cx = float(h[:, 0].mean())
    return {"perimeter": perimeter, "area": area, "cx": cx, "z_min": float(h[:, 1].min())}


class Body:
    def __init__(self, verts, faces):
        self.v, self.f = verts, faces
        used = np.unique(faces)
        self.y0 = float(verts[used, 1].min())
        self.stature = float(verts[used, 1].max()) - self.y0
        ys = verts[faces, 1]
        self.ylo, self.yhi = ys.min(1), ys.max(1)
        self.nv = len(verts)

    def at(self, fraction):
        return self.y0 + fraction * self.stature

    def slice(self, h):
        """Loops at height h: list of dicts with x_min, x_max and points (n, 2)."""
        sel = np.nonzero((self.ylo <= h + 1e-9) & (self.yhi >= h - 1e-9))[0]
        f = self.f[sel]
        d = self.v[:, 1] - h
        d = np.where(np.abs(d) < ON_PLANE, ON_PLANE, d)
        above = d[f] > 0
        crosses = above != np.roll(above, -1, axis=1)
        keep = crosses.sum(1) == 2
        f, crosses = f[keep], crosses[keep]
        if len(f) == 0:
            return []
        rows, cols = np.nonzero(crosses)  # two per row, in row order
        a = f[rows, cols]
        b = f[rows, (cols + 1) % 3]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        t = d[lo] / (d[lo] - d[hi])
        p = self.v[lo] + (self.v[hi] - self.v[lo]) * t[:, None]
        keys = lo * self.nv + hi
        uniq, inv = np.unique(keys, return_inverse=True)
        pts = np.zeros((len(uniq), 2))
        pts[inv] = p[:, [0, 2]]
        inv = inv.reshape(-1, 2)
        # Connected components of the key graph (each segment joins its two keys).
        label = np.arange(len(uniq))
        while True:
            seg = np.minimum(label[inv[:, 0]], label[inv[:, 1]])
            new = label.copy()
            np.minimum.at(new, inv[:, 0], seg)
            np.minimum.at(new, inv[:, 1], seg)
            new = new[new]
            if np.array_equal(new, label):
                break
            label = new
        loops = []
        for lab in np.unique(label):
            q = pts[label == lab]
            loops.append({"x_min": q[:, 0].min(), "x_max": q[:, 0].max(), "points": q})
        return loops

    def torso(self, loops, axis):
        r = 0.04 * self.stature
        best = None
        for i, l in enumerate(loops):
            if l["x_min"] <= axis - r and l["x_max"] >= axis + r:
                h = hull(l["points"])
                if h and (best is None or h["area"] > best[1]["area"]):
                    best = (i, h)
        return best

    def side_hulls(self, loops, axis, side):
        t = self.torso(loops, axis)
        out = []
        for i, l in enumerate(loops):
            if t and i == t[0]:
                continue
            h = hull(l["points"])
            if h and (h["cx"] > axis if side > 0 else h["cx"] < axis):
                out.append(h)
        return out

    def has_torso(self, h, axis):
        return self.torso(self.slice(h), axis) is not None

    def arms_apart(self, h, axis):
        loops = self.slice(h)
        if self.torso(loops, axis) is None:
            return False
        g = 0.05 * self.stature
        return all(
            any(s["perimeter"] >= g for s in self.side_hulls(loops, axis, side))
            for side in (1, -1)
        )

    def bisect(self, no, yes, pred):
        while abs(yes - no) > FINE + 1e-9:
            mid = 0.5 * (no + yes)
            if pred(mid):
                yes = mid
            else:
                no = mid
        return yes

    def torso_at(self, h, axis):
        t = self.torso(self.slice(h), axis)
        return (h, t[1]) if t else None


def measure(body):
    s = body.stature
    loops = body.slice(body.at(0.60))
    hulls = [h for h in (hull(l["points"]) for l in loops) if h]
    axis = max(hulls, key=lambda h: h["area"])["cx"]

    bottom, top = body.at(0.30), body.at(0.60)
    crotch = None
    for k in range(int(np.floor((top - bottom) / GRID + 1e-9)) + 1):
        y = bottom + k * GRID
        if body.has_torso(y, axis):
            if k == 0:
                raise SystemExit("no crotch: torso at the search start")
            crotch = body.bisect(y - GRID, y, lambda h: body.has_torso(h, axis))
            break
    if crotch is None:
        raise SystemExit("no crotch")

    top, bottom = body.at(0.88), body.at(0.62)
    armpit = None
    for k in range(int(np.floor((top - bottom) / GRID + 1e-9)) + 1):
        y = top - k * GRID
        if body.arms_apart(y, axis):
            armpit = y if k == 0 else body.bisect(y + GRID, y, lambda h: body.arms_apart(h, axis))
            break
    if armpit is None:
        raise SystemExit("no armpit")

    profile = []
    for k in range(int(np.floor((armpit - crotch) / GRID + 1e-9)) + 1):
        y = crotch + k * GRID
        if y >= armpit - 1e-9:
            break
        t = body.torso_at(y, axis)
        if t:
            profile.append(t)
    t = body.torso_at(armpit, axis)
    if t:
        profile.append(t)

    def extremum(lo, hi, ends, key):
        inside = lambda y: lo - 1e-9 <= y <= hi + 1e-9
        best = None
        for smp in profile + ends:
            if inside(smp[0]) and (best is None or key(smp[1]) < key(best[1])):
                best = smp
        g = best[0]
        for j in range(-FINE_STEPS, FINE_STEPS + 1):
            y = g + j * FINE
            if j == 0 or not inside(y):
                continue
            smp = body.torso_at(y, axis)
            if smp and key(smp[1]) < key(best[1]):
                best = smp
        return best

    max_girth = lambda h: -h["perimeter"]
    min_girth = lambda h: h["perimeter"]
    chest = extremum(max(armpit - 0.10 * s, crotch), armpit, [], max_girth)
    waist0 = extremum(crotch, chest[0], [chest], min_girth)
    hip_max = extremum(crotch, waist0[0], [waist0], max_girth)
    waist = extremum(hip_max[0], chest[0], [hip_max, chest], min_girth)
    hip = extremum(crotch, waist[0], [waist], lambda h: h["z_min"])

    thighs = {}
    band_lo, band_hi = crotch - 0.08, crotch - 0.01
    n = int(np.floor((band_hi - band_lo) / GRID + 1e-9))
    for side, name in ((1, "left"), (-1, "right")):
        best = None
        for k in range(n + 1):
            y = band_hi - k * GRID
            hs = body.side_hulls(body.slice(y), axis, side)
            if hs:
                g = max(hs, key=lambda h: h["area"])["perimeter"]
                if best is None or g > best[1]:
                    best = (y, g)
        g0 = best[0]
        for j in range(-FINE_STEPS, FINE_STEPS + 1):
            y = g0 + j * FINE
            if j == 0 or not (band_lo - 1e-9 <= y <= band_hi + 1e-9):
                continue
            hs = body.side_hulls(body.slice(y), axis, side)
            if hs:
                g = max(hs, key=lambda h: h["area"])["perimeter"]
                if g > best[1]:
                    best = (y, g)
        thighs[name] = best

    mm = 1000.0
    return {
        "measurements_mm": {
            "stature": s * mm,
            "chest_girth": chest[1]["perimeter"] * mm,
            "waist_girth": waist[1]["perimeter"] * mm,
            "hip_girth": hip[1]["perimeter"] * mm,
            "thigh_girth_left": thighs["left"][1] * mm,
            "thigh_girth_right": thighs["right"][1] * mm,
            "hip_girth_max": hip_max[1]["perimeter"] * mm,
        },
        "levels_m": {
            "axis_x_m": axis,
            "crotch_m": crotch,
            "armpit_m": armpit,
            "chest_m": chest[0],
            "waist_m": waist[0],
            "hip_m": hip[0],
            "hip_girth_max_m": hip_max[0],
            "thigh_left_m": thighs["left"][0],
            "thigh_right_m": thighs["right"][0],
        },
    }


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: measure_spec.py MESH.obj")
    verts, faces = read_obj(sys.argv[1])
    if len(faces) == 0:
        sys.exit("no triangles in " + sys.argv[1])
    print(json.dumps(measure(Body(verts, faces)), indent=2))


if __name__ == "__main__":
    main()
