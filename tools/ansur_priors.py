#!/usr/bin/env python3
"""Spreads of real bodies that the station's uncertainty model uses (fit/uncertainty.rs).

Reads ANSUR II (../shared/data/ansur2, public domain) and prints, per girth, the residual
standard deviation (mm) of
  shape: circumference regressed on breadth and depth (and their product): how far a
         girth can be from what its two extents say, i.e. the section shape two views
         cannot see;
  depth: depth regressed on breadth, stature, weight and sex: how far the depth can be
         from what the rest of the body says, i.e. a depth the side view did not show;
  breadth: the same for the breadth (an extent the front view did not show);
  front-only depth: how far real people's depth lies from what breadth and stature alone
         say (no weight, no sex: a front camera and a typed stature), about ANSUR's own
         line and about the shape library's (tools/library_extents.csv): the depth the
         station takes from its library when the side view is missing (one-camera fits,
         station/uncertainty.rs `depth_prior_one_view_mm`).
Usage: python3 tools/ansur_priors.py [ANSUR_DIR]   (numpy only)
"""
import csv, os, sys
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "..", "shared", "data", "ansur2")

def rows(name, enc):
    with open(os.path.join(root, name), encoding=enc, newline="") as f:
        r = csv.reader(f)
        head = [h.lower() for h in next(r)]
        for line in r:
            yield dict(zip(head, line))

data = [(d, 1.0) for d in rows("ANSUR_II_MALE_Public.csv", "latin-1")] + \
       [(d, 0.0) for d in rows("ANSUR_II_FEMALE_Public.csv", "utf-8")]

def col(name):
    return np.array([float(d[name]) for d, _ in data])

sex = np.array([s for _, s in data])
stature, weight = col("stature"), col("weightkg") / 10.0

def resid_sd(y, *xs):
    a = np.column_stack([np.ones_like(y), *xs])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    r = y - a @ coef
    return float(np.sqrt(np.mean(r * r)))

print(f"ANSUR II: {len(data)} subjects")
print(f"{'girth':8} {'shape sd':>9} {'depth sd':>9} {'breadth sd':>11}   (mm)   shape sd / mean girth")
for name, circ, breadth, depth in [
    ("chest", "chestcircumference", "chestbreadth", "chestdepth"),
    ("waist", "waistcircumference", "waistbreadth", "waistdepth"),
    ("hip", "buttockcircumference", "hipbreadth", "buttockdepth"),
]:
    c, b, d = col(circ), col(breadth), col(depth)
    shape = resid_sd(c, b, d, b * d, sex)
    dsd = resid_sd(d, b, stature, weight, sex)
    bsd = resid_sd(b, d, stature, weight, sex)
    print(f"{name:8} {shape:9.1f} {dsd:9.1f} {bsd:11.1f}          {shape / c.mean():.4f}")
t = col("thighcircumference")
print(f"{'thigh':8} {resid_sd(t, stature, weight, sex, col('buttockcircumference')):9.1f}   (girth from stature, weight, sex and buttock girth: no thigh breadth or depth in ANSUR)")
print()
# One view: the depth the station cannot see comes from its shape library (the body
# chosen by the front widths and the stature), so what matters is how far real people's
# depths lie from the library's depth-given-breadth-and-stature line. The library's
# breadths and depths are its trunk sections' extents at the measurement levels
# (tools/library_extents.csv, from `cargo test --release library_extents_csv --
# --ignored --nocapture`); ANSUR II's are caliper measures at its own landmarks, so the
# two differ by an offset (the mean, printed) that is partly one of definitions and
# partly the library's bodies being shallower than real people for their breadth; the
# station cannot tell the two parts apart from one view, so its one-view prior is the
# root mean square about the library's line (offset and spread together).
lib_path = os.path.join(here, "library_extents.csv")
with open(lib_path, newline="") as f:
    lib = list(csv.DictReader(f))
lc = lambda n: np.array([float(d[n]) for d in lib])
print(f"front view alone (breadths and stature seen, depth unseen): {len(lib)} library bodies")
print(f"{'girth':8} {'sd about ANSUR line':>20} {'sd about library line':>22} {'offset':>8} {'rms about library line':>23}   (mm)")
for name, breadth, depth in [
    ("chest", "chestbreadth", "chestdepth"),
    ("waist", "waistbreadth", "waistdepth"),
    ("hip", "hipbreadth", "buttockdepth"),
]:
    a = np.column_stack([np.ones(len(lib)), lc(breadth), lc("stature")])
    coef, *_ = np.linalg.lstsq(a, lc(depth), rcond=None)
    r = col(depth) - np.column_stack([np.ones(len(data)), col(breadth), stature]) @ coef
    print(f"{name:8} {resid_sd(col(depth), col(breadth), stature):20.1f} {r.std():22.1f} {r.mean():+8.1f} {np.sqrt(np.mean(r * r)):23.1f}")
# No thigh breadth or depth in ANSUR: the thigh girth's spread given what a front view
# shows nearby (hip breadth, stature), all of it taken as the unseen depth's:
# girth sd / (pi/2).
tg = resid_sd(t, col("hipbreadth"), stature)
print(f"{'thigh':8} {tg / (np.pi / 2):20.1f}   (thigh girth sd given hip breadth and stature, {tg:.1f} mm, over pi/2)")
print()


def ellipse_perimeter(b, d):
    a, c = b / 2.0, d / 2.0
    return np.pi * (3.0 * (a + c) - np.sqrt((3.0 * a + c) * (a + 3.0 * c)))


# The section's fullness: circumference over the perimeter of the ellipse with the same
# breadth and depth (fit/section_prior.rs gives the waist band this median). ANSUR's chest
# breadth and depth are taken at the nipples with calipers and do not match a section's
# extents (depth/breadth 0.8-1.0 here, about 0.75 in a body's section): chest is printed
# for completeness, not used.
print(f"{'girth':8} {'fullness: median':>17} {'p25':>6} {'p75':>6} {'p5':>6} {'p95':>6}   (circumference / ellipse perimeter of breadth, depth)")
for name, circ, breadth, depth in [
    ("chest", "chestcircumference", "chestbreadth", "chestdepth"),
    ("waist", "waistcircumference", "waistbreadth", "waistdepth"),
    ("hip", "buttockcircumference", "hipbreadth", "buttockdepth"),
]:
    r = col(circ) / ellipse_perimeter(col(breadth), col(depth))
    q = np.percentile(r, [50, 25, 75, 5, 95])
    by_sex = f"women {np.median(r[sex == 0.0]):.3f}, men {np.median(r[sex == 1.0]):.3f}"
    print(f"{name:8} {q[0]:17.3f} {q[1]:6.3f} {q[2]:6.3f} {q[3]:6.3f} {q[4]:6.3f}   (median {by_sex})")
print()

# The waist's girth from its own breadth and depth, the most two views that see both
# extents right can say of it: the median fullness times the ellipse, and a linear fit on
# the ellipse, breadth, depth and the ellipse times depth/breadth (fit on one half of ANSUR
# II, tested on the other).
wb, wd, wc = col("waistbreadth"), col("waistdepth"), col("waistcircumference")
we = ellipse_perimeter(wb, wd)
wx = np.column_stack([np.ones_like(we), we, wb, wd, we * wd / wb])
wrows = np.random.default_rng(0).permutation(len(we))
wfit, wtest = wrows[: len(wrows) // 2], wrows[len(wrows) // 2:]
wcoef, *_ = np.linalg.lstsq(wx[wfit], wc[wfit], rcond=None)
print(f"waist circumference from its breadth and depth: median fullness x ellipse MAE "
      f"{np.mean(np.abs(wc - np.median(wc / we) * we)):.1f} mm, linear fit MAE "
      f"{np.mean(np.abs(wc[wtest] - wx[wtest] @ wcoef)):.1f} mm (tested on the other half)")
print()

# The hand's reach beyond the wrist, as a share of the forearm (radiale to stylion): what
# a hand capsule from the side view's elbow and wrist keypoints must cover.
hand = col("handlength") / col("radialestylionlength")
print(f"hand length / radiale-stylion length: median {np.median(hand):.3f}, p95 {np.percentile(hand, 95):.3f}")
print()

# What two silhouettes can say at best: each girth predicted, on half of ANSUR II, from
# everything a front and a side view measure (the three breadths and depths, their
# products, stature, shoulder breadths) and sex, checked on the other half. The mean
# absolute error includes ANSUR's own measuring noise.
seen = [col(k) for k in ("chestbreadth", "chestdepth", "waistbreadth", "waistdepth", "hipbreadth", "buttockdepth")]
extra = [stature, col("bideltoidbreadth"), col("biacromialbreadth"), sex]
x = np.column_stack([np.ones_like(stature)] + seen + extra
                    + [a * b / 1000.0 for i, a in enumerate(seen) for b in seen[i:]])
half = np.random.default_rng(0).permutation(len(stature))
fit_rows, test_rows = half[: len(half) // 2], half[len(half) // 2:]
print("girth from everything two views see (fit on half of ANSUR II, tested on the other half)")
for name, circ in [("chest", "chestcircumference"), ("waist", "waistcircumference"), ("hip", "buttockcircumference")]:
    y = col(circ)
    coef, *_ = np.linalg.lstsq(x[fit_rows], y[fit_rows], rcond=None)
    e = np.abs(y[test_rows] - x[test_rows] @ coef)
    print(f"{name:8} MAE {e.mean():5.1f} mm   p95 {np.percentile(e, 95):5.1f} mm")
