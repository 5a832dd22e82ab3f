#pragma once
/// @file
/// A drop-in for the C++ API of the published base library (Mayr and Salt Ducaju, "A C++
/// Implementation of a Cartesian Impedance Controller for Robotic Manipulators", class
/// `cartesian_impedance_controller::CartesianImpedanceController`): code written against it
/// compiles unchanged against this header and gets the same torques, computed by this library.
///
/// The published semantics are kept exactly:
/// - every filter closes a fraction of the remaining gap per second at the given update
///   frequency, with the published step 1 / (kappa f + 1), kappa = -1 / ln(1 - p); a parameter
///   of exactly 1 switches a filter off;
/// - the damping is a matrix of its own, D = factor * 2 sqrt(K) per axis ("unit mass"),
///   recomputed when the damping factors change or the stiffness changes with auto_damping, and
///   filtered like the stiffness;
/// - the nullspace projector uses the damped pseudo-inverse with lambda = 0.2;
/// - the commanded torque changes by at most the torque delta per call.
///
/// Bad input keeps the published contract (docs/switching.md, "What the drop-in accepts"): every
/// value the published library accepts is accepted, and one outside this library's ranges is
/// clamped to the nearest bound; a value the published library asserts on (a negative stiffness,
/// a filter parameter outside (0, 1], ...) or a NaN keeps the last valid value. Each adjustment is
/// reported by inputReport() and adjustmentCount() and in a rate-limited line on stderr; nothing
/// throws. In a translation unit compiled without NDEBUG the published assertions stop the
/// program with the published text, as the published library does: those checks are inline
/// here, so they follow the NDEBUG of the code that calls the setter, not of this library's
/// build. Checking::strict instead throws cartesian_impedance::Error naming the argument, the
/// value and the range, and changes nothing. A measured state that is wrongly sized, not finite
/// or implausible fails the call closed (the torque steps toward zero by at most the torque
/// delta, status() and fault() say why) instead of producing NaN torques; the default
/// constructor is ready for 7 joints; any joint count up to cartesian_impedance::kMaxJoints works
/// (the published projector is fixed at 7).
///
/// The published signature of calculateCommandedTorques() returns an Eigen::VectorXd, which
/// allocates once per call; the overload that writes into a caller's vector allocates nothing.
///
/// Threads, as the published ROS wrapper uses the class: one thread may call the setters while
/// another (the control thread) calls calculateCommandedTorques() and the getters. A setter
/// works on its own copy of the settings and hands the result over through a lock-free buffer;
/// the control thread takes up the newest settings at the start of its next call (or getter),
/// never waits for a setter and never sees a half-made change. setNumberOfJoints() builds the
/// controller for the new count on the setter's thread and the control thread swaps it in.
/// More than one setter thread, or getters on the setter thread while the control thread runs,
/// is not supported (docs/switching.md, "Threads").

#include <Eigen/Dense>
#include <atomic>
#include <cassert>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/mailbox.hpp"

namespace cartesian_impedance_controller {

class CartesianImpedanceController {
 public:
  /// How setters treat a value outside this library's ranges or outside the published domain.
  enum class Checking {
    /// The published contract: clamp or keep the last valid value, report, never throw (and,
    /// without NDEBUG, stop at the published assertions).
    published,
    /// Throw cartesian_impedance::Error naming the argument, the value and the range; the call
    /// changes nothing.
    strict,
  };

  /// What the last setter call did with its arguments.
  struct InputReport {
    enum class Action : unsigned char {
      accepted,  ///< every argument taken as given
      clamped,   ///< an argument outside this library's range: the nearest bound is in effect
      kept,      ///< an argument the published library asserts on, or NaN: the last valid value
                 ///< stays in effect
    };
    /// For the call's first adjusted argument (accepted if none was).
    Action action = Action::accepted;
    /// That argument: `input` names the method and argument ("setStiffness: t_x"), `value` is
    /// what was given, `bound` the bound it broke (where `has_bound`), `unit` its unit.
    cartesian_impedance::Fault fault;
    /// The value in effect for that argument after the call (the bound it was clamped to, or the
    /// last valid value; NaN where a whole vector was kept).
    double applied = 0.0;
    /// How many arguments the call adjusted.
    int adjusted = 0;
  };

  /// Ready for 7 joints, stiffness (200, 200, 200, 20, 20, 20), nullspace stiffness 0, damping
  /// factors 1, no filtering at 1000 Hz, torque delta 1 Nm per call (the published defaults).
  CartesianImpedanceController() : CartesianImpedanceController(Checking::published) {}
  /// The same, with `checking` for bad input.
  explicit CartesianImpedanceController(Checking checking);
  /// Copies need both threads of `other` to be quiet, as copying any object does.
  CartesianImpedanceController(const CartesianImpedanceController& other) { *this = other; }
  CartesianImpedanceController& operator=(const CartesianImpedanceController& other);

  /// Sets the reference pose, also as the filtered one (no filtering).
  void initDesiredPose(const Eigen::Vector3d& position_d_target,
                       const Eigen::Quaterniond& orientation_d_target);
  /// Sets the nullspace configuration [rad], also as the filtered one (no filtering).
  void initNullspaceConfig(const Eigen::VectorXd& q_d_nullspace_target) {
    assert_nullspace_size(q_d_nullspace_target);
    set_nullspace_config(q_d_nullspace_target, true);
  }
  /// Resets the joint state and the nullspace configuration to zero, and the last torques too
  /// when the count changes (with the same count the next call moves from the torque the robot
  /// receives by at most the torque delta). Takes effect at the control thread's next call.
  /// @throws cartesian_impedance::Error unless 1 <= n_joints <= kMaxJoints (in either mode: the
  /// published library throws for a negative count too).
  void setNumberOfJoints(size_t n_joints);

  /// Stiffness targets [N/m x3, Nm/rad x3, nullspace Nm/rad]; with auto_damping the damping
  /// targets become factor * 2 sqrt(stiffness).
  void setStiffness(const Eigen::Matrix<double, 7, 1>& stiffness, bool auto_damping = true) {
#ifndef NDEBUG
    if (set_.checking == Checking::published) {
      for (int i = 0; i < 7; ++i) {
        // As published, only inside the test for a negative value: NaN passes the assertion.
        if (stiffness(i) < 0.0) {
          assert(stiffness(i) >= 0 && "Stiffness values need to be positive.");
        }
      }
    }
#endif
    set_stiffness(stiffness, auto_damping);
  }
  void setStiffness(double t_x, double t_y, double t_z, double r_x, double r_y, double r_z,
                    double n, bool auto_damping = true) {
    setStiffness((Eigen::Matrix<double, 7, 1>() << t_x, t_y, t_z, r_x, r_y, r_z, n).finished(),
                 auto_damping);
  }
  /// As above, keeping the nullspace stiffness target.
  void setStiffness(double t_x, double t_y, double t_z, double r_x, double r_y, double r_z,
                    bool auto_damping = true) {
    setStiffness(t_x, t_y, t_z, r_x, r_y, r_z, set_.settings.targets.nullspace_stiffness,
                 auto_damping);
  }
  /// Damping factors (1 is "critical" for a unit mass); applies the damping rule at once.
  void setDampingFactors(double d_x, double d_y, double d_z, double d_a, double d_b, double d_c,
                         double d_n) {
    const Eigen::Matrix<double, 7, 1> factors =
        (Eigen::Matrix<double, 7, 1>() << d_x, d_y, d_z, d_a, d_b, d_c, d_n).finished();
#ifndef NDEBUG
    if (set_.checking == Checking::published) {
      // The published order: the negative factors first, then the rule meets the NaN ones.
      for (int i = 0; i < 7; ++i) {
        if (factors(i) < 0) {
          assert(factors(i) >= 0 && "Damping factor must not be negative.");
        }
      }
      for (int i = 0; i < 7; ++i) {
        assert(factors(i) >= 0.0 && "Damping values need to be positive.");
      }
    }
#endif
    set_damping_factors(factors);
  }

  /// Reference pose target, approached through the pose filter; the quaternion is normalised.
  void setReferencePose(const Eigen::Vector3d& position_d, const Eigen::Quaterniond& orientation_d);
  /// Nullspace configuration target [rad], approached through the nullspace filter.
  void setNullspaceConfig(const Eigen::VectorXd& q_d_nullspace_target) {
    assert_nullspace_size(q_d_nullspace_target);
    set_nullspace_config(q_d_nullspace_target, false);
  }

  /// Update frequency [Hz] and, per filter, the fraction in (0, 1] of the remaining gap closed
  /// per second; 1 switches a filter off.
  void setFiltering(double update_frequency, double filter_params_nullspace_config,
                    double filter_params_stiffness, double filter_params_pose,
                    double filter_params_wrench) {
#ifndef NDEBUG
    if (set_.checking == Checking::published) {
      // The fractions before the frequency (the published code checks the frequency first): a
      // call with both wrong stops at the fraction, as the published tests expect.
      for (const double p : {filter_params_nullspace_config, filter_params_stiffness,
                             filter_params_pose, filter_params_wrench}) {
        assert(p > 0 && p <= 1.0 && "Filter params need to be between 0 and 1.");
      }
      assert(update_frequency >= 0.0 && "Update frequency needs to be greater or equal to zero");
    }
#endif
    set_filtering(update_frequency, filter_params_nullspace_config, filter_params_stiffness,
                  filter_params_pose, filter_params_wrench);
  }
  /// Largest change of the commanded torque per call [Nm] (a huge value switches the limit off
  /// as far as this library's largest torque rate, 1e6 Nm/s, allows).
  void setMaxTorqueDelta(double d) {
#ifndef NDEBUG
    if (set_.checking == Checking::published) {
      assert(d >= 0.0 && "Allowed torque change must be positive");
    }
#endif
    set_max_torque_delta(d, set_.settings.update_frequency, false);
  }
  /// As above, and the update frequency [Hz].
  void setMaxTorqueDelta(double d, double update_frequency) {
#ifndef NDEBUG
    if (set_.checking == Checking::published) {
      assert(d >= 0.0 && "Allowed torque change must be positive");
      assert(update_frequency >= 0.0 && "Update frequency needs to be greater or equal to zero");
    }
#endif
    set_max_torque_delta(d, update_frequency, true);
  }
  /// Wrench target [N; Nm] in the root frame, approached through the wrench filter.
  void applyWrench(const Eigen::Matrix<double, 6, 1>& cartesian_wrench);

  // The control thread's calls: these and the getters below take up the setters' newest settings
  // first.

  /// One control step at the last measured state.
  Eigen::VectorXd calculateCommandedTorques();
  /// One control step: stores the measured state, performs a filtering step and returns the
  /// commanded torques [Nm] (one heap allocation, for the returned vector).
  Eigen::VectorXd calculateCommandedTorques(const Eigen::VectorXd& q, const Eigen::VectorXd& dq,
                                            const Eigen::Vector3d& position,
                                            Eigen::Quaterniond orientation,
                                            const Eigen::MatrixXd& jacobian);
  /// The same step writing the torques into `tau` (sized n): allocates nothing, throws nothing.
  /// Returns status(); if `tau` is wrongly sized nothing is computed (invalid_robot_state).
  cartesian_impedance::Status calculateCommandedTorques(
      const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& dq,
      const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
      const Eigen::Ref<const Eigen::MatrixXd>& jacobian, Eigen::Ref<Eigen::VectorXd> tau) noexcept;

  /// The last measured state and the filtered targets the last step used. Null outputs are
  /// skipped; vector outputs are resized.
  void getState(Eigen::VectorXd* q, Eigen::VectorXd* dq, Eigen::Vector3d* position,
                Eigen::Quaterniond* orientation, Eigen::Vector3d* position_d,
                Eigen::Quaterniond* orientation_d, Eigen::Matrix<double, 6, 6>* cartesian_stiffness,
                double* nullspace_stiffness, Eigen::VectorXd* q_d_nullspace,
                Eigen::Matrix<double, 6, 6>* cartesian_damping) const;
  void getState(Eigen::Vector3d* position_d, Eigen::Quaterniond* orientation_d,
                Eigen::Matrix<double, 6, 6>* cartesian_stiffness, double* nullspace_stiffness,
                Eigen::VectorXd* q_d_nullspace,
                Eigen::Matrix<double, 6, 6>* cartesian_damping) const;
  /// The torques of the last step [Nm].
  Eigen::VectorXd getLastCommands() const {
    take_settings();
    return cycle_.tau;
  }
  /// The filtered wrench of the last step [N; Nm].
  Eigen::Matrix<double, 6, 1> getAppliedWrench() const {
    take_settings();
    return cycle_.filtered.wrench;
  }
  /// [p - p_d; rotation vector of R R_d^T] of the last step [m; rad].
  Eigen::Matrix<double, 6, 1> getPoseError() const {
    take_settings();
    return cycle_.controller.state().pose_error;
  }

  // Beyond the published API.

  /// Outcome of the last step: ok, or why it failed closed (not_started after
  /// setNumberOfJoints() until the next step).
  cartesian_impedance::Status status() const noexcept {
    take_settings();
    return cycle_.status;
  }
  /// Which input made the last step fail closed (empty input if it did not).
  const cartesian_impedance::Fault& fault() const noexcept {
    take_settings();
    return cycle_.fault;
  }
  /// The library controller that evaluates the law (its state() has every torque component;
  /// its torque() is before the published torque delta, which this class applies).
  const cartesian_impedance::CartesianImpedanceController& controller() const noexcept {
    take_settings();
    return cycle_.controller;
  }

  // The setter thread's calls.

  /// What the last setter call did with its arguments (Checking::published; a strict call that
  /// throws leaves it as it was).
  const InputReport& inputReport() const noexcept {
    return set_.report;
  }
  /// Arguments clamped or kept since construction.
  std::uint64_t adjustmentCount() const noexcept {
    return set_.adjustment_count;
  }
  /// Each adjustment is also written to stderr as one line, at most one per `seconds` [s]
  /// (default 1; the next line says how many were left out): 0 writes every one, infinity only
  /// the first. @throws cartesian_impedance::Error if `seconds` is negative or NaN.
  void setWarningInterval(double seconds);
  Checking checking() const noexcept {
    return set_.checking;
  }
  void setChecking(Checking checking) noexcept {
    set_.checking = checking;
  }
  /// The torque delta in effect [Nm per call]: the one asked for, clamped to this library's
  /// torque rate range at the update frequency.
  double maxTorqueDelta() const noexcept {
    return set_.settings.max_torque_delta;
  }
  /// The update frequency in effect [Hz].
  double updateFrequency() const noexcept {
    return set_.settings.update_frequency;
  }

 private:
  // What the published law is evaluated with; held twice, as targets and as their filtered
  // values (which the law uses).
  struct Impedance {
    Eigen::Vector3d position_d = Eigen::Vector3d::Zero();
    Eigen::Quaterniond orientation_d = Eigen::Quaterniond::Identity();
    cartesian_impedance::Matrix6d stiffness = cartesian_impedance::Matrix6d::Identity();
    cartesian_impedance::Matrix6d damping = cartesian_impedance::Matrix6d::Identity();
    cartesian_impedance::JointVector q_d_nullspace;
    // As published: the current nullspace stiffness and damping start at 1 and reach their
    // targets at the first step (at once without stiffness filtering).
    double nullspace_stiffness = 1.0;
    double nullspace_damping = 1.0;
    cartesian_impedance::Vector6d wrench = cartesian_impedance::Vector6d::Zero();
  };

  // Everything the setters decide and the cycle needs, handed over whole. Fixed-size (JointVector
  // has a compile-time maximum), so copying it allocates nothing.
  struct Settings {
    Impedance targets;
    // initDesiredPose() and initNullspaceConfig() (and setNumberOfJoints(), which zeroes the
    // nullspace configuration) also set the filtered value: the newest such value, and how many
    // there were, so that the cycle applies each one once.
    Eigen::Vector3d init_position_d = Eigen::Vector3d::Zero();
    Eigen::Quaterniond init_orientation_d = Eigen::Quaterniond::Identity();
    std::uint64_t pose_inits = 0;
    cartesian_impedance::JointVector init_q_d_nullspace;
    std::uint64_t nullspace_inits = 0;
    // setNumberOfJoints() calls so far: each starts the controller over (a new count with the
    // controller built for it).
    std::uint64_t joint_count_changes = 0;
    int n_joints = 7;
    double update_frequency = 1000.0;  // [Hz]
    double max_torque_delta = 1.0;     // [Nm] per call, in effect
    // Filter parameters (1 = off) and the per-call steps derived from them.
    double filter_nullspace = 1.0, filter_stiffness = 1.0, filter_pose = 1.0, filter_wrench = 1.0;
    double step_nullspace = 1.0, step_stiffness = 1.0, step_pose = 1.0, step_wrench = 1.0;
  };

  // The setter thread's state.
  struct SetterState {
    Checking checking = Checking::published;
    int n_joints = 7;
    Settings settings;
    Eigen::Matrix<double, 7, 1> damping_factors = Eigen::Matrix<double, 7, 1>::Ones();
    double requested_torque_delta = 1.0;  // [Nm] per call, as asked for
    InputReport report;
    std::uint64_t adjustment_count = 0;
    double warning_interval = 1.0;  // [s]
    bool warned = false;
    std::chrono::steady_clock::time_point last_warning;
    std::uint64_t warnings_left_out = 0;
  };

  // The control thread's state.
  struct CycleState {
    CycleState();
    cartesian_impedance::CartesianImpedanceController controller;
    cartesian_impedance::ScheduledImpedance schedule;
    cartesian_impedance::RobotState measured;  // last valid measurement
    cartesian_impedance::RobotState input;     // this call's measurement, until it is checked
    cartesian_impedance::Status status = cartesian_impedance::Status::not_started;
    cartesian_impedance::Fault fault;
    Settings settings;  // in force
    Settings incoming;  // the newest handed over, while it is taken up
    Impedance filtered;
    Impedance next;
    // The torque commanded: the published tau_c, which the torque delta limits per joint.
    cartesian_impedance::JointVector tau;
    int n_joints = 7;
    // What of the setters' hand-over has been taken up.
    std::uint64_t version = 0, pose_inits = 0, nullspace_inits = 0, joint_count_changes = 0;
  };

  // The published assertion of the nullspace setters, in the caller's translation unit.
  void assert_nullspace_size(const Eigen::VectorXd& q_d_nullspace_target) const {
#ifndef NDEBUG
    if (set_.checking == Checking::published) {
      assert(q_d_nullspace_target.size() == static_cast<Eigen::Index>(set_.n_joints) &&
             "Nullspace target needs to same size as n_joints_");
    }
#else
    (void)q_d_nullspace_target;
#endif
  }
  // The setters' work, out of line: the published assertions above are the callers' only.
  void set_stiffness(const Eigen::Matrix<double, 7, 1>& stiffness, bool auto_damping);
  void set_damping_factors(const Eigen::Matrix<double, 7, 1>& factors);
  void set_nullspace_config(const Eigen::VectorXd& q_d_nullspace_target, bool init);
  void set_filtering(double update_frequency, double filter_nullspace, double filter_stiffness,
                     double filter_pose, double filter_wrench);
  void set_max_torque_delta(double d, double update_frequency, bool frequency_given);
  void set_reference_pose(const Eigen::Vector3d& position_d,
                          const Eigen::Quaterniond& orientation_d);

  // Reporting of adjusted arguments.
  void begin_call() noexcept;
  void report(InputReport::Action action, const cartesian_impedance::Fault& fault, double applied);
  // `value` against the published domain [published_min, inf) (below it, or NaN: the last
  // valid value `last` stays) and this library's [min, max] (clamped); returns what to use.
  double accept(const char* input, const char* unit, double value, double last,
                double published_min, double min, double max);

  // Applies the update frequency and the torque delta asked for (`requested`), clamped to the
  // rate range; `input` names what is reported if it is clamped.
  void reconfigure(const char* input, double requested, double update_frequency);
  void apply_damping_rule();
  void update_filter_steps();
  // Hands the setter thread's settings to the control thread.
  void publish() noexcept;

  // Control thread: takes up the newest settings (and a new joint count's controller) if the
  // setters changed them. Const because the getters call it: what they return is the control
  // thread's state, with the setters' last changes.
  void take_settings() const noexcept;
  // Applies a setNumberOfJoints(): false if the controller for a new count is not here yet.
  bool reset_joints(const Settings& incoming) const noexcept;
  bool take_controller(int n) const noexcept;
  void filter_step(Impedance& next) const noexcept;
  // One cycle at `measured`; `measurement_checked`: q and dq were checked already.
  cartesian_impedance::Status step(const cartesian_impedance::RobotState& measured,
                                   bool measurement_checked = false) noexcept;
  // The published rate limit on the native controller's torque: each joint moves from the last
  // commanded torque by at most the torque delta, on its own.
  void limit_torque_change() noexcept;
  cartesian_impedance::Status compute(const Eigen::Ref<const Eigen::VectorXd>& q,
                                      const Eigen::Ref<const Eigen::VectorXd>& dq,
                                      const Eigen::Vector3d& position,
                                      const Eigen::Quaterniond& orientation,
                                      const Eigen::Ref<const Eigen::MatrixXd>& jacobian,
                                      Eigen::Ref<Eigen::VectorXd> tau) noexcept;

  SetterState set_;
  // mutable: the getters take up the setters' last changes (take_settings()).
  mutable CycleState cycle_;

  // The hand-over between the two threads: the newest settings, and a counter the setters raise
  // after each publication, so that the cycle reads the buffer only when something changed.
  cartesian_impedance::SnapshotBuffer<Settings, 3> settings_buffer_;
  std::atomic<std::uint64_t> settings_version_{0};
  // The controller for a new joint count: built by the setter thread (constructing it
  // allocates), swapped in by the cycle, which leaves the old one in its place for the setter
  // thread to free. handoff_state_ says who may touch handoff_.
  enum HandoffState : int { kSetterOwns, kReady, kTaking };
  mutable std::optional<cartesian_impedance::CartesianImpedanceController> handoff_;
  mutable std::atomic<int> handoff_state_{kSetterOwns};
};

}  // namespace cartesian_impedance_controller

namespace cartesian_impedance::compat {
/// The drop-in class under this library's namespace.
using CartesianImpedanceController = cartesian_impedance_controller::CartesianImpedanceController;
}  // namespace cartesian_impedance::compat
