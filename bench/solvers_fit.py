#!/usr/bin/env python3
"""Fits the constants of auto's cost model (core/sm_elasticity.c, COST_*)
on the raw lines bench/solvers.sh leaves in build/solvers/raw.txt: each
solver's set-up and solve (CPU seconds of one thread) and the memory it
adds, against the figures the model reads (the matrix's entries nnz, the
factor's entries lnz and flops).  Least squares on the relative error
(each line weighs the same, whatever its size), non-negative constants.

    python3 bench/solvers_fit.py [build/solvers/raw.txt]

Prints the constants, each line's prediction over its measure, and the
worst ratio, for docs/solvers.md."""
import sys

import numpy as np
from scipy.optimize import nnls


def read(path):
    rows = {}
    for line in open(path):
        parts = line.split()
        if len(parts) < 3 or parts[1] != "SOLVER":
            continue
        kv = dict(p.split("=", 1) for p in parts[2:] if "=" in p)
        # the last measurement of a case and solver counts
        rows[(parts[0], kv["solver"])] = kv
    return rows


def fit(name, X, y, labels, cols):
    # relative least squares: divide each row by its measure
    A = X / y[:, None]
    c, _ = nnls(A, np.ones(len(y)))
    pred = X @ c
    print(f"{name}: " + ", ".join(f"{n} {v:.4g}" for n, v in zip(cols, c)))
    worst = 0
    for lab, p, m in zip(labels, pred, y):
        worst = max(worst, abs(p / m - 1))
        print(f"    {lab:12s} measured {m:10.4g} predicted {p:10.4g} ({p / m:.2f})")
    print(f"    worst relative error {worst:.0%}")
    return c


def fit_power(name, x, y, labels, xname):
    # y = c x^p: least squares on the logarithms (relative errors)
    p, logc = np.polyfit(np.log(x), np.log(y), 1)
    c = np.exp(logc)
    pred = c * x ** p
    print(f"{name}: {c:.4g} * {xname}^{p:.3f}")
    worst = 0
    for lab, q, m in zip(labels, pred, y):
        worst = max(worst, abs(q / m - 1))
        print(f"    {lab:12s} measured {m:10.4g} predicted {q:10.4g} ({q / m:.2f})")
    print(f"    worst relative error {worst:.0%}")
    return c, p


def main():
    rows = read(sys.argv[1] if len(sys.argv) > 1 else "build/solvers/raw.txt")
    chol = [(k[0], v) for k, v in rows.items() if k[1] == "cholmod"]
    amg = [(k[0], v) for k, v in rows.items() if k[1] == "amg"]
    f = lambda v, k: float(v[k])
    if chol:
        lab = [c for c, _ in chol]
        fit("cholmod set-up s", np.array([[f(v, "flops"), f(v, "nnz")] for _, v in chol]),
            np.array([f(v, "cpu_setup") for _, v in chol]), lab, ["per flop", "per nnz"])
        fit_power("cholmod solve s", np.array([f(v, "lnz") for _, v in chol]),
                  np.array([f(v, "cpu_solve") for _, v in chol]), lab, "lnz")
        fit("cholmod MiB", np.array([[f(v, "lnz"), f(v, "nnz")] for _, v in chol]),
            np.array([f(v, "rss_mib") for _, v in chol]), lab, ["per lnz", "per nnz"])
    if amg:
        lab = [c for c, _ in amg]
        # the hierarchy takes the rigid rotations from 80,000 unknowns on
        # (SM_AMG_MODES_MIN_UNKNOWNS): a dearer set-up per entry
        modes = lambda v: f(v, "unknowns") >= 80000
        fit("amg set-up s", np.array([[f(v, "nnz") * (not modes(v)), f(v, "nnz") * modes(v)]
                                      for _, v in amg]),
            np.array([f(v, "cpu_setup") for _, v in amg]), lab,
            ["per nnz", "per nnz with the rotations"])
        fit_power("amg solve s", np.array([f(v, "nnz") for _, v in amg]),
                  np.array([f(v, "cpu_solve") for _, v in amg]), lab, "nnz")
        fit("amg MiB", np.array([[f(v, "nnz")] for _, v in amg]),
            np.array([f(v, "rss_mib") for _, v in amg]), lab, ["per nnz"])


main()
