#!/usr/bin/env python3
"""How the girth errors of a synthetic set go with the subject's turn on the mark.

The synthetic subjects stand turned by a small yaw (`placement.yaw_deg` in each
`SUBJECT.truth/truth.json`, a few degrees either way); the fit has no yaw of its own
(issue 19, item 4). A girth does not depend on a turn (spec/measurements.md), so any
dependence of the errors on it is the fit's. For each measurement this prints the
least-squares line of the error (the report's value minus the truth's) against the
signed yaw, its correlation with the signed and with the absolute yaw, and then the
subjects ordered by yaw.

Usage: python3 tools/yaw_errors.py SET_DIR FITS_DIR
   where FITS_DIR/SUBJECT/report.json comes from
   `fitstation replay SET_DIR/SUBJECT --out FITS_DIR/SUBJECT`
(numpy)
"""
import json
import os
import sys

import numpy as np

KEYS = ["chest_girth", "waist_girth", "hip_girth", "thigh_girth_left", "thigh_girth_right"]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    set_dir, fits_dir = sys.argv[1], sys.argv[2]
    rows, names = [], []
    for name in sorted(os.listdir(set_dir)):
        truth_path = os.path.join(set_dir, name + ".truth", "truth.json")
        report_path = os.path.join(fits_dir, name, "report.json")
        if not (os.path.isfile(truth_path) and os.path.isfile(report_path)):
            continue
        truth = json.load(open(truth_path))
        report = json.load(open(report_path))
        got = report.get("measurements_mm", {})
        want = truth["measurements_mm"]
        if not all(k in got and k in want for k in KEYS):
            continue
        rows.append([truth["placement"]["yaw_deg"]] + [got[k] - want[k] for k in KEYS])
        names.append(name)
    if len(rows) < 3:
        sys.exit(f"fewer than 3 fitted subjects with a truth in {set_dir} and {fits_dir}")
    a = np.array(rows)
    yaw = a[:, 0]
    print(f"{len(rows)} subjects, yaw {yaw.min():+.2f} to {yaw.max():+.2f} deg")
    print(f"{'measurement':20} {'mm/deg':>8} {'at 0 deg':>9} {'r(yaw)':>7} {'r(|yaw|)':>9}")
    for k, key in enumerate(KEYS):
        e = a[:, k + 1]
        slope, at_zero = np.polyfit(yaw, e, 1)
        r = np.corrcoef(yaw, e)[0, 1]
        r_abs = np.corrcoef(np.abs(yaw), e)[0, 1]
        print(f"{key:20} {slope:+8.1f} {at_zero:+9.1f} {r:+7.2f} {r_abs:+9.2f}")
    print()
    print(f"{'subject':12} {'yaw':>6} " + " ".join(f"{k[:11]:>11}" for k in KEYS))
    for i in np.argsort(yaw):
        print(f"{names[i]:12} {yaw[i]:+6.2f} " + " ".join(f"{x:+11.1f}" for x in a[i, 1:]))


if __name__ == "__main__":
    main()
