#include "cartesian_impedance/runtime/robot_io.hpp"

#include <time.h>

#include <cerrno>
#include <cmath>
#include <string>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::runtime {

namespace {

int checked_joint_count(const char* what, int num_joints) {
  if (num_joints < 1 || num_joints > kMaxJoints) {
    throw Error(std::string(what) + ": num_joints = " + std::to_string(num_joints) +
                " is outside [1, " + std::to_string(kMaxJoints) + "]");
  }
  return num_joints;
}

}  // namespace

std::chrono::steady_clock::time_point monotonic_now() noexcept {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return std::chrono::steady_clock::time_point(std::chrono::seconds(now.tv_sec) +
                                               std::chrono::nanoseconds(now.tv_nsec));
}

// ---- MeasurementBuffer ------------------------------------------------------------------------

MeasurementBuffer::MeasurementBuffer(int num_joints)
    : num_joints_(checked_joint_count("MeasurementBuffer", num_joints)) {
  staging_.q = staging_.dq = JointVector::Zero(num_joints_);
  staging_.effort.resize(0);
  buffer_.publish(staging_);
}

void MeasurementBuffer::publish(const JointMeasurement& measurement) noexcept {
  staging_ = measurement;
  staging_.sequence = ++sequence_;
  staging_.received = monotonic_now();
  // A stamp from the future (a driver's clock ahead of ours) would report a negative age.
  if (staging_.sampled.time_since_epoch().count() == 0 || staging_.sampled > staging_.received) {
    staging_.sampled = staging_.received;
  }
  buffer_.publish(staging_);
}

void MeasurementBuffer::read(JointMeasurement& out) const noexcept {
  buffer_.read(out);
}

// ---- TorqueOutbox -----------------------------------------------------------------------------

TorqueOutbox::TorqueOutbox(int num_joints)
    : num_joints_(checked_joint_count("TorqueOutbox", num_joints)) {
  staging_.sample.tau = JointVector::Zero(num_joints_);
  buffer_.publish(staging_);
  sem_init(&semaphore_, 0, 0);
}

TorqueOutbox::~TorqueOutbox() {
  sem_destroy(&semaphore_);
}

void TorqueOutbox::write(const JointVector& tau, std::uint64_t cycle) noexcept {
  staging_.sample.tau = tau;
  staging_.sample.cycle = cycle;
  ++staging_.sequence;
  buffer_.publish(staging_);
  sem_post(&semaphore_);
}

void TorqueOutbox::wake() noexcept {
  sem_post(&semaphore_);
}

bool TorqueOutbox::wait(double timeout, TorqueSample& sample) noexcept {
  timespec deadline{};
  clock_gettime(CLOCK_MONOTONIC, &deadline);
  const long nanoseconds =
      deadline.tv_nsec + static_cast<long>(std::fmax(0.0, std::fmin(timeout, 1e6)) * 1e9);
  deadline.tv_sec += nanoseconds / 1000000000L;
  deadline.tv_nsec = nanoseconds % 1000000000L;
  int result;
  while ((result = sem_clockwait(&semaphore_, CLOCK_MONOTONIC, &deadline)) == -1 &&
         errno == EINTR) {
  }
  if (result != 0) return false;
  buffer_.read(received_);
  // Several posts may be answered by one read: report each written torque once, and the initial
  // one, which no cycle wrote, never (a wake() before the first write posts too).
  if (received_.sequence == returned_) return false;
  returned_ = received_.sequence;
  sample = received_.sample;
  return true;
}

}  // namespace cartesian_impedance::runtime
