#!/usr/bin/env python3
"""Markdown tables from the estimates of `cargo bench --bench dynamics` (BENCHMARKS.md).

    python3 benches/criterion_table.py [CRITERION_DIR]     # default: target/criterion

Reads `<group>/<function>/<n>/new/estimates.json` (criterion's median, ns) and prints: the
operator form against the recursive algorithms, the growth of forward dynamics in n, one RK4
step against one forward dynamics, `simulate` of 10⁴ steps, and the space-arm figures.
"""

from __future__ import annotations

import json
import os
import sys

SIZES = [7, 14, 28, 56, 112]


def load(root: str, *parts: str):
    path = os.path.join(root, *parts, "new", "estimates.json")
    try:
        with open(path) as fh:
            return json.load(fh)["median"]["point_estimate"]
    except (OSError, KeyError, ValueError):
        return None


def us(ns) -> str:
    return "–" if ns is None else (f"{ns / 1e3:.2f}" if ns < 1e6 else f"{ns / 1e3:,.0f}")


def main() -> None:
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.environ.get("CARGO_TARGET_DIR", "target"), "criterion"
    )
    out = []
    out += [
        "Operator form (dense, O(n³)) against the recursive algorithms (median µs; speed-up = operator / recursive):",
        "",
        "| n | mass matrix: CRBA | operator | speed-up | bias: RNEA | operator | speed-up | forward dynamics: ABA | operator | speed-up |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for n in SIZES:
        row = [str(n)]
        for group in ("mass_matrix", "bias_forces", "forward_dynamics"):
            rec, op = load(root, group, "recursive", str(n)), load(root, group, "operator", str(n))
            row += [us(rec), us(op), "–" if not (rec and op) else f"{op / rec:,.0f}×"]
        out.append("| " + " | ".join(row) + " |")

    fd7 = load(root, "forward_dynamics", "recursive", "7")
    id7 = load(root, "inverse_dynamics", "recursive", "7")
    out += [
        "",
        "Growth in n and the RK4 step (median µs; ratios within this run):",
        "",
        "| n | ABA | ABA(n) / ABA(7) | RNEA | RNEA(n) / RNEA(7) | CRBA | RK4 step | RK4 step / ABA | simulate 10⁴ steps (ms) | per step (µs) |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for n in SIZES:
        fd = load(root, "forward_dynamics", "recursive", str(n))
        inv = load(root, "inverse_dynamics", "recursive", str(n))
        mm = load(root, "mass_matrix", "recursive", str(n))
        step = load(root, "rk4_step", str(n))
        sim = load(root, "simulate_1e4", str(n))
        out.append(
            "| "
            + " | ".join(
                [
                    str(n),
                    us(fd),
                    "–" if not (fd and fd7) else f"{fd / fd7:.1f}",
                    us(inv),
                    "–" if not (inv and id7) else f"{inv / id7:.1f}",
                    us(mm),
                    us(step),
                    "–" if not (step and fd) else f"{step / fd:.2f}",
                    "–" if sim is None else f"{sim / 1e6:.1f}",
                    "–" if sim is None else f"{sim / 1e4 / 1e3:.2f}",
                ]
            )
            + " |"
        )

    names = ["aba", "rnea", "crba", "rk4_step", "simulate_1e4"]
    vals = {k: load(root, "space_arm", k) for k in names}
    if any(vals.values()):
        out += [
            "",
            "Built-in space arm (7 joints; median µs, simulate in ms):",
            "",
            "| aba | rnea | crba | RK4 step | RK4 step / aba | simulate 10⁴ steps (ms) |",
            "|---:|---:|---:|---:|---:|---:|",
            "| "
            + " | ".join(
                [
                    us(vals["aba"]),
                    us(vals["rnea"]),
                    us(vals["crba"]),
                    us(vals["rk4_step"]),
                    "–" if not (vals["aba"] and vals["rk4_step"]) else f"{vals['rk4_step'] / vals['aba']:.2f}",
                    "–" if vals["simulate_1e4"] is None else f"{vals['simulate_1e4'] / 1e6:.1f}",
                ]
            )
            + " |",
        ]
    print("\n".join(out))


if __name__ == "__main__":
    main()
