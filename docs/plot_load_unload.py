#!/usr/bin/env python3
"""Plots the load-unload curves of examples/plastic_stretch (docs/plasticity.md).

    /usr/bin/python3 docs/plot_load_unload.py OUT.png DIR
DIR holds the example's CSVs (stretch_<model>_Hex8_VertexBlended_L0_set<k>.csv: time, force,
tip_ux, material_tip_ux). One panel per elastic model: the end-face force against the tip's
displacement (the end face's mean) through the ramp, the hold, the release and the relaxation,
one line per parameter set; the dashed lines are the material mesh's tip (the plastic part).
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return [[float(r[k]) for r in rows] for k in ("time", "force", "tip_ux", "material_tip_ux")]


def main():
    out, folder = sys.argv[1], sys.argv[2]
    models = [("corotational", "linear-corotational + plastic (force 350)",
               ["tau 1000, nu 0.4", "tau 1500, nu 0.2", "tau 1500, nu 0.1"]),
              ("neohookean", "Neo-Hookean + plastic (force 1000)",
               ["tau 1500, nu 0.25", "tau 1800, nu 0.2", "tau 2000, nu 0.15"])]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, (model, title, labels) in zip(axes, models):
        for k, label in enumerate(labels, start=1):
            t, force, tip, material = read(f"{folder}/stretch_{model}_Hex8_VertexBlended_L0_set{k}.csv")
            line, = ax.plot(tip, force, label=f"set {k}: {label}", lw=1.2)
            ax.plot(material, force, ls="--", lw=1.0, color=line.get_color())
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("tip displacement (end face mean); dashed: material mesh")
        ax.set_ylabel("end-face force")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle("bar90 Hex8, vertex-blended: ramp 0-1 s, hold 1-2 s, release, relax to 4 s (mass damping 1)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
