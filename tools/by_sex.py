#!/usr/bin/env python3
"""Girth errors of an `eval --json` run split by the ANSUR II person's sex.

The `ansur` population's truths name the person each body follows
(`truth.json` -> `ansur.record.sex`); `fitstation eval` pools both sexes. This prints,
per set and per girth, the MAE, bias and count of the women's and the men's errors
(subjects without an ANSUR person, e.g. the library set, are skipped).

Usage: fitstation eval --json --set ansur=DIR ... > EVAL.json
       python3 tools/by_sex.py EVAL.json ansur=DIR [varied=DIR ...]
"""
import json
import os
import sys

import numpy as np

GIRTHS = ["chest_girth", "waist_girth", "hip_girth", "thigh_girth_left", "thigh_girth_right"]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        sets = json.load(f)["sets"]
    for arg in sys.argv[2:]:
        name, _, folder = arg.partition("=")
        rows = sets.get(name, {}).get("rows", [])
        errors = {}
        for row in rows:
            truth = os.path.join(folder, row["subject"] + ".truth", "truth.json")
            try:
                with open(truth) as f:
                    sex = json.load(f)["ansur"]["record"]["sex"]
            except (OSError, KeyError, TypeError, ValueError):
                continue
            for m in row.get("measurements", []):
                if m.get("name") in GIRTHS and m.get("error_mm") is not None:
                    errors.setdefault((sex, m["name"]), []).append(m["error_mm"])
        print(f"== {name}: MAE / bias mm (subjects)")
        for sex in ("female", "male"):
            cells = []
            for g in GIRTHS:
                e = np.array(errors.get((sex, g), []))
                cells.append(f"{g.replace('_girth', '')} "
                             + (f"{np.abs(e).mean():.1f} / {e.mean():+.1f} ({len(e)})" if len(e) else "-"))
            print(f"{sex:7} " + "   ".join(cells))


if __name__ == "__main__":
    main()
