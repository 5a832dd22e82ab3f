#!/usr/bin/python3
"""The speed power and force limiting allows, as the Panda reaches out: computed by the controller.

For each configuration of a sweep (the elbow, joint 4, opening from folded at -2.9 rad to
stretched at -0.5 rad, the other joints at the ready pose), the controller is given the arm's state with the flange moving
at 1 cm/s along x (radially, away from the base), y (sideways, a swing about the base) or z
(vertically), and reports what safety.pfl computes: the arm's effective mass at the flange along
that motion, m_R = 1 / u^T J M^-1 J^T u (the rotors' inertia, as in the robot's MJCF, included),
and the speed whose impact on the body region stays within the region's transient force limit,
v = F_T / sqrt(k mu), 1/mu = 1/m_H + 1/m_R (ISO/TS 15066, Annex A). Writes
docs/images/pfl_speed_map.png and prints the extremes.

    PYTHONPATH=build/python /usr/bin/python3 apps/pfl_speed_map.py [--out FILE]
"""

import argparse
import pathlib

import numpy as np

import cartesian_impedance as ci

SOURCE = pathlib.Path(__file__).resolve().parent.parent
READY = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
ARMATURE = np.array([0.1, 0.1, 0.1, 0.1, 0.04, 0.04, 0.04])  # models/panda/panda.xml
ELBOW = np.linspace(-2.9, -0.5, 49)  # joint 4 [rad], within its range
DIRECTIONS = {"x (radial)": 0, "y (sideways)": 1, "z (vertical)": 2}
REGIONS = ["skull", "chest", "hand"]


def limit(model, q, axis, region):
    """The controller's effective mass [kg] and speed limit [m/s] at q, moving along `axis`."""
    k = model.compute(q, np.zeros(7), True)
    jacobian = np.asarray(k.jacobian)
    direction = np.zeros(3)
    direction[axis] = 0.01
    dq = np.linalg.pinv(jacobian[:3]) @ direction
    k = model.compute(q, dq, True)
    mass = np.asarray(k.mass) + np.diag(ARMATURE)
    controller = ci.CartesianImpedanceController(
        7, {"safety.pfl.body_region": region, "dynamics.armature": ARMATURE.tolist()})
    robot = ci.RobotState(q, dq, k.pose, jacobian, mass=mass)
    controller.start(robot)
    controller.update(robot, 0.001)
    safety = controller.state.safety
    return safety.pfl_effective_mass, safety.pfl_speed_limit


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(SOURCE / "docs" / "images" / "pfl_speed_map.png"))
    args = parser.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    model = ci.RobotModel.from_urdf_file(SOURCE / "models" / "panda" / "panda.urdf",
                                         "panda_link0", "panda_link8")
    reach = ELBOW
    fig, axes = plt.subplots(1, 1 + len(REGIONS), figsize=(15, 3.8))
    for name, axis in DIRECTIONS.items():
        masses = [limit(model, np.r_[READY[:3], e, READY[4:]], axis, "chest")[0] for e in ELBOW]
        axes[0].plot(reach, masses, label=name)
        print(f"effective mass along {name}: {min(masses):.2f}-{max(masses):.2f} kg")
        for column, region in enumerate(REGIONS, start=1):
            speeds = [limit(model, np.r_[READY[:3], e, READY[4:]], axis, region)[1]
                      for e in ELBOW]
            axes[column].plot(reach, speeds, label=name)
            print(f"  {region:5s} along {name}: {min(speeds):.3f}-{max(speeds):.3f} m/s")
    axes[0].set_title("Panda's effective mass at the flange")
    axes[0].set_ylabel("m_R [kg]")
    for column, region in enumerate(REGIONS, start=1):
        axes[column].set_title(f"speed limit, body region '{region}'")
        axes[column].set_ylabel("v [m/s]")
        axes[column].set_ylim(bottom=0.0)
    for ax in axes:
        ax.set_xlabel("elbow, joint 4 [rad] (folded -> stretched)")
        ax.grid(True, alpha=0.3)
        ax.legend(title="motion along", fontsize=8)
    fig.suptitle("Power and force limiting (ISO/TS 15066): v = F_T / sqrt(k mu), "
                 "1/mu = 1/m_H + 1/m_R, as the elbow opens (joint 4 from -2.9 to -0.5 rad)")
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
