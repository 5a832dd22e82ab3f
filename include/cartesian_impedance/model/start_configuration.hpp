#pragma once
/// @file
/// A start configuration the library chooses itself, for a robot given by its URDF alone: the
/// simulation of a URDF would otherwise start at q = 0, where most arms are singular (stretched
/// out or folded on themselves) and every Cartesian motion fails.
///
/// The score of a configuration q (largest is best) is
///
///     score(q) = sigma_min(S J(q)) * limits(q) * ready(q)
///
/// - sigma_min(S J): the smallest singular value of the 6 x n Jacobian with its translation rows
///   divided by the arm's reach L (S = diag(I/L, I)), so that moving the flange by its reach and
///   turning it by a radian weigh the same: the direction in which the arm moves worst, in
///   units that do not depend on the arm's size. Far from every singularity, there is room to
///   move and to turn in every direction, which is what a Cartesian controller needs.
/// - limits(q) in [0, 1]: per joint 0 at limit_margin from a position limit (where
///   check_configuration() warns), rising linearly to 1 a quarter of the way to the middle of its
///   range; the product over the joints. Continuous joints count 1.
/// - ready(q) in [0.07, 1]: a preference for a "ready" pose, because the demo's scenarios push
///   the flange along x, y and z, step the reference by 10 cm and press on a table (0.3 m wide,
///   standing on the floor) below the flange, so a start needs room in every direction: the
///   flange 25 % to 60 % of the reach out from the base's vertical axis (clear of the base, a
///   table fits under it) and 20 % to 60 % of the reach above the base (a push down does not
///   reach the floor), 35 % to 80 % of the reach from the base origin (neither folded nor
///   stretched), in front of the base (+x), the tool's z axis pointing down (the table is met
///   by the tool, not by the side of the last link; pointing away from the base counts half).
///   Each factor is 1 in its band and falls linearly to 0.5 to 0.8 outside it; "up" is
///   against the model's gravity, so an arm mounted sideways keeps the meaning. A factor that
///   no configuration can change (a planar arm's height) leaves the choice to the others.
///
/// The search: `samples` configurations drawn uniformly within the limits minus limit_margin
/// (continuous joints in [-pi, pi]) from a fixed seed, the `refined` best of them improved by a
/// coordinate search (steps of 0.2 rad or a tenth of the range, halved until 1e-3 rad), and the
/// best result that check_configuration() would not warn about. Deterministic: the same model
/// and options give the same q on every run and machine (the random numbers are drawn without
/// the standard library's distributions, whose results differ between implementations).

#include <cstdint>
#include <string>

#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace cartesian_impedance {

/// How find_start_configuration() searches; the defaults suit arms of up to 7 joints (well
/// under a second).
struct StartSearch {
  int samples = 2000;       ///< random configurations drawn within the limits (>= 1)
  int refined = 4;          ///< best samples improved by the local search (>= 1)
  std::uint64_t seed = 29;  ///< of the random configurations
  /// Below this smallest singular value of the Jacobian a configuration is not accepted
  /// (check_configuration()'s default: a start chosen here never triggers its warning).
  double singular_threshold = 0.02;
  /// Joints within this distance of a position limit are not accepted [rad or m]
  /// (check_configuration()'s default).
  double limit_margin = 0.1;
};

/// The configuration find_start_configuration() chose, and why.
struct StartChoice {
  JointVector q;  ///< [rad or m], one per joint of the model, within its limits
  /// Smallest singular value of the Jacobian at q, as check_configuration() computes it
  /// (unscaled rows: m/rad and rad/rad).
  double smallest_singular_value = 0.0;
  /// The same with the translation rows divided by `reach`: comparable between arms.
  double scaled_singular_value = 0.0;
  /// Distance of the joint nearest a position limit [rad or m]; +inf if no joint is limited.
  double limit_distance = 0.0;
  double reach = 0.0;  ///< L [m]: the farthest the flange got from the base origin in the search
  double score = 0.0;  ///< the score above (dimensionless)
  Eigen::Vector3d flange_position = Eigen::Vector3d::Zero();  ///< at q, base frame [m]
  /// One line for a log: singular value, limit distance, where the flange is.
  std::string description;
};

/// Chooses a well-conditioned start configuration for `model` within its joint limits (see the
/// score and the search at the top of this file).
/// @throws Error if the options are invalid (naming the field and value), or if no
///         configuration found has a smallest singular value of at least singular_threshold and
///         every joint at least limit_margin inside its limits (naming the best singular value
///         found): give a start yourself then.
StartChoice find_start_configuration(const RobotModel& model, const StartSearch& options = {});

}  // namespace cartesian_impedance
