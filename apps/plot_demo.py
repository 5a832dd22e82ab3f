#!/usr/bin/env python3
"""Plots of the demo's CSV logs: pose error, torques, filtered vs commanded targets, contact
force, and displacement against force for the compliance sweep. Usage: plot_demo.py OUTPUT_DIR
"""
import csv
import math
import pathlib
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {key: [float(row[key]) for row in rows] for key in rows[0]} if rows else {}


def save(figure, path):
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def plot_log(name, log, out):
    t = log["time"]
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    top.plot(t, [1e3 * math.sqrt(x * x + y * y + z * z)
                 for x, y, z in zip(log["error_x"], log["error_y"], log["error_z"])])
    top.set_ylabel("translation error [mm]")
    bottom.plot(t, [math.sqrt(x * x + y * y + z * z)
                    for x, y, z in zip(log["error_rx"], log["error_ry"], log["error_rz"])])
    bottom.set_ylabel("rotation error [rad]")
    bottom.set_xlabel("time [s]")
    top.set_title(f"{name}: pose error |e| (after clipping)")
    save(figure, out / f"{name}_pose_error.png")

    figure, axes = plt.subplots(figsize=(8, 4))
    for key in sorted((k for k in log if k.startswith("tau_")), key=lambda k: int(k[4:])):
        axes.plot(t, log[key], label=key.replace("tau_", "joint "))
    axes.set_xlabel("time [s]")
    axes.set_ylabel("commanded torque [Nm]")
    axes.legend(fontsize="small", ncol=4)
    axes.set_title(f"{name}: commanded joint torques")
    save(figure, out / f"{name}_torques.png")

    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for axis, colour in zip("xyz", ("tab:red", "tab:green", "tab:blue")):
        top.plot(t, log[f"commanded_{axis}"], "--", color=colour, label=f"commanded {axis}")
        top.plot(t, log[f"reference_{axis}"], color=colour, label=f"filtered {axis}")
        top.plot(t, log[axis], ":", color=colour, label=f"flange {axis}")
    top.set_ylabel("position [m]")
    top.legend(fontsize="x-small", ncol=3)
    bottom.plot(t, log["commanded_stiffness_x"], "--", label="commanded")
    bottom.plot(t, log["stiffness_x"], label="filtered")
    bottom.set_ylabel("stiffness x [N/m]")
    bottom.set_xlabel("time [s]")
    bottom.legend(fontsize="small")
    top.set_title(f"{name}: filtered vs commanded targets")
    save(figure, out / f"{name}_targets.png")

    if any(abs(value) > 1e-9 for value in log["contact_z"]):
        figure, axes = plt.subplots(figsize=(8, 3.5))
        axes.plot(t, log["contact_z"], label="contact force z (measured)")
        axes.plot(t, [-value for value in log["wrench_z"]], "--", label="commanded force (down)")
        axes.set_xlabel("time [s]")
        axes.set_ylabel("[N]")
        axes.legend()
        axes.set_title(f"{name}: force on the table")
        save(figure, out / f"{name}_force.png")


def plot_sweep(out):
    summary = out / "summary.csv"
    if not summary.exists():
        return
    with open(summary, newline="") as handle:
        rows = [row for row in csv.DictReader(handle) if row["scenario"] == "compliance sweep"]
    if not rows:
        return
    forces = [float(re.search(r"under ([0-9.]+) N", row["quantity"]).group(1)) for row in rows]
    figure, axes = plt.subplots(figsize=(6, 4))
    axes.plot(forces, [float(row["theory"]) for row in rows], "-", label="theory F / K")
    axes.plot(forces, [float(row["measured"]) for row in rows], "o", label="measured")
    axes.set_xlabel("push along x [N]")
    axes.set_ylabel("displacement [mm]")
    axes.legend()
    axes.set_title("compliance: displacement vs force at 500 N/m")
    save(figure, out / "compliance_displacement_vs_force.png")


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = pathlib.Path(sys.argv[1])
    for path in sorted(out.glob("*.csv")):
        if path.name != "summary.csv":
            log = read(path)
            if log:
                plot_log(path.stem, log, out)
    plot_sweep(out)


if __name__ == "__main__":
    main()
