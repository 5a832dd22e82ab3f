#!/usr/bin/env python3
"""Plots of the demo's CSV logs: pose error, torques, filtered vs commanded targets (every
quantity the scenario commands), contact force, displacement against force for the compliance
sweep, the stability grid's map, both arms of the two-arm scene, the safety layer's contact
force with and without its caps, flange speeds against the speed cap, the workspace box with the
flange's path, the energy with and without the energy tank, and the collision monitor's
residuals per joint and the contact force with and without each reaction. Each time plot shades the
scenario's phases and names them.
Usage: plot_demo.py OUTPUT_DIR
"""
import csv
import math
import pathlib
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

AXES = ("x", "y", "z")
COLOURS = ("tab:red", "tab:green", "tab:blue")
PHASE_COLOURS = ("#fdf3d8", "#dcecf8", "#e3f4df", "#f6e1ee", "#ece6f7", "#f9e4d6")


def read(path):
    """Columns by name: numbers as floats, the phase column as text."""
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        return {}
    return {key: [row[key] if key == "phase" else float(row[key]) for row in rows]
            for key in rows[0]}


def save(figure, path):
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def floor_range(axes, values, floor, centre=None):
    """At least `floor` of y range: a quantity that varies by less (e.g. 1e-19 m of round-off on a
    held position) is drawn as the flat line it is, not stretched into a trend."""
    values = [v for v in values if math.isfinite(v)]
    if not values:
        return
    low, high = min(values), max(values)
    if high - low >= floor:
        return
    middle = 0.5 * (low + high) if centre is None else centre
    if centre is not None:  # e.g. errors from 0: keep 0 at the bottom
        axes.set_ylim(min(low, centre) - 0.05 * floor, max(high, centre + floor))
    else:
        axes.set_ylim(middle - 0.5 * floor, middle + 0.5 * floor)


def phases(log):
    """(start, end, label) of each run of equal phase labels."""
    spans = []
    t, labels = log["time"], log.get("phase", [])
    for i, label in enumerate(labels):
        if i == 0 or label != labels[i - 1]:
            spans.append([t[i], t[i], label])
        spans[-1][1] = t[i]
    return spans


def shade_phases(axes_list, log, label_axes=None):
    """Shades each phase in every axes; names them in `label_axes` (the top one), rotated when
    there are many."""
    spans = [s for s in phases(log) if s[2]]
    if not spans:
        return
    names = sorted({s[2] for s in spans})
    colour = {name: PHASE_COLOURS[i % len(PHASE_COLOURS)] for i, name in enumerate(names)}
    for axes in axes_list:
        for start, end, name in spans:
            axes.axvspan(start, end, color=colour[name], zorder=0, linewidth=0)
    if label_axes is None:
        return
    duration = log["time"][-1] - log["time"][0] or 1.0
    many = len(spans) > 6
    transform = label_axes.get_xaxis_transform()
    for start, end, name in spans:
        if (end - start) / duration < (0.01 if many else 0.04):
            continue
        label_axes.text(start + 0.5 * (end - start), 0.98, name, transform=transform,
                        rotation=90 if many else 0, ha="center", va="top",
                        fontsize=6 if many else 7, color="0.2", clip_on=True,
                        bbox={"facecolor": "white", "alpha": 0.6, "linewidth": 0, "pad": 1})


def norm3(log, prefix, suffixes=AXES, scale=1.0):
    return [scale * math.sqrt(sum(v * v for v in values))
            for values in zip(*(log[prefix + s] for s in suffixes))]


def changes(values, tolerance):
    return bool(values) and max(values) - min(values) > tolerance


def width_for(log):
    """Long runs (the compliance tour is 110 s) get a wider figure."""
    return 8 if log["time"][-1] - log["time"][0] < 30 else 14


def plot_pose_error(name, log, out):
    t = log["time"]
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(width_for(log), 5), sharex=True)
    translation = norm3(log, "error_", scale=1e3)
    rotation = norm3(log, "error_", ("rx", "ry", "rz"))
    top.plot(t, translation, color="k", linewidth=1)
    top.set_ylabel("translation error [mm]")
    floor_range(top, translation, 0.5, centre=0.0)
    bottom.plot(t, rotation, color="k", linewidth=1)
    bottom.set_ylabel("rotation error [rad]")
    floor_range(bottom, rotation, 0.005, centre=0.0)
    bottom.set_xlabel("time [s]")
    shade_phases((top, bottom), log, top)
    top.set_title(f"{name}: pose error |e| (after clipping); shaded: what the scenario does")
    save(figure, out / f"{name}_pose_error.png")


def plot_torques(name, log, out):
    t = log["time"]
    figure, axes = plt.subplots(figsize=(width_for(log), 4))
    keys = sorted((k for k in log if k.startswith("tau_")), key=lambda k: int(k[4:]))
    for key in keys:
        axes.plot(t, log[key], label=key.replace("tau_", "joint "), linewidth=1)
    floor_range(axes, [v for key in keys for v in log[key]], 0.5)
    shade_phases((axes,), log, axes)
    axes.set_xlabel("time [s]")
    axes.set_ylabel("commanded torque [Nm]")
    axes.legend(fontsize="small", ncol=4, loc="lower right")
    axes.set_title(f"{name}: commanded joint torques")
    save(figure, out / f"{name}_torques.png")


def plot_targets(name, log, out):
    """Every commanded quantity the scenario changes, filtered (solid) and commanded (dashed)."""
    t = log["time"]
    panels = []
    panels.append("position")
    for panel, suffixes in (("translation stiffness", AXES),
                            ("rotation stiffness", ("rx", "ry", "rz"))):
        if any(changes(log[f"commanded_stiffness_{a}"], 1e-6) or
               changes(log[f"stiffness_{a}"], 1e-6) for a in suffixes):
            panels.append(panel)
    if any(changes(log[f"commanded_wrench_{a}"], 1e-6) for a in AXES):
        panels.append("wrench")
    joints = sorted((int(k[len("nullspace_q_"):]) for k in log if k.startswith("nullspace_q_")))
    if any(changes(log[f"commanded_nullspace_q_{j}"], 1e-6) for j in joints):
        panels.append("nullspace")
    figure, axes_list = plt.subplots(len(panels), 1,
                                     figsize=(width_for(log) + 2, 2.6 * len(panels)),
                                     sharex=True, squeeze=False)
    axes_list = [a[0] for a in axes_list]
    for axes, panel in zip(axes_list, panels):
        if panel == "position":
            # From where the reference started, in mm: a 19 mm sag or a 40 mm push is plain to
            # see, which it is not on a scale from 0 to the arm's 0.6 m reach.
            values = []
            for axis, colour in zip(AXES, COLOURS):
                start = log[f"commanded_{axis}"][0]
                for key, style, what in ((f"commanded_{axis}", "--", "commanded"),
                                         (f"reference_{axis}", "-", "filtered"),
                                         (axis, ":", "flange")):
                    shifted = [1e3 * (v - start) for v in log[key]]
                    axes.plot(t, shifted, style, color=colour, label=f"{what} {axis}")
                    values += shifted
            floor_range(axes, values, 1.0)
            axes.set_ylabel("position from the\nfirst reference [mm]")
            axes.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        elif panel.endswith("stiffness"):
            rotation = panel.startswith("rotation")
            suffixes = ("rx", "ry", "rz") if rotation else AXES
            for suffix, colour in zip(suffixes, COLOURS):
                axes.plot(t, log[f"commanded_stiffness_{suffix}"], "--", color=colour,
                          label=f"commanded {suffix}")
                axes.plot(t, log[f"stiffness_{suffix}"], color=colour, label=f"filtered {suffix}",
                          linewidth=1)
            axes.set_ylabel("K rotation [Nm/rad]" if rotation else "K translation [N/m]")
            floor_range(axes, [v for s in suffixes for v in log[f"stiffness_{s}"]],
                        10.0 if rotation else 100.0)
            axes.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        elif panel == "wrench":
            for axis, colour in zip(AXES, COLOURS):
                axes.plot(t, log[f"commanded_wrench_{axis}"], "--", color=colour,
                          label=f"commanded {axis}")
                axes.plot(t, log[f"wrench_{axis}"], color=colour, label=f"filtered {axis}",
                          linewidth=1)
            axes.set_ylabel("commanded force [N]")
            axes.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
        else:
            for j in joints:
                line = axes.plot(t, log[f"commanded_nullspace_q_{j}"], "--", linewidth=1,
                                 label=f"target {j}")
                axes.plot(t, log[f"q_{j}"], color=line[0].get_color(), linewidth=1,
                          label=f"q {j}")
            axes.set_ylabel("nullspace target\n(dashed) and q [rad]")
            axes.legend(fontsize="xx-small", ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes_list[-1].set_xlabel("time [s]")
    shade_phases(axes_list, log, axes_list[0])
    axes_list[0].set_title(f"{name}: targets as commanded (dashed) and filtered (solid); "
                           "flange (dotted)", fontsize=10)
    save(figure, out / f"{name}_targets.png")


def plot_force(name, log, out):
    if not any(abs(value) > 1e-9 for value in log["contact_z"]):
        return
    t = log["time"]
    figure, axes = plt.subplots(figsize=(8, 3.8))
    contact = log["contact_z"]
    axes.plot(t, contact, label="contact force on the tip, z (measured)", linewidth=1)
    axes.plot(t, [-value for value in log["wrench_z"]], "--", label="commanded force (down)")
    axes.set_xlabel("time [s]")
    axes.set_ylabel("contact force [N]")
    peak = max(range(len(contact)), key=lambda i: contact[i])
    settled = contact[-1]
    if contact[peak] > 1.5 * max(abs(settled), 1.0):
        # The tip starts 3 cm above the table with no vertical spring: the commanded force
        # accelerates it, and it lands with momentum that the table stops in a few milliseconds.
        axes.annotate(f"peak {contact[peak]:.0f} N at t = {t[peak]:.2f} s (sampled every 10 ms):\n"
                      "the tip lands on the "
                      "table (impact),\nthen the force settles to the commanded one",
                      xy=(t[peak], contact[peak]), xytext=(0.35, 0.6),
                      textcoords="axes fraction", fontsize=8,
                      arrowprops={"arrowstyle": "->", "color": "0.3"})
        # The impact would flatten the rest: show the settled force with room around it.
        axes.set_ylim(-2, max(3 * settled, settled + 10, contact[peak] * 1.05))
    shade_phases((axes,), log)
    axes.legend(fontsize="small", loc="lower right")
    axes.set_title(f"{name}: force between the tip and the table")
    save(figure, out / f"{name}_force.png")


def plot_log(name, log, out):
    plot_pose_error(name, log, out)
    plot_torques(name, log, out)
    plot_targets(name, log, out)
    plot_force(name, log, out)


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


def plot_grid(path, out):
    """The stability grid as a map: one cell per stiffness pair, green if it converged with its
    energy (less the work of the torque limits) never above what the step put in, red if not; the
    text gives the numbers."""
    grid = read(path)
    if not grid:
        return
    translations = sorted(set(grid["translation_stiffness"]))
    rotations = sorted(set(grid["rotation_stiffness"]))
    figure, axes = plt.subplots(figsize=(7.5, 6))
    for i in range(len(grid["converged"])):
        column = translations.index(grid["translation_stiffness"][i])
        row = rotations.index(grid["rotation_stiffness"][i])
        ok = grid["converged"][i] > 0.5
        axes.add_patch(plt.Rectangle((column - 0.5, row - 0.5), 1, 1, edgecolor="white",
                                     linewidth=3, facecolor="#b9e4b0" if ok else "#f4b6b0"))
        text = (f"{'stable' if ok else 'NOT stable'}\nerror {grid['error_mm'][i]:.2f} mm\n"
                f"energy x{grid['energy_ratio'][i]:.3f}")
        if grid["torque_limited"][i] > 0.5:
            text += "\n(torque or rate limited:\ntheir work counted)"
        axes.text(column, row, text, ha="center", va="center", fontsize=8)
    axes.set_xlim(-0.5, len(translations) - 0.5)
    axes.set_ylim(-0.5, len(rotations) - 0.5)
    axes.set_xticks(range(len(translations)), [f"{k:g}" for k in translations])
    axes.set_yticks(range(len(rotations)), [f"{k:g}" for k in rotations])
    axes.set_xlabel("translational stiffness [N/m]")
    axes.set_ylabel("rotational stiffness [Nm/rad]")
    axes.set_title("stability grid: a 3 cm + 0.05 rad reference step at each stiffness\n"
                   "error after 2.5 s; energy: peak of spring + kinetic - work of the torque\n"
                   "limits, over what the step put in (<= 1.05)",
                   fontsize=10)
    save(figure, out / "stability_grid_map.png")


def plot_two_arms(path, out):
    """Each arm's flange displacement from its start: the pushed left arm moves, the right one
    beside it does not, then the right one steps while the left one stays."""
    motion = read(path)
    if not motion:
        return
    names = {0.0: "", 1.0: "left arm pushed", 2.0: "released",
             3.0: "right arm: reference step 5 cm"}
    log = {"time": motion["time"], "phase": [names.get(float(p), "") for p in motion["phase"]]}
    figure, (left, right) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for axes, arm, title in ((left, "left", "left arm"), (right, "right", "right arm")):
        values = []
        for axis, colour in zip(AXES, COLOURS):
            axes.plot(motion["time"], motion[f"{arm}_d{axis}_mm"], color=colour, label=axis)
            values += motion[f"{arm}_d{axis}_mm"]
        floor_range(axes, values, 1.0)
        axes.set_ylabel(f"{title}\nflange motion [mm]")
        axes.legend(fontsize="small", loc="lower left")
    shade_phases((left, right), log, left)
    right.set_xlabel("time [s]")
    left.set_title("two arms, one scene, two controllers: each arm's flange from its start")
    save(figure, out / "two_arms_motion.png")


def plot_energy_tank(path, out):
    """Issue 30's stiffness schedule with and without the energy tank: the pose error, the total
    energy (kinetic + spring + tank) of each run, and what the total is made of with the tank."""
    log = read(path)
    if not log:
        return
    t = log["time"]
    figure, (error, total, parts) = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    error.plot(t, log["without_error_mm"], color="tab:red", linewidth=1, label="without the tank")
    error.plot(t, log["with_error_mm"], color="tab:blue", linewidth=1.5, label="with the tank")
    bound = log["with_error_mm"][0] + 2.0
    error.axhline(bound, color="k", linestyle="--", linewidth=1,
                  label=f"initial error + 2 mm = {bound:.1f} mm (issue 30's bound)")
    error.set_ylabel("pose error |e| [mm]")
    error.legend(fontsize="small", loc="upper left")
    soft, stiff = min(log["without_stiffness"]), max(log["without_stiffness"])
    error.set_title(f"energy tank: {soft:.0f} N/m while |e| grows, {stiff:.0f} N/m while it "
                    f"shrinks, from a {log['with_error_mm'][0]:.0f} mm offset", fontsize=10)
    total.semilogy(t, log["without_total"], color="tab:red", linewidth=1,
                   label="without the tank: kinetic + spring")
    total.semilogy(t, log["with_total"], color="tab:blue", linewidth=1.5,
                   label="with the tank: kinetic + spring + tank")
    total.axhline(log["with_total"][0], color="tab:blue", linestyle=":", linewidth=1,
                  label=f"with the tank at the start: {1e3 * log['with_total'][0]:.1f} mJ")
    total.set_ylabel("total energy [J]")
    total.legend(fontsize="small", loc="upper left")
    millijoules = {key: [1e3 * v for v in log[f"with_{key}"]]
                   for key in ("kinetic", "spring", "tank")}
    parts.stackplot(t, millijoules["kinetic"], millijoules["spring"], millijoules["tank"],
                    colors=("#f4b6b0", "#b9e4b0", "#b0c8f4"),
                    labels=("kinetic 1/2 dq^T M dq", "spring 1/2 e^T K e", "tank level"))
    parts.set_ylabel("with the tank [mJ]")
    parts.set_xlabel("time since the schedule started [s]")
    parts.legend(fontsize="small", loc="upper right")
    save(figure, out / "energy_tank_energy.png")


def plot_safety_force(path, out):
    """Contact force on the table with and without the caps, for the reference that jumps 5 cm
    into the table and for the one moved there at 0.1 m/s, with the force cap drawn."""
    log = read(path)
    if not log:
        return
    t = log["time"]
    cap = log["cap"][0]
    figure, panels = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    for axes, case, title in ((panels[0], "jump", "reference jumps 5 cm into the table"),
                              (panels[1], "ramp", "reference moved there at 0.1 m/s")):
        free, capped = log[f"{case}_without_caps"], log[f"{case}_with_caps"]
        axes.plot(t, free, color="tab:red", linewidth=1, label="without caps")
        axes.plot(t, capped, color="tab:blue", linewidth=1.2,
                  label="with the caps (0.1 m/s, force cap)")
        axes.axhline(cap, color="tab:blue", linestyle="--", linewidth=0.8,
                     label=f"force cap {cap:.3g} N")
        for values, colour in ((free, "tab:red"), (capped, "tab:blue")):
            finite = [(v, i) for i, v in enumerate(values) if math.isfinite(v)]
            peak, at = max(finite)
            settled = [v for v, _ in finite[-500:]]  # the run's last 0.5 s
            axes.annotate(f"peak {peak:.0f} N, settled {sum(settled) / len(settled):.1f} N",
                          xy=(t[at], peak), xytext=(8, 10 if colour == "tab:blue" else -4),
                          textcoords="offset points", fontsize=8, color=colour,
                          va="bottom" if colour == "tab:blue" else "top")
        axes.set_ylabel("contact force [N]")
        axes.set_title(title, fontsize=10)
        axes.legend(fontsize="small", loc="center right")
    panels[1].set_xlabel("time [s] (every 1 ms cycle)")
    figure.suptitle("safety: contact force on a table 10 cm under the flange, 3000 N/m")
    save(figure, out / "safety_contact_force.png")


def plot_safety_speed(path, out):
    """Flange speed under a 300 mm reference jump without and with the speed cap, a trajectory
    twice as fast as the cap, a commanded force in free space and a push from outside."""
    log = read(path)
    if not log:
        return
    t = log["time"]
    cap, push_cap = log["cap"][0], log["push_cap"][0]
    figure, axes = plt.subplots(figsize=(9, 4.5))
    for key, colour, label in (("jump_without_cap", "tab:red", "reference jump, no cap"),
                               ("jump_with_cap", "tab:blue", "reference jump, cap"),
                               ("trajectory_with_cap", "tab:purple", "trajectory at 2 x cap"),
                               ("wrench_with_cap", "tab:green", "commanded force, no spring"),
                               ("push_with_cap", "tab:orange", "pushed from outside (teaching)")):
        axes.plot(t, log[key], color=colour, linewidth=1, label=label)
    axes.axhline(cap, color="0.3", linestyle="--", linewidth=0.8, label=f"cap {cap:.2g} m/s")
    axes.axhline(1.1 * cap, color="0.3", linestyle=":", linewidth=0.8, label="1.1 x cap")
    if abs(push_cap - cap) > 1e-9:
        axes.axhline(push_cap, color="tab:orange", linestyle="--", linewidth=0.8,
                     label=f"push's cap {push_cap:.2g} m/s")
    axes.axhline(log["push_unbraked"][0], color="tab:orange", linestyle=":", linewidth=0.8,
                 label="push without the brake (F / d)")
    axes.set_xlabel("time since the command [s]")
    axes.set_ylabel("flange speed [m/s]")
    axes.legend(fontsize="small", loc="upper right")
    axes.set_title("safety: flange speed (ground truth, every cycle); the push from outside is "
                   "braked, not stopped", fontsize=10)
    save(figure, out / "safety_speed.png")


def plot_safety_workspace(path, out):
    """The box and the flange's path: along the wall's normal over time (pushed toward the wall
    while teaching; sent to a reference outside the box), and in the plane of that normal and z
    (base frame), with the box's face."""
    log = read(path)
    if not log:
        return
    axis = int(log["axis"][0])
    other = 2 if axis != 2 else 0
    names = "xyz"
    a, b = names[axis], names[other]
    low, high = log[f"min_{a}"][0], log[f"max_{a}"][0]
    figure, (along, plane) = plt.subplots(2, 1, figsize=(9, 7.5),
                                          gridspec_kw={"height_ratios": [3, 2]})
    runs = ((0.0, "tab:orange", "flange, pushed 20 N toward the wall while teaching"),
            (1.0, "tab:blue", "flange, sent to a reference 10 cm outside"))
    values = []
    for run, colour, label in runs:
        rows = [i for i, r in enumerate(log["run"]) if r == run]
        t0 = log["time"][rows[0]]
        t = [log["time"][i] - t0 for i in rows]
        along.plot(t, [1e3 * log[a][i] for i in rows], color=colour, linewidth=1.5, label=label)
        plane.plot([1e3 * log[a][i] for i in rows], [1e3 * log[b][i] for i in rows],
                   color=colour, linewidth=1.5)
        values += [1e3 * log[a][i] for i in rows]
        if run == 1.0:
            along.plot(t, [1e3 * log[f"reference_{a}"][i] for i in rows], "--", color=colour,
                       linewidth=1, label="its reference as the law used it (clipped)")
            requested = 1e3 * log[f"requested_{a}"][rows[0]]
            along.axhline(requested, color=colour, linestyle=":", linewidth=1,
                          label=f"its reference as requested ({requested:.0f} mm)")
            plane.plot(requested, 1e3 * log[f"requested_{b}"][rows[0]], "x", color=colour,
                       markersize=9, label="reference requested")
            values.append(requested)
    view = (min(values) - 15, max(values) + 15)
    for axes, vertical in ((along, False), (plane, True)):
        for face in (low, high):
            if view[0] < 1e3 * face < view[1]:
                (axes.axvline if vertical else axes.axhline)(
                    1e3 * face, color="tab:red", linewidth=2, label="face of the workspace box")
        inside = (max(view[0], 1e3 * low), min(view[1], 1e3 * high))
        for start, end in ((view[0], inside[0]), (inside[1], view[1])):
            if end > start:
                (axes.axvspan if vertical else axes.axhspan)(start, end, color="tab:red",
                                                            alpha=0.08, linewidth=0)
    along.set_ylim(*view)
    along.set_xlabel("time since the push / the reference [s]")
    along.set_ylabel(f"flange {a} [mm], base frame")
    along.legend(fontsize="small", loc="center right")
    along.set_title("safety: the workspace wall (red; shaded: outside the box) stops the "
                    "flange; a reference outside is clipped onto the face", fontsize=10)
    plane.set_xlim(*view)
    plane.set_aspect("equal", adjustable="datalim")
    plane.set_xlabel(f"{a} [mm], base frame")
    plane.set_ylabel(f"{b} [mm]")
    plane.legend(fontsize="small", loc="upper left")
    plane.set_title(f"the flange's path in the {a}-{b} plane", fontsize=10)
    save(figure, out / "safety_workspace.png")


def plot_collision_residuals(path, out):
    """The swing without a reaction: per joint, the part of the momentum observer's estimate
    nobody expected against its threshold, with the first contact and the detection marked."""
    log = read(path)
    if not log:
        return
    t = log["time"]
    joints = sorted(int(key.split("_")[1]) for key in log if key.startswith("unexpected_"))
    contact = next((t[i] for i, f in enumerate(log["contact_force"]) if f > 0.0), None)
    found = next((t[i] for i, d in enumerate(log["detected"]) if d > 0.5), None)
    figure, panels = plt.subplots(len(joints), 1, figsize=(9, 1.35 * len(joints) + 1.2),
                                  sharex=True)
    for axes, joint in zip(panels, joints):
        axes.plot(t, log[f"unexpected_{joint}"], color="tab:blue", linewidth=1,
                  label="|unexpected external torque|")
        axes.plot(t, log[f"threshold_{joint}"], color="tab:red", linestyle="--", linewidth=1,
                  label="threshold")
        for when, colour in ((contact, "tab:orange"), (found, "k")):
            if when is not None:
                axes.axvline(when, color=colour, linewidth=0.8, linestyle=":")
        axes.set_ylabel(f"joint {joint}\n[Nm]", fontsize=8)
        axes.tick_params(labelsize=7)
    panels[0].legend(fontsize="x-small", loc="upper left", ncol=2)
    title = "collision: the swing without a reaction, per joint"
    if contact is not None and found is not None:
        title += (f"; first contact (orange) at {contact:.3f} s, found (black) "
                  f"{1e3 * (found - contact):.0f} ms later")
    panels[0].set_title(title, fontsize=9)
    panels[-1].set_xlabel("time since the reference was sent [s] (every 1 ms cycle)")
    save(figure, out / "collision_residuals.png")


def plot_collision_force(path, out):
    """The contact force on the arm from 50 ms before its first contact, for each reaction."""
    log = read(path)
    if not log:
        return
    t = log["time_since_contact"]
    figure, (whole, late) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    colours = {"report": "tab:red", "stop": "tab:blue", "reflex": "tab:green",
               "retract": "tab:purple"}
    for reaction, colour in colours.items():
        if reaction not in log:
            continue
        values = log[reaction]
        finite = [v for v in values if math.isfinite(v)]
        late_values = [v for v, when in zip(values, t) if when >= 0.1 and math.isfinite(v)]
        label = (f"{reaction}: impact {max(finite[:61] or [0]):.0f} N, then at most "
                 f"{max(late_values or [0]):.1f} N")
        whole.plot(t, values, color=colour, linewidth=1.2 if reaction != "report" else 1,
                   label=label)
        late.plot(t, values, color=colour, linewidth=1.2, label=reaction)
    soft = {key: colour for key, colour in (("soft_report", "tab:red"), ("soft_stop", "tab:blue"),
                                            ("soft_retract", "tab:purple")) if key in log}
    for key, colour in soft.items():
        whole.plot(t, log[key], color=colour, linewidth=1, linestyle="--",
                   label=f"{key.replace('_', ' box, ')} (dashed)")
        late.plot(t, log[key], color=colour, linewidth=1, linestyle="--")
    whole.set_ylabel("contact force on the arm [N]")
    whole.set_title("collision: the force with and without each reaction (collision.reaction)",
                    fontsize=10)
    whole.legend(fontsize="small", loc="upper right")
    late.set_yscale("symlog", linthresh=1.0)
    late.axvline(0.1, color="k", linewidth=0.8, linestyle=":")
    late.set_ylabel("the same, symlog [N]")
    late.set_xlabel("time since the first contact [s] (every 1 ms cycle); dotted: 0.1 s "
                    "(the clamping force is measured from 0.1 s after the detection)")
    save(figure, out / "collision_force.png")


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = pathlib.Path(sys.argv[1])
    tables = {"stability_grid_grid.csv": plot_grid, "two_arms_motion.csv": plot_two_arms,
              "safety_force.csv": plot_safety_force, "safety_speed.csv": plot_safety_speed,
              "safety_workspace.csv": plot_safety_workspace,
              "energy_tank_energy.csv": plot_energy_tank,
              "collision_residuals.csv": plot_collision_residuals,
              "collision_force.csv": plot_collision_force}
    for path in sorted(out.glob("*.csv")):
        if path.name in tables:
            tables[path.name](path, out)
        elif path.name != "summary.csv":
            log = read(path)
            if log and "phase" in log:
                plot_log(path.stem, log, out)
    plot_sweep(out)


if __name__ == "__main__":
    main()
