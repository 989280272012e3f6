#!/usr/bin/env python3
"""Plots the accuracy-vs-cost study (bench/study_accuracy.cpp, docs/study.md).

    /usr/bin/python3 docs/plot_study.py [CSV] [PNG]
    (defaults: build/bench/study_accuracy.csv, docs/speed_accuracy.png)

One log-log panel per scene: error against cost (dynamic scene: median ms per Newmark step;
static scenes: ms for the whole static solve). Colour = element, marker = model, marker size =
mesh size h, hollow = real-time mode, pale = the CG 1e-3 and 1e-9 variants of a dynamic case.
The grey staircase is the Pareto front (cheapest configuration for each error level); its points
are labelled. The shaded band is below the reference's own discretisation error, estimated by
the `linear` scene (Tet10 at h = 0.5 against h = 0.25): differences there are not resolved.
Needs only Debian's python3-matplotlib.
"""
import csv
import math
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

COLOURS = {"Hex8": "#1f77b4", "Tet4": "#d62728", "Tet10": "#2ca02c"}
MARKERS = OrderedDict([
    ("Linear", "o"),
    ("LinearMeanDilatation", "h"),
    ("Corotational", "s"),
    ("CorotationalPerElement", "D"),
    ("CorotationalMeanDilatation", "p"),
    ("NeoHookean", "^"),
    ("NeoHookeanMeanDilatation", "v"),
    ("StableNeoHookean", "<"),
    ("StableNeoHookeanMeanDilatation", ">"),
])
SHORT = {
    "Linear": "Lin", "LinearMeanDilatation": "LinMD", "Corotational": "Corot",
    "CorotationalPerElement": "CorotPE", "CorotationalMeanDilatation": "CorotMD",
    "NeoHookean": "NH", "NeoHookeanMeanDilatation": "NHMD", "StableNeoHookean": "SNH",
    "StableNeoHookeanMeanDilatation": "SNHMD",
}
SIZES = {1.0: 28, 0.5: 60, 0.25: 110}
TITLES = {
    "linear": "linear: discretisation only (Linear statics)",
    "static": "static: bending under gravity",
    "dynamic": "dynamic: 200 Newmark steps, tip history",
    "large": "large: bending under 3 g",
}


def number(s):
    try:
        v = float(s)
        return v if math.isfinite(v) else None
    except (TypeError, ValueError):
        return None


def variant(r):
    if r["mode"] == "static":
        return r["solver"]
    if r["mode"] == "realtime":
        return "RT"
    return "CG{:g}".format(float(r["tolerance"]))


def pareto(points, floor=None):
    """Points (x, y, row) not dominated by a cheaper one: the lower-left staircase. Errors below
    `floor` (the reference's own resolution) are not distinguishable, so the front ends at the
    cheapest point that reaches it."""
    front, best = [], float("inf")
    for p in sorted(points, key=lambda p: (p[0], p[1])):
        if best <= (floor or 0):
            break
        if p[1] < 0.97 * best:  # a few per cent better, not the same answer at another tolerance
            front.append(p)
            best = max(p[1], floor or 0)
    return front


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else "build/bench/study_accuracy.csv"
    dst = sys.argv[2] if len(sys.argv) > 2 else "docs/speed_accuracy.png"
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    scenes = list(OrderedDict.fromkeys(r["scene"] for r in rows))
    if not scenes:
        sys.exit(f"{src}: no rows")

    # The reference's own discretisation error, from the linear scene (Tet10 h=0.5 vs finest).
    floor = None
    for r in rows:
        if r["scene"] == "linear" and r["element"] == "Tet10" and r["model"] == "Linear" \
                and float(r["h"]) == 0.5 and "reference" not in r["note"]:
            floor = number(r["error"])

    ncol = 2 if len(scenes) > 1 else 1
    nrow = math.ceil(len(scenes) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(7.2 * ncol, 5.6 * nrow), squeeze=False)
    for ax in axes.flat[len(scenes):]:
        ax.axis("off")

    for ax, scene in zip(axes.flat, scenes):
        sr = [r for r in rows if r["scene"] == scene]
        dynamic = any(r["mode"] in ("accurate", "realtime") for r in sr)
        ref = next((r for r in sr if "reference" in r["note"]), None)
        pts, failed = [], []
        for r in sr:
            if ref is not None and r is ref:
                continue
            # The reference's own element, model and mesh at a looser solver tolerance: its
            # error is the solver's alone (1e-9 or less); it stays in the CSV.
            if ref is not None and (r["element"], r["model"], r["h"]) == (ref["element"], ref["model"], ref["h"]) \
                    and "unstable" not in r["note"]:
                continue
            err = number(r["error"])
            cost = number(r["ms_per_step"] if dynamic else r["total_ms"])
            if err is None or cost is None:
                if r["note"].find("failed") >= 0:
                    failed.append(r)
                continue
            err = max(err, 1e-7)  # keeps an exact match on the log axis
            h = float(r["h"])
            rt = r["mode"] == "realtime"
            pale = dynamic and not rt and float(r["tolerance"]) != 1e-6
            colour = COLOURS.get(r["element"], "k")
            ax.scatter(cost, err, s=SIZES.get(h, 40), marker=MARKERS.get(r["model"], "x"),
                       facecolors="none" if rt else colour, edgecolors=colour,
                       alpha=0.35 if pale else 0.9, linewidths=1.1, zorder=3)
            if "wrong kinematics" in r["note"]:
                ax.scatter(cost, err, s=SIZES.get(h, 40) * 1.9, marker="x", color="k", linewidths=0.8, zorder=4)
            if "unstable" in r["note"]:
                ax.scatter(cost, err, s=SIZES.get(h, 40) * 2.2, marker="+", color="m", linewidths=1.0, zorder=4)
            pts.append((cost, err, r))
        if floor and scene != "linear":
            ax.axhspan(1e-9, floor, color="0.88", zorder=0)
            ax.text(0.01, floor, "reference resolution ~{:.1%}".format(floor), transform=ax.get_yaxis_transform(),
                    ha="left", va="top", fontsize=7, color="0.35")
        front = pareto([p for p in pts if "wrong kinematics" not in p[2]["note"] and "unstable" not in p[2]["note"]],
                       floor if scene != "linear" else None)
        if front:
            xs, ys = [], []
            for i, (x, y, _) in enumerate(front):
                xs += [x] if i == 0 else [x, x]
                ys += [y] if i == 0 else [front[i - 1][1], y]
            ax.plot(xs, ys, color="0.45", lw=0.9, zorder=2, drawstyle="default")
            last = None
            for i, (x, y, r) in enumerate(front):
                # Skip a label that would sit on the previous one (close in both log x and log y).
                if last and abs(math.log10(x / last[0])) < 0.25 and abs(math.log10(y / last[1])) < 0.3:
                    continue
                label = "{} {} h={:g}".format(r["element"], SHORT.get(r["model"], r["model"]), float(r["h"]))
                if dynamic:
                    label += " " + variant(r)
                ax.annotate(label, (x, y), xytext=(4, 3 if i % 2 == 0 else -9), textcoords="offset points",
                            fontsize=6.5, color="0.2")
                last = (x, y)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ys = [p[1] for p in pts]
        if ys:
            lo = min(ys) / 2.5
            if floor and scene != "linear":
                lo = min(lo, floor / 2.5)
            ax.set_ylim(lo, max(ys) * 2.0)
        ax.grid(True, which="major", color="0.85", lw=0.6)
        ax.grid(True, which="minor", color="0.94", lw=0.4)
        ax.set_xlabel("median ms per Newmark step (1 thread)" if dynamic else "ms for the static solve (1 thread)")
        ax.set_ylabel("RMS tip-history error / max |ref|" if dynamic else "relative tip-displacement error")
        title = TITLES.get(scene, scene)
        if ref is not None:
            title += "\nreference: " + ref["reference"]
        ax.set_title(title, fontsize=9.5)
        if failed:
            names = sorted({"{} {} h={:g}".format(r["element"], SHORT.get(r["model"], r["model"]), float(r["h"]))
                            for r in failed})
            ax.text(0.01, 0.01, "no static solution (Newton diverged):\n" + "\n".join(names),
                    transform=ax.transAxes, fontsize=6.5, va="bottom", ha="left", color="0.3",
                    bbox=dict(boxstyle="round", fc="white", ec="0.8"))

    present = {r["model"] for r in rows}
    handles = [Line2D([], [], ls="", marker="s", ms=8, color=c, label=e) for e, c in COLOURS.items()]
    handles += [Line2D([], [], ls="", marker=m, ms=7, mfc="0.5", mec="0.3", label=name)
                for name, m in MARKERS.items() if name in present]
    handles += [Line2D([], [], ls="", marker="o", ms=math.sqrt(s), mfc="0.5", mec="0.3", label="h = {:g}".format(h))
                for h, s in SIZES.items()]
    handles += [Line2D([], [], ls="", marker="o", ms=7, mfc="none", mec="0.3", label="real-time mode (CG 1e-6)"),
                Line2D([], [], ls="", marker="o", ms=7, mfc="0.5", mec="0.5", alpha=0.35,
                       label="accurate, CG 1e-3 or 1e-9 (pale)"),
                Line2D([], [], ls="", marker="x", ms=8, color="k", label="wrong kinematics (flagged)"),
                Line2D([], [], ls="", marker="+", ms=9, color="m", label="unstable run (energy blow-up)"),
                Line2D([], [], color="0.45", lw=0.9, label="Pareto front (labelled)")]
    fig.legend(handles=handles, loc="lower center", ncol=6, fontsize=7.5, frameon=False)
    fig.suptitle("plastifem: accuracy against cost of the elastic models on the bar (10 x 3 x 3, E = 3000, "
                 "nu = 0.45, clamped, gravity)", fontsize=11)
    fig.tight_layout(rect=(0, 0.075, 1, 0.97))
    fig.savefig(dst, dpi=130)
    print(f"wrote {dst}")


if __name__ == "__main__":
    main()
