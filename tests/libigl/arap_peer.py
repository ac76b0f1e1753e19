#!/usr/bin/env python3
"""Outside peer for `fitstation bench deform`: libigl's ARAP (PyPI `libigl`) on the same
mesh and constraints the bench writes.

Inputs (written by the bench):
  mesh.obj         the rest mesh, metres
  constraints.csv  header `index,x,y,z`, one control vertex and its target per line
  refit.csv        optional, same format: targets moved a few millimetres (warm refit)
Prints one `key value` line per measurement (times in ms, lengths in m) so the Rust
side can parse it.
"""
import argparse
import sys
import time

import numpy as np

try:
    import igl
except ImportError:
    print("SKIPPED: python module igl (PyPI libigl) is not installed", file=sys.stderr)
    sys.exit(3)


def read_constraints(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return data[:, 0].astype(np.int32), np.ascontiguousarray(data[:, 1:4], dtype=np.float64)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", required=True)
    ap.add_argument("--constraints", required=True)
    ap.add_argument("--refit", default=None)
    ap.add_argument("--max-iter", type=int, default=10, help="ARAP local/global iterations per solve")
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()

    V, F = igl.read_triangle_mesh(a.mesh)
    b, bc = read_constraints(a.constraints)
    print(f"vertices {V.shape[0]}")
    print(f"controls {b.shape[0]}")

    best_pre = float("inf")
    data = None
    for _ in range(a.repeats):
        d = igl.ARAPData()
        d.max_iter = a.max_iter
        t0 = time.perf_counter()
        igl.arap_precomputation(V, F, 3, b, d)
        best_pre = min(best_pre, time.perf_counter() - t0)
        data = d
    print(f"precompute_ms {best_pre * 1e3:.2f}")

    best_solve = float("inf")
    U = None
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        U = igl.arap_solve(bc, data, V.copy())
        best_solve = min(best_solve, time.perf_counter() - t0)
    print(f"solve_ms {best_solve * 1e3:.2f}")
    print(f"iterations {a.max_iter}")
    print(f"per_iteration_ms {best_solve * 1e3 / a.max_iter:.3f}")
    print(f"constraint_residual_m {np.abs(U[b] - bc).max():.3e}")
    print(f"max_displacement_m {np.linalg.norm(U - V, axis=1).max():.4f}")

    if a.refit:
        b2, bc2 = read_constraints(a.refit)
        if not np.array_equal(b2, b):
            print("refit controls differ from the first set", file=sys.stderr)
            sys.exit(2)
        best_refit = float("inf")
        for _ in range(a.repeats):
            t0 = time.perf_counter()
            igl.arap_solve(bc2, data, U.copy())
            best_refit = min(best_refit, time.perf_counter() - t0)
        print(f"warm_refit_ms {best_refit * 1e3:.2f}")


if __name__ == "__main__":
    main()
