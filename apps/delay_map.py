#!/usr/bin/python3
"""The stiffness an arm holds behind a delay: a measured map, per shipped robot and damping design.

Each cell is one run on the realistic plant (sim.Plant.realistic: model error, noise, 1 ms of
actuation delay) with the measurement delay of its column: a 5 cm reference step along x at the
stiffness of its row (rotation a tenth of it, in Nm/rad), 12 s, the controller told the loop's
delay (safety.passivity.delay). The passivity controller halves the springs that generate energy,
and the oscillation watch what still oscillates; the cell shows how many times the translation's
and the rotation's stiffness were halved (0/0: the loop held the stiffness as commanded) and
whether the arm was at rest in the last second. Writes docs/images/delay_map.png and prints the
map as Markdown.

    PYTHONPATH=build/python /usr/bin/python3 apps/delay_map.py [--out FILE]
"""

import argparse
import math
import pathlib

import numpy as np

import cartesian_impedance as ci

SOURCE = pathlib.Path(__file__).resolve().parent.parent
ROBOTS = {  # name: (URDF, MJCF, base link, tip link)
    "panda": ("panda/panda.urdf", "panda/panda.xml", "panda_link0", "panda_link8"),
    "iiwa14": ("iiwa14/iiwa14.urdf", "iiwa14/iiwa14.xml", "iiwa_link_0", "iiwa_link_ee"),
}
STIFFNESS = [300.0, 1000.0, 3000.0]  # [N/m]; rotation: a tenth, in Nm/rad
DELAYS_MS = [0, 1, 2, 4, 8, 16, 32, 64]  # measurement delay; the plant adds 1 ms of actuation
SECONDS = 12.0
SETTLED_SPEED = 0.05  # [rad/s] the realistic plant's noise keeps a settled arm below 0.02


def run_cell(robot, model, shaped, stiffness, delay):
    _, mjcf, _, _ = ROBOTS[robot]
    plant = ci.sim.Plant.realistic(seed=1)
    plant.measurement_delay = delay
    sim = ci.sim.Simulation.from_mjcf_file(SOURCE / "models" / mjcf, plant=plant)
    loop = ci.ControlLoop(model, {"stiffness.translation": stiffness,
                                  "stiffness.rotation": stiffness / 10.0,
                                  "dynamics.inertia_shaped_damping": shaped,
                                  "safety.passivity.delay": delay + plant.actuation_delay})
    loop.start(sim.q, sim.dq)
    pose = loop.state.controller.pose
    loop.set_reference_pose((np.asarray(pose.position) + [0.05, 0.0, 0.0], pose.orientation))
    sim.run(loop, SECONDS - 1.0)
    fastest = 0.0
    ok = True
    for _ in range(100):
        sim.run(loop, 0.01)
        fastest = max(fastest, float(np.abs(sim.true_dq).max()))
        ok = ok and loop.state.controller.status == ci.Status.ok
    safety = loop.state.controller.safety
    kept = safety.oscillation_scale * np.asarray(safety.passivity_scale)
    translation, rotation = (round(-math.log2(k)) for k in kept[:2])
    return translation, rotation, ok and fastest <= SETTLED_SPEED


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(SOURCE / "docs" / "images" / "delay_map.png"))
    args = parser.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    designs = [(True, "inertia-shaped damping (default)"), (False, "unit-mass damping")]
    fig, axes = plt.subplots(len(ROBOTS), len(designs), figsize=(11, 3.2 * len(ROBOTS)),
                             squeeze=False)
    print("| robot | damping | stiffness [N/m] | " +
          " | ".join(f"{d} ms" for d in DELAYS_MS) + " |")
    print("|---|---|---|" + "---|" * len(DELAYS_MS))
    for row, (robot, (urdf, _, base, tip)) in enumerate(ROBOTS.items()):
        model = ci.RobotModel.from_urdf_file(SOURCE / "models" / urdf, base, tip)
        for column, (shaped, title) in enumerate(designs):
            grid = np.zeros((len(STIFFNESS), len(DELAYS_MS)))
            ax = axes[row][column]
            for i, stiffness in enumerate(STIFFNESS):
                cells = []
                for j, delay_ms in enumerate(DELAYS_MS):
                    translation, rotation, settled = run_cell(robot, model, shaped, stiffness,
                                                              delay_ms * 1e-3)
                    grid[i, j] = translation
                    text = f"{translation}/{rotation}" + ("" if settled else "*")
                    cells.append(text)
                    ax.text(j, i, text, ha="center", va="center", fontsize=8,
                            color="white" if translation >= 4 else "black")
                print(f"| {robot} | {'inertia-shaped' if shaped else 'unit-mass'} | "
                      f"{stiffness:.0f} | " + " | ".join(cells) + " |")
            ax.imshow(grid, cmap="Reds", vmin=0, vmax=8, aspect="auto", origin="lower")
            ax.set_xticks(range(len(DELAYS_MS)), [str(d) for d in DELAYS_MS])
            ax.set_yticks(range(len(STIFFNESS)), [f"{k:.0f}" for k in STIFFNESS])
            ax.set_xlabel("measurement delay [ms] (+1 ms actuation)")
            ax.set_ylabel("commanded stiffness [N/m]")
            ax.set_title(f"{robot}, {title}", fontsize=10)
    fig.suptitle("Halvings of the translation / rotation stiffness a 5 cm step needed to settle\n"
                 "(colour: translation; 0/0: held as commanded; * not at rest after 12 s; "
                 "realistic plant)", fontsize=11)
    fig.tight_layout()
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
