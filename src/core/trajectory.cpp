#include "cartesian_impedance/core/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"

namespace cartesian_impedance {

namespace {

// The velocity at point k (of the points 0 to `last`, one per column) of a path through
// `positions` at `times` that has none given: the
// average of the neighbouring slopes, zero where the path turns, limited as Fritsch and Carlson do
// so that a monotone stretch stays monotone (the path never overshoots its waypoints). Zero at
// the last point.
void derive_velocity(const double* times, const Eigen::MatrixXd& positions, int last, int k,
                     Eigen::MatrixXd& velocities) noexcept {
  for (Eigen::Index j = 0; j < positions.rows(); ++j) {
    if (k == last) {
      velocities(j, k) = 0.0;
      continue;
    }
    const double before = (positions(j, k) - positions(j, k - 1)) / (times[k] - times[k - 1]);
    const double after = (positions(j, k + 1) - positions(j, k)) / (times[k + 1] - times[k]);
    if (before * after <= 0.0) {
      velocities(j, k) = 0.0;
    } else {
      const double average = 0.5 * (before + after);
      const double bound = 3.0 * std::min(std::abs(before), std::abs(after));
      velocities(j, k) = std::copysign(std::min(std::abs(average), bound), average);
    }
  }
}

// One joint on one cubic Hermite segment of duration h from (q0, v0) to (q1, v1): the largest
// speed and the smallest and largest position on it. The velocity is the quadratic
// a s^2 + b s + v0 of s in [0, 1] (scaled by 1/h), so both follow from its ends, its vertex and
// its roots.
struct SegmentExtremes {
  double speed = 0.0;
  double lowest = 0.0;
  double highest = 0.0;
};

SegmentExtremes hermite_extremes(double q0, double v0, double q1, double v1, double h) noexcept {
  const double a = 6.0 * (q0 - q1) / h + 3.0 * (v0 + v1);
  const double b = 6.0 * (q1 - q0) / h - 4.0 * v0 - 2.0 * v1;
  const double c = v0;
  const auto velocity = [&](double s) { return (a * s + b) * s + c; };
  const auto position = [&](double s) {
    const double s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * q0 + (s3 - 2 * s2 + s) * h * v0 + (-2 * s3 + 3 * s2) * q1 +
           (s3 - s2) * h * v1;
  };
  SegmentExtremes extremes;
  extremes.speed = std::max(std::abs(v0), std::abs(v1));
  extremes.lowest = std::min(q0, q1);
  extremes.highest = std::max(q0, q1);
  if (a != 0.0) {
    const double vertex = -b / (2.0 * a);
    if (vertex > 0.0 && vertex < 1.0) {
      extremes.speed = std::max(extremes.speed, std::abs(velocity(vertex)));
    }
  }
  // Turning points of the position: roots of the velocity inside the segment.
  double roots[2];
  int count = 0;
  if (a == 0.0) {
    if (b != 0.0) roots[count++] = -c / b;
  } else {
    const double discriminant = b * b - 4.0 * a * c;
    if (discriminant >= 0.0) {
      // The form without cancellation: q = -(b + sign(b) sqrt(D)) / 2, roots q / a and c / q.
      const double root = std::sqrt(discriminant);
      const double half = -0.5 * (b + std::copysign(root, b));
      if (half != 0.0) roots[count++] = c / half;
      roots[count++] = half / a;
    }
  }
  for (int i = 0; i < count; ++i) {
    if (roots[i] > 0.0 && roots[i] < 1.0) {
      const double q = position(roots[i]);
      extremes.lowest = std::min(extremes.lowest, q);
      extremes.highest = std::max(extremes.highest, q);
    }
  }
  return extremes;
}

}  // namespace

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
  assign(trajectory, joint_names,
         TrajectoryLimits{
             lower, upper,
             JointVector::Constant(lower.size(), std::numeric_limits<double>::infinity())});
}

void TrajectoryBuffer::assign(const JointTrajectory& trajectory,
                              const std::vector<std::string>& joint_names,
                              const TrajectoryLimits& limits, const TrajectoryStartState* start) {
  const JointVector& lower = limits.lower;
  const JointVector& upper = limits.upper;
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
        if (std::abs(velocity) > limits.velocity[row]) {
          throw Error(point + ", joint '" + joint_names[j] + "': velocity " +
                      format_number(velocity) + " is beyond its velocity limit " +
                      format_number(limits.velocity[row]) + " (URDF)");
        }
        velocities(row, index) = velocity;
      }
    }
  }
  // The path between the points: every velocity but the first point's (which depends on the
  // start state) is known now; with a start state, that one too.
  const int count = static_cast<int>(times.size());
  if (!has_velocities) {
    for (int k = 2; k < count; ++k)
      derive_velocity(times.data(), positions, count - 1, k, velocities);
  }
  int first_segment = 1;
  if (start != nullptr) {
    positions.col(0) = start->q;
    velocities.col(0) = start->dq;
    if (!has_velocities && count > 1) {
      derive_velocity(times.data(), positions, count - 1, 1, velocities);
    }
    first_segment = 0;
  }
  for (int segment = first_segment; segment + 1 < count; ++segment) {
    const double h =
        times[static_cast<std::size_t>(segment) + 1] - times[static_cast<std::size_t>(segment)];
    const std::string from =
        segment == 0 ? std::string("the start state")
                     : "point " + std::to_string(static_cast<std::size_t>(segment) - 1 + first);
    const std::string where = "trajectory segment from " + from + " to point " +
                              std::to_string(static_cast<std::size_t>(segment) + first);
    for (std::size_t j = 0; j < n; ++j) {
      const Eigen::Index row = static_cast<Eigen::Index>(j);
      const SegmentExtremes extremes =
          hermite_extremes(positions(row, segment), velocities(row, segment),
                           positions(row, segment + 1), velocities(row, segment + 1), h);
      // The waypoints passed exactly; a path between them may touch a limit to round-off.
      const double slack = 1e-9 * (1.0 + std::max(std::abs(lower[row]), std::abs(upper[row])));
      if (extremes.speed > limits.velocity[row] * (1.0 + 1e-9)) {
        throw Error(where + ", joint '" + joint_names[j] + "': the interpolated speed reaches " +
                    format_number(extremes.speed) + ", beyond its velocity limit " +
                    format_number(limits.velocity[row]) + " (URDF); give the segment more time " +
                    "than its " + format_number(h) + " s (speeds scale with 1 / duration)");
      }
      if (extremes.lowest < lower[row] - slack || extremes.highest > upper[row] + slack) {
        throw Error(where + ", joint '" + joint_names[j] + "': the interpolated position reaches " +
                    format_number(extremes.lowest < lower[row] - slack ? extremes.lowest
                                                                       : extremes.highest) +
                    ", outside its limits [" + format_number(lower[row]) + ", " +
                    format_number(upper[row]) + "] (the velocities make it overshoot)");
      }
    }
  }

  // Validated: store. Nothing below throws.
  num_points_ = count;
  velocities_given_ = has_velocities;
  std::copy(times.begin(), times.end(), times_.begin());
  positions_.leftCols(num_points_) = positions;
  velocities_.leftCols(num_points_) = velocities;
}

void TrajectoryBuffer::begin(const JointVector& q_start, const JointVector& dq_start) noexcept {
  positions_.col(0) = q_start;
  velocities_.col(0) = dq_start;
  // Every other velocity was derived by assign(), in the sender's thread: begin() then costs the
  // same for 2 points as for 10,000.
  if (!velocities_given_ && num_points_ > 1) {
    derive_velocity(times_.data(), positions_, num_points_ - 1, 1, velocities_);
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
