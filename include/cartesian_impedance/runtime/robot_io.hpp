#pragma once
/// @file
/// What a robot driver (a ROS joint_states callback, a fieldbus thread) exchanges with the control
/// thread: measured joint states in, commanded torques out. Both directions are lock-free and
/// allocate nothing after construction, so the control cycle never waits for the driver.
///
/// Times are std::chrono::steady_clock time points taken with monotonic_now(), i.e. from
/// CLOCK_MONOTONIC, the clock the control thread keeps its deadlines on.

#include <semaphore.h>

#include <chrono>
#include <cstdint>

#include "cartesian_impedance/core/mailbox.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance::runtime {

/// CLOCK_MONOTONIC now, as a steady_clock time point (on Linux steady_clock is that clock).
/// Real-time safe (a vDSO call).
std::chrono::steady_clock::time_point monotonic_now() noexcept;

/// A measured joint state in the model's joint order. Fixed-size storage: copying it does not
/// allocate.
struct JointMeasurement {
  JointVector q;       ///< joint positions [rad or m]
  JointVector dq;      ///< joint velocities [rad/s or m/s]
  JointVector effort;  ///< measured joint torques [Nm or N]; size 0 if the robot reports none
  std::uint64_t sequence = 0;  ///< 1, 2, ... in order of publication; 0: nothing received yet
  std::chrono::steady_clock::time_point received{};  ///< when it was published (monotonic_now)
  /// When the robot measured it, on the same clock: a driver's stamp (a ROS header.stamp, the
  /// time of a fieldbus frame). The default (the clock's epoch) means the driver gives none: then
  /// it is `received`. The control thread reports the age of each measurement it uses from it
  /// (ControlThreadStatistics::measurement_age_p50_us).
  std::chrono::steady_clock::time_point sampled{};
};

/// Measurements from one writer thread (the driver) to any number of readers (the control thread,
/// a state publisher), each reading the newest one.
class MeasurementBuffer {
 public:
  /// Starts with q = dq = 0 (num_joints each), no effort and sequence 0 (nothing received).
  /// @throws Error if num_joints is not in [1, kMaxJoints].
  explicit MeasurementBuffer(int num_joints);
  MeasurementBuffer(const MeasurementBuffer&) = delete;
  MeasurementBuffer& operator=(const MeasurementBuffer&) = delete;

  int num_joints() const noexcept { return num_joints_; }

  /// Makes a copy of `measurement` the newest, with the next sequence number and
  /// received = monotonic_now() (its own sequence and received are ignored); its `sampled` is
  /// kept if given and not later than `received`, else set to `received`. q and dq are passed
  /// on as they are, even wrongly sized or non-finite: the control cycle then fails closed, which
  /// is the safe reaction to a bad measurement. One writer thread at a time. Real-time safe:
  /// noexcept, lock-free, no allocation.
  void publish(const JointMeasurement& measurement) noexcept;

  /// Copies the newest measurement into `out`. Any thread. Real-time safe.
  void read(JointMeasurement& out) const noexcept;

 private:
  SnapshotBuffer<JointMeasurement> buffer_;
  JointMeasurement staging_;  // the writer's
  std::uint64_t sequence_ = 0;
  int num_joints_;
};

/// Where the control thread puts each cycle's torque (a robot driver, a publisher's hand-off).
class TorqueSink {
 public:
  virtual ~TorqueSink() = default;
  /// Called in the control thread once per cycle with the torque to command `tau` [Nm or N] and
  /// the loop's cycle count (LoopState::cycle). Must be real-time safe: no allocation, no lock,
  /// no blocking call.
  virtual void write(const JointVector& tau, std::uint64_t cycle) noexcept = 0;
};

/// One cycle's torque, as a TorqueOutbox hands it on.
struct TorqueSample {
  JointVector tau;  ///< [Nm or N]
  std::uint64_t cycle = 0;
};

/// A TorqueSink for one consumer thread that sends each torque on (e.g. a ROS publisher of
/// effort commands): the control thread publishes the torque and wakes the consumer with a
/// semaphore post (at most a futex wake, never a wait). The consumer gets the newest torque; if it
/// is slower than the cycle, it skips the ones in between.
class TorqueOutbox final : public TorqueSink {
 public:
  /// @throws Error if num_joints is not in [1, kMaxJoints].
  explicit TorqueOutbox(int num_joints);
  ~TorqueOutbox() override;
  TorqueOutbox(const TorqueOutbox&) = delete;
  TorqueOutbox& operator=(const TorqueOutbox&) = delete;

  int num_joints() const noexcept { return num_joints_; }

  /// Control thread: publishes and wakes the consumer. Real-time safe.
  void write(const JointVector& tau, std::uint64_t cycle) noexcept override;

  /// Consumer thread (one): waits up to `timeout` [s] for a torque written since the last one it
  /// returned. True with `sample` filled if there is one; false after the timeout or a wake()
  /// (also one before the first write: nothing was written yet).
  bool wait(double timeout, TorqueSample& sample) noexcept;

  /// Wakes the consumer early (for shutdown): its wait() returns false unless a new torque came.
  void wake() noexcept;

 private:
  struct Written {
    TorqueSample sample;
    std::uint64_t sequence = 0;  // 1, 2, ... per write(); 0: the initial zero, never written
  };
  SnapshotBuffer<Written, 4> buffer_;
  Written staging_;   // the control thread's
  Written received_;  // the consumer's, and the sequence of the newest torque it returned
  std::uint64_t returned_ = 0;
  sem_t semaphore_;
  int num_joints_;
};

}  // namespace cartesian_impedance::runtime
