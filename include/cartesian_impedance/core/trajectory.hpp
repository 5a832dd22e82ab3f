#pragma once
/// @file
/// Joint-space trajectories: the message as a user sends it (joint names in any order), its
/// validation into a preallocated buffer, and sampling by cubic Hermite interpolation, which has
/// continuous position and velocity. Validation allocates and throws; sampling does neither.

#include <string>
#include <vector>

#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// A trajectory as received: like trajectory_msgs/JointTrajectory.
struct JointTrajectory {
  std::vector<std::string> joint_names;        ///< any order, each joint of the arm exactly once
  std::vector<double> times;                   ///< time from start of each point [s], increasing
  std::vector<std::vector<double>> positions;  ///< per point, in joint_names order [rad or m]
  /// Optional: per point, in joint_names order [rad/s or m/s]. Empty: velocities are chosen so
  /// the path is smooth (finite differences of neighbouring points, zero at both ends).
  std::vector<std::vector<double>> velocities;
};

/// What a trajectory must keep, per joint of the arm in its order: the position limits on the
/// whole interpolated path (not only at the waypoints) and the speed limits.
struct TrajectoryLimits {
  JointVector lower;     ///< [rad or m]
  JointVector upper;     ///< [rad or m]
  JointVector velocity;  ///< |dq| bound [rad/s or m/s]; +inf where there is none
};

/// The state a trajectory will start from (its first segment runs from here to its first point).
struct TrajectoryStartState {
  JointVector q;   ///< [rad or m]
  JointVector dq;  ///< [rad/s or m/s]
};

/// A validated trajectory in the arm's joint order, in storage sized once. Point 0 is the state
/// the trajectory starts from (filled when execution begins), so a new trajectory continues from
/// where the previous command was, without a jump.
class TrajectoryBuffer {
 public:
  /// Storage for up to `max_points` points (plus the start point) of `num_joints` joints.
  TrajectoryBuffer(int num_joints, int max_points);

  /// Validates `trajectory` for an arm with these joints and limits, reorders it into the arm's
  /// joint order and stores it, with the velocities derived if none are given (all but that of
  /// the first point, which depends on the start state). A point at time 0 is taken as the start
  /// state, which execution replaces by the actual one. The path between the points is checked
  /// too: on every segment the interpolated position stays within the limits and the
  /// interpolated speed within the velocity limit; the first segment, from the start state to the
  /// first point, when `start` says where that will be.
  /// @throws Error naming the point (or segment), joint and value for: unknown, missing or
  ///         repeated joint names, wrong sizes, non-finite values, times not strictly increasing
  ///         or not positive, positions outside the limits, a given velocity above the velocity
  ///         limit, a segment whose interpolation leaves the position limits or exceeds the
  ///         velocity limit, more than max_points points, none at all.
  void assign(const JointTrajectory& trajectory, const std::vector<std::string>& joint_names,
              const TrajectoryLimits& limits, const TrajectoryStartState* start = nullptr);
  /// assign() with position limits only (no speed limit, the first segment unchecked).
  void assign(const JointTrajectory& trajectory, const std::vector<std::string>& joint_names,
              const JointVector& lower, const JointVector& upper);

  /// Sets point 0 to the state execution starts from and, if velocities were not given, derives
  /// the first point's. noexcept, no allocation, the same cost for any number of points.
  void begin(const JointVector& q_start, const JointVector& dq_start) noexcept;

  /// Position and velocity at `time` [s] since begin(); before 0 and after the end the trajectory
  /// holds its first and last point with zero velocity past the end. noexcept, no allocation.
  void sample(double time, JointVector& q, JointVector& dq) const noexcept;

  int num_joints() const noexcept { return num_joints_; }
  int num_points() const noexcept { return num_points_; }  ///< including the start point
  int max_points() const noexcept { return max_points_; }
  double duration() const noexcept { return num_points_ > 0 ? times_[num_points_ - 1] : 0.0; }

 private:
  int num_joints_;
  int max_points_;
  int num_points_ = 0;
  bool velocities_given_ = false;
  std::vector<double> times_;
  Eigen::MatrixXd positions_;   // num_joints x (max_points + 1)
  Eigen::MatrixXd velocities_;  // num_joints x (max_points + 1)
};

}  // namespace cartesian_impedance
