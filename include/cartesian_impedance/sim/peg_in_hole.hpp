#pragma once
/// @file
/// Peg-in-hole scenes: a square hole in a block built from static boxes, and a robot holding a
/// square peg at its flange (an AttachedBox) with such a hole in front of it. For insertion
/// tasks, tests and learning environments; on MuJoCo and on DART (with a URDF robot).
///
/// Frames: world frame as everywhere in the simulation (the robot's base at the origin for the
/// project's robot files).

#include <string>
#include <vector>

#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::sim {

/// A blind (or through) square hole in a block. The block is four walls around the hole and a
/// floor below it, each a static Box.
struct SquareHole {
  /// Centre of the hole's opening in the block's top face, world frame. Its z axis points out of
  /// the hole (up for a hole in a table), its x and y axes along the hole's sides: the peg's
  /// sides must line up with them to go in.
  Pose opening;
  double peg_half_width = 0.0125;  ///< half the width of the square peg it takes [m], > 0
  /// Hole width minus peg width [m], >= 0: a centred peg has clearance / 2 on each side, and one
  /// offset by more than that along x or y lands on the block's top face.
  double clearance = 0.001;
  double depth = 0.04;  ///< from the opening to the hole's floor [m], > 0
  double wall = 0.05;   ///< block material beside the hole [m], > 0
  double floor = 0.02;  ///< block material below the hole [m], >= 0; 0: a through hole
  /// The boxes are named <name>_wall_x_plus, _wall_x_minus, _wall_y_plus, _wall_y_minus and
  /// <name>_floor.
  std::string name = "hole";
};

/// The static boxes of `hole` (four walls, and the floor unless hole.floor is 0), for
/// make_scene(). The walls along x are long enough to close the corners.
/// @throw Error naming the field if a value is not finite or out of its range, or the
///        orientation is not a unit quaternion.
std::vector<Box> hole_boxes(const SquareHole& hole);

/// A square peg at the flange and a hole, as make_peg_in_hole_scene() builds them.
struct PegInHole {
  /// The robot: a URDF (MuJoCo or DART) or an MJCF file (MuJoCo only).
  std::string robot;
  /// The body the peg is fixed to (the flange: "panda_link8", "iiwa_link_ee", "tool0").
  std::string flange;
  /// The hole; its peg_half_width is the peg's.
  SquareHole hole;
  /// The peg: a box of 2 hole.peg_half_width x 2 hole.peg_half_width x peg_length along the
  /// flange's z axis, from the flange face outwards, its sides along the flange's x and y axes.
  /// Its tip is at (0, 0, peg_length) in the flange frame.
  double peg_length = 0.1;  ///< [m], > 0
  /// [kg], > 0. Not compensated by the simulated firmware (AttachedBox): declare it to the
  /// controller as payload.mass with payload.center_of_mass = (0, 0, peg_length / 2).
  double peg_mass = 0.2;
  std::string peg_name = "peg";  ///< the peg's body and geom
};

/// The robot of `scene` holding its peg, with the hole's block in the world: make_scene(robot,
/// hole_boxes(hole), {peg}, options).
/// @throw Error as make_scene() and hole_boxes(), or naming peg_length or peg_mass.
Simulation make_peg_in_hole_scene(const PegInHole& scene, SimulationOptions options = {});

}  // namespace cartesian_impedance::sim
