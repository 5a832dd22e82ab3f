#include "cartesian_impedance/core/trajectory.hpp"

#include <algorithm>
#include <cmath>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"

namespace cartesian_impedance {

TrajectoryBuffer::TrajectoryBuffer(int num_joints, int max_points)
    : num_joints_(num_joints), max_points_(max_points) {
  if (num_joints < 1 || num_joints > kMaxJoints) {
    throw Error("trajectory num_joints = " + std::to_string(num_joints) + " is outside [1, " +
                std::to_string(kMaxJoints) + "]");
  }
  if (max_points < 1) {
    throw Error("trajectory max_points = " + std::to_string(max_points) + " must be at least 1");
  }
  times_.assign(static_cast<std::size_t>(max_points) + 1, 0.0);
  positions_ = Eigen::MatrixXd::Zero(num_joints, max_points + 1);
  velocities_ = Eigen::MatrixXd::Zero(num_joints, max_points + 1);
}

void TrajectoryBuffer::assign(const JointTrajectory& trajectory,
                              const std::vector<std::string>& joint_names, const JointVector& lower,
                              const JointVector& upper) {
  const std::size_t n = joint_names.size();
  if (static_cast<int>(n) != num_joints_) {
    throw Error("trajectory buffer is for " + std::to_string(num_joints_) + " joints, not " +
                std::to_string(n));
  }
  // Where each of the arm's joints sits in the message.
  std::vector<std::size_t> column(n);
  for (std::size_t j = 0; j < n; ++j) {
    const auto found =
        std::find(trajectory.joint_names.begin(), trajectory.joint_names.end(), joint_names[j]);
    if (found == trajectory.joint_names.end()) {
      throw Error("trajectory.joint_names lacks joint '" + joint_names[j] + "'");
    }
    if (std::find(found + 1, trajectory.joint_names.end(), joint_names[j]) !=
        trajectory.joint_names.end()) {
      throw Error("trajectory.joint_names names joint '" + joint_names[j] + "' twice");
    }
    column[j] = static_cast<std::size_t>(found - trajectory.joint_names.begin());
  }
  for (const std::string& name : trajectory.joint_names) {
    if (std::find(joint_names.begin(), joint_names.end(), name) == joint_names.end()) {
      std::string known;
      for (const std::string& joint : joint_names) known += (known.empty() ? "" : ", ") + joint;
      throw Error("trajectory.joint_names has unknown joint '" + name + "' (the arm has: " + known +
                  ")");
    }
  }
  const std::size_t points = trajectory.positions.size();
  if (trajectory.times.size() != points) {
    throw Error("trajectory has " + std::to_string(points) + " positions but " +
                std::to_string(trajectory.times.size()) + " times");
  }
  const bool has_velocities = !trajectory.velocities.empty();
  if (has_velocities && trajectory.velocities.size() != points) {
    throw Error("trajectory has " + std::to_string(points) + " positions but " +
                std::to_string(trajectory.velocities.size()) + " velocities (give all or none)");
  }
  // A point at time 0 describes the start state, which execution takes from the robot instead.
  const std::size_t first = points > 0 && trajectory.times[0] == 0.0 ? 1 : 0;
  if (points - first == 0) throw Error("trajectory has no point after time 0");
  if (static_cast<int>(points - first) > max_points_) {
    throw Error("trajectory has " + std::to_string(points - first) + " points; at most " +
                std::to_string(max_points_) + " fit (raise trajectory capacity)");
  }
  std::vector<double> times(points - first + 1, 0.0);
  Eigen::MatrixXd positions(n, points - first + 1);
  Eigen::MatrixXd velocities = Eigen::MatrixXd::Zero(n, points - first + 1);
  double previous_time = 0.0;
  for (std::size_t k = first; k < points; ++k) {
    const std::string point = "trajectory point " + std::to_string(k);
    const double time = trajectory.times[k];
    if (!std::isfinite(time) || !(time > previous_time)) {
      throw Error(point + ": time " + format_number(time) + " s must be finite and greater than " +
                  format_number(previous_time) + " s (times increase strictly from 0)");
    }
    previous_time = time;
    if (trajectory.positions[k].size() != trajectory.joint_names.size()) {
      throw Error(point + " has " + std::to_string(trajectory.positions[k].size()) +
                  " positions; expected " + std::to_string(trajectory.joint_names.size()));
    }
    if (has_velocities && trajectory.velocities[k].size() != trajectory.joint_names.size()) {
      throw Error(point + " has " + std::to_string(trajectory.velocities[k].size()) +
                  " velocities; expected " + std::to_string(trajectory.joint_names.size()));
    }
    const Eigen::Index index = static_cast<Eigen::Index>(k - first + 1);
    times[static_cast<std::size_t>(index)] = time;
    for (std::size_t j = 0; j < n; ++j) {
      const double position = trajectory.positions[k][column[j]];
      const Eigen::Index row = static_cast<Eigen::Index>(j);
      if (!std::isfinite(position) || position < lower[row] || position > upper[row]) {
        throw Error(point + ", joint '" + joint_names[j] + "': position " +
                    format_number(position) + " is outside its limits [" +
                    format_number(lower[row]) + ", " + format_number(upper[row]) + "]");
      }
      positions(row, index) = position;
      if (has_velocities) {
        const double velocity = trajectory.velocities[k][column[j]];
        if (!std::isfinite(velocity)) {
          throw Error(point + ", joint '" + joint_names[j] + "': velocity " +
                      format_number(velocity) + " is not finite");
        }
        velocities(row, index) = velocity;
      }
    }
  }
  // Validated: store. Nothing below throws.
  num_points_ = static_cast<int>(times.size());
  velocities_given_ = has_velocities;
  std::copy(times.begin(), times.end(), times_.begin());
  positions_.leftCols(num_points_) = positions;
  velocities_.leftCols(num_points_) = velocities;
  // Every velocity but that of point 1, which depends on the start state, is derived here, in
  // the sender's thread: begin() then costs the same for 2 points as for 10,000.
  if (!velocities_given_) {
    for (int k = 2; k < num_points_; ++k) derive_velocity(k);
  }
}

void TrajectoryBuffer::begin(const JointVector& q_start, const JointVector& dq_start) noexcept {
  positions_.col(0) = q_start;
  velocities_.col(0) = dq_start;
  if (!velocities_given_ && num_points_ > 1) derive_velocity(1);
}

void TrajectoryBuffer::derive_velocity(int k) noexcept {
  // Average of the neighbouring slopes, zero where the path turns, limited as Fritsch and Carlson
  // do so that a monotone stretch stays monotone: the path never overshoots its waypoints, and so
  // stays within the joint limits the waypoints were checked against. Zero at the last point.
  const int last = num_points_ - 1;
  for (int j = 0; j < num_joints_; ++j) {
    if (k == last) {
      velocities_(j, k) = 0.0;
      continue;
    }
    const double before = (positions_(j, k) - positions_(j, k - 1)) / (times_[k] - times_[k - 1]);
    const double after = (positions_(j, k + 1) - positions_(j, k)) / (times_[k + 1] - times_[k]);
    if (before * after <= 0.0) {
      velocities_(j, k) = 0.0;
    } else {
      const double average = 0.5 * (before + after);
      const double bound = 3.0 * std::min(std::abs(before), std::abs(after));
      velocities_(j, k) = std::copysign(std::min(std::abs(average), bound), average);
    }
  }
}

void TrajectoryBuffer::sample(double time, JointVector& q, JointVector& dq) const noexcept {
  const int last = num_points_ - 1;
  if (num_points_ == 0) return;
  if (time >= times_[last]) {
    q = positions_.col(last);
    dq.setZero(num_joints_);
    return;
  }
  if (time <= 0.0) {
    q = positions_.col(0);
    dq = velocities_.col(0);
    return;
  }
  // Segment k: times_[k] <= time < times_[k + 1].
  const auto end = times_.begin() + num_points_;
  const int k = static_cast<int>(std::upper_bound(times_.begin(), end, time) - times_.begin()) - 1;
  const double h = times_[k + 1] - times_[k];
  const double s = (time - times_[k]) / h;
  const double s2 = s * s, s3 = s2 * s;
  const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s;
  const double h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
  const double d00 = 6 * s2 - 6 * s, d10 = 3 * s2 - 4 * s + 1;
  const double d01 = -6 * s2 + 6 * s, d11 = 3 * s2 - 2 * s;
  q = h00 * positions_.col(k) + (h10 * h) * velocities_.col(k) + h01 * positions_.col(k + 1) +
      (h11 * h) * velocities_.col(k + 1);
  dq = (d00 / h) * positions_.col(k) + d10 * velocities_.col(k) +
       (d01 / h) * positions_.col(k + 1) + d11 * velocities_.col(k + 1);
}

}  // namespace cartesian_impedance
