#pragma once
// Closed-loop scenarios in the MuJoCo simulation: each drives a ControlLoop against the simulated
// robot and returns what theory predicts next to what was measured. The behaviour tests assert
// them; the demo prints, logs, plots and renders them. One definition serves both.

#include <functional>
#include <string>
#include <vector>

#include "cartesian_impedance/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::scenarios {

/// A deliberately broken controller, to show that the scenarios' checks can fail: the torque the
/// loop computes is replaced before it reaches the simulated robot.
enum class Mutation {
  none,          ///< the controller as it is
  zero_torque,   ///< a dead controller: zero torque (the simulated firmware still holds gravity)
  flipped_sign,  ///< the law with its sign flipped: -tau
};

/// A robot as the scenarios need it: the URDF for the controller's model, the MJCF (or the URDF
/// again) for the simulation, the chain, and the body or site at the tip.
struct RobotSetup {
  std::string name;
  std::string urdf;
  std::string mjcf;  ///< "" = simulate the URDF itself
  std::string base_link;
  std::string tip_link;
  std::string flange;           ///< site or body of the simulation at the tip
  std::string parameters_file;  ///< "" = library defaults
  /// Start configuration of the simulation [rad or m]; empty: the MJCF's keyframe "ready" (or
  /// q = 0 for a URDF).
  JointVector start_q = JointVector();
  Mutation mutation = Mutation::none;
};

/// A robot the project ships ("panda", "iiwa14", "ur5e", "planar3"), from models/ and config/
/// under `source_dir`.
/// @throws Error for another name.
RobotSetup builtin_robot(const std::string& name, const std::string& source_dir);

/// One line of a scenario's report.
struct Result {
  std::string scenario;
  std::string quantity;   ///< what is compared, in words
  double expected = 0.0;  ///< theory
  double measured = 0.0;
  std::string unit;
  double tolerance = 0.0;  ///< |measured - expected| allowed, or an upper bound (see `bound`)
  bool bound = false;      ///< true: passes if measured <= expected + tolerance
  bool passed = false;
  std::string note;
  /// false: the robot cannot do what this line measures (e.g. push along y on an arm that moves
  /// in the x-z plane only); `note` says why, and the line is neither passed nor failed.
  bool applicable = true;
};

/// Samples of a run, every 10 ms, for logs and plots.
struct Sample {
  double time = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();   ///< flange, base frame [m]
  Eigen::Vector3d reference = Eigen::Vector3d::Zero();  ///< filtered reference [m]
  Eigen::Vector3d commanded = Eigen::Vector3d::Zero();  ///< commanded reference [m]
  Vector6d pose_error = Vector6d::Zero();               ///< [m; rad]
  double stiffness_x = 0.0;            ///< filtered translational stiffness along x [N/m]
  double commanded_stiffness_x = 0.0;  ///< commanded [N/m]
  Eigen::Vector3d push = Eigen::Vector3d::Zero();     ///< external force applied [N]
  Eigen::Vector3d contact = Eigen::Vector3d::Zero();  ///< contact force on the tip [N]
  Eigen::Vector3d wrench = Eigen::Vector3d::Zero();   ///< filtered commanded force [N]
  JointVector tau;                                    ///< commanded torque [Nm]
  double max_torque_rate = 0.0;  ///< largest |dtau/dt| since the previous sample [Nm/s]
};

/// Called at moments worth a picture ("pushed", "settled", ...).
using MomentCallback = std::function<void(const std::string& label, const sim::Simulation&)>;

/// The simulated robot and its control loop, stepped together at 1 kHz by a closed-loop runner.
class Rig {
 public:
  Rig(const RobotSetup& robot, const Parameters& parameters,
      const std::vector<sim::Box>& boxes = {});
  Rig(const Rig&) = delete;  // the runner refers to the simulation and the loop
  Rig& operator=(const Rig&) = delete;

  /// Steps for `seconds`, sampling every 10 ms.
  void run(double seconds);
  /// Applies `force` [N] (and `torque` [Nm]) at the flange, world frame, until cleared.
  void push(const Eigen::Vector3d& force, const Eigen::Vector3d& torque = Eigen::Vector3d::Zero());
  void release();

  /// Flange pose in the base frame, as the simulation has it (ground truth).
  Pose flange() const;
  /// Contact force on the flange's body from the environment, world frame [N].
  Eigen::Vector3d contact_force() const;

  ControlLoop& loop() { return *loop_; }
  sim::Simulation& sim() { return sim_; }
  const RobotModel& model() const { return model_; }
  const std::vector<Sample>& samples() const { return samples_; }
  /// Largest |dtau_i/dt| over all steps so far, divided by the joint's rate limit.
  double largest_rate_fraction() const { return largest_rate_fraction_; }
  double time() const { return time_; }

 private:
  RobotSetup robot_;
  RobotModel model_;
  sim::Simulation sim_;
  std::unique_ptr<ControlLoop> loop_;
  sim::ClosedLoopRunner runner_;
  bool flange_is_site_ = true;
  Eigen::Vector3d push_force_ = Eigen::Vector3d::Zero();
  std::vector<Sample> samples_;
  JointVector previous_tau_;
  double largest_rate_fraction_ = 0.0;
  double rate_since_sample_ = 0.0;
  double time_ = 0.0;
  long steps_ = 0;
};

/// What a scenario produced.
struct Outcome {
  std::vector<Result> results;
  std::vector<Sample> samples;  ///< of the scenario's main rig
  /// Parameters the scenario sets instead of the robot's configuration, e.g.
  /// "stiffness.translation = 500 500 500 N/m (configured: 1000 1000 1000)".
  std::vector<std::string> overrides = {};
};

/// Names of the scenarios, in demo order.
const std::vector<std::string>& scenario_names();

/// Runs one scenario on `robot`. `moment` (optional) is called at notable moments.
/// @throws Error for an unknown name (listing the known ones).
Outcome run_scenario(const std::string& name, const RobotSetup& robot,
                     const MomentCallback& moment = {});

/// The parameters a scenario starts from for `robot` (its config file, or defaults).
Parameters base_parameters(const RobotSetup& robot);

}  // namespace cartesian_impedance::scenarios
