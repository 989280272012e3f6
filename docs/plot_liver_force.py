#!/usr/bin/env python3
"""Plots the liver_cage example's grasper force over time (docs/liver_cage_force.png).

Needs Debian's python3-matplotlib (run with /usr/bin/python3):
    /usr/bin/python3 docs/plot_liver_force.py DIR/liver_cage_force.csv OUT.png
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 (after choosing the backend)


def main():
    path, out = sys.argv[1:3]
    with open(path) as f:
        rows = list(csv.DictReader(f))
    t = [float(r["time"]) for r in rows]
    lift = [1e3 * float(r["lift"]) for r in rows]
    fz = [float(r["force_z"]) for r in rows]
    fx = [float(r["force_x"]) for r in rows]
    fig, force = plt.subplots(figsize=(7, 3.6), dpi=110)
    force.plot(t, fz, color="tab:red", label="vertical force $F_z$")
    force.plot(t, fx, color="tab:orange", linestyle="--", label="along the organ $F_x$")
    force.set_xlabel("time (s)")
    force.set_ylabel("grasper force on the organ (N)")
    force.axhline(0, color="0.6", linewidth=0.8)
    height = force.twinx()
    height.plot(t, lift, color="tab:blue", linestyle=":", label="grasper lift (while it holds)")
    height.set_ylabel("grasper lift (mm)", color="tab:blue")
    lines = force.get_lines()[:2] + height.get_lines()
    force.legend(lines, [line.get_label() for line in lines], loc="upper right", fontsize=9)
    force.set_title("Liver lobe grasped at t = 0.5 s, lifted 25 mm, held, released at t = 2 s")
    fig.tight_layout()
    fig.savefig(out)


if __name__ == "__main__":
    main()
