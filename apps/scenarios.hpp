#pragma once
// Closed-loop scenarios in the MuJoCo simulation: each drives a ControlLoop against the simulated
// robot and returns what theory predicts next to what was measured. The behaviour tests assert
// them; the demo prints, logs, plots and renders them. One definition serves both.

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::scenarios {

/// A deliberately broken controller, to show that the scenarios' checks can fail: the torque the
/// loop computes is replaced before it reaches the simulated robot.
enum class Mutation {
  none,          ///< the controller as it is
  zero_torque,   ///< a dead controller: zero torque (the simulated firmware still holds gravity)
  flipped_sign,  ///< the law with its sign flipped: -tau
  /// The controller without its energy tank (safety.energy_tank.enabled = false), whatever the
  /// scenario configures: the mutant of the tank's own checks.
  no_energy_tank,
  // The safety layer with one of its caps removed, in the `safety` scenario's parameters (the
  // torque is the controller's own; the other scenarios run as they are): each check of that
  // cap must then fail.
  no_speed_cap,  ///< safety.max_speed 0
  no_force_cap,  ///< safety.max_force 0
  no_workspace,  ///< no box: safety.workspace.min/max the defaults (+-10 m), no walls
  no_payload,    ///< the payload not declared (payload.mass 0)
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
  /// The physics engine of the simulation (with_engine() sets it and what it needs).
  sim::Engine engine = sim::Engine::mujoco;
  /// sim::SimulationOptions::boxes_for_missing_meshes (the demo's --boxes-for-missing-meshes).
  bool boxes_for_missing_meshes = false;
  /// sim::SimulationOptions::plant (the demo's --plant): model error, delays and noise.
  sim::PlantOptions plant = sim::PlantOptions();
};

/// `robot` simulated by `engine`. DART simulates URDF files only: a robot with an MJCF is then
/// simulated from its URDF, starting where the MJCF's keyframe "ready" starts (unless start_q
/// says otherwise), with its tip link as the flange (the MJCF's flange site sits at its origin).
/// @throws Error if the engine is not available in this build (the message says why).
RobotSetup with_engine(RobotSetup robot, sim::Engine engine);

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

/// Samples of a run, every 10 ms, for logs and plots: what was measured, and every quantity the
/// scenario commands (filtered as the law used it, and as commanded).
struct Sample {
  double time = 0.0;
  /// What the scenario is doing, e.g. "push 20 N along +x" (Rig::phase() and the pushes).
  std::string phase;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();     ///< flange, base frame [m]
  Eigen::Vector3d reference = Eigen::Vector3d::Zero();    ///< filtered reference [m]
  Eigen::Vector3d commanded = Eigen::Vector3d::Zero();    ///< commanded reference [m]
  Vector6d pose_error = Vector6d::Zero();                 ///< [m; rad]
  Vector6d stiffness = Vector6d::Zero();                  ///< filtered diagonal of K [N/m; Nm/rad]
  Vector6d commanded_stiffness = Vector6d::Zero();        ///< commanded [N/m; Nm/rad]
  Eigen::Vector3d push = Eigen::Vector3d::Zero();         ///< external force applied [N]
  Eigen::Vector3d push_torque = Eigen::Vector3d::Zero();  ///< external torque applied [Nm]
  Eigen::Vector3d contact = Eigen::Vector3d::Zero();      ///< contact force on the tip [N]
  Eigen::Vector3d wrench = Eigen::Vector3d::Zero();       ///< filtered commanded force [N]
  Eigen::Vector3d commanded_wrench = Eigen::Vector3d::Zero();  ///< commanded force [N]
  JointVector q;                                               ///< measured joint positions [rad]
  JointVector nullspace_target;                                ///< filtered nullspace target [rad]
  JointVector commanded_nullspace_target;                      ///< commanded [rad]
  JointVector tau;                                             ///< commanded torque [Nm]
  double max_torque_rate = 0.0;  ///< largest |dtau/dt| since the previous sample [Nm/s]
};

/// Called at moments worth a picture ("pushed", "settled", ...), with what to draw on it: a
/// caption saying what is applied, the applied force as an arrow, the reference pose as a frame,
/// and a ghost of the arm where it was before.
using MomentCallback = std::function<void(const std::string& label, const sim::Simulation&,
                                          const sim::RenderOverlay& overlay)>;

/// The simulated robot and its control loop, stepped together at 1 kHz by a closed-loop runner.
class Rig {
 public:
  Rig(const RobotSetup& robot, const Parameters& parameters,
      const std::vector<sim::Box>& boxes = {});
  /// Adds the oscillations its controller's watch found (SafetyState::oscillations) to the
  /// count run_scenario() reports.
  ~Rig();
  /// The scenario drives this rig's loop unstable on purpose (a stiffness schedule pumping
  /// without the energy tank): what the watch finds here is not counted.
  void expect_oscillation() { oscillation_expected_ = true; }
  /// Collisions the monitor found with nothing touching the arm: no push and no contact on any
  /// of its bodies within the last kTouchMemory (the observer's filter and the isolation window
  /// lag the contact). run_scenario() reports them; each scenario's arm touches only what it
  /// meant to, so each is a false alarm.
  int false_alarms() const { return false_alarms_; }
  static constexpr double kTouchMemory = 0.2;  // [s]
  Rig(const Rig&) = delete;                    // the runner refers to the simulation and the loop
  Rig& operator=(const Rig&) = delete;

  /// Steps for `seconds`, sampling every 10 ms.
  void run(double seconds);
  /// Applies `force` [N] (and `torque` [Nm]) at the flange, world frame, until cleared. A push
  /// from rest remembers the arm's joint positions there (the ghost of the pictures).
  void push(const Eigen::Vector3d& force, const Eigen::Vector3d& torque = Eigen::Vector3d::Zero());
  void release();

  /// What the scenario does from now on (beyond the pushes, which name themselves), for the
  /// samples' phase column and the pictures' captions, e.g. "stiffness x doubled".
  void phase(const std::string& what);
  /// Remembers the current joint positions, drawn as a translucent ghost in the next pictures,
  /// with what they are ("before the step").
  void remember_pose(const std::string& what);
  /// Direction of the pictures' camera [deg] (RenderOverlay::azimuth, elevation).
  void view(double azimuth, double elevation);
  /// Calls `moment` (if any) with a picture's overlay: the caption (`label`, the time, the
  /// stiffness, the applied force, then `details`), the push and contact forces as arrows, the
  /// reference pose as a frame and the remembered pose as a ghost.
  void moment(const MomentCallback& moment, const std::string& label,
              const std::vector<std::string>& details = {});
  /// Draws `arrow` into the next picture only (e.g. a contact the scenario found), with
  /// `caption` added to its caption.
  void mark(const sim::RenderArrow& arrow, const std::string& caption);

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
  Eigen::Vector3d push_torque_ = Eigen::Vector3d::Zero();
  std::string phase_;    // set by phase()
  JointVector ghost_q_;  // remember_pose(); empty: none
  std::string ghost_what_;
  double view_azimuth_ = std::numeric_limits<double>::quiet_NaN();
  double view_elevation_ = std::numeric_limits<double>::quiet_NaN();
  std::vector<Sample> samples_;
  JointVector previous_tau_;
  double largest_rate_fraction_ = 0.0;
  double rate_since_sample_ = 0.0;
  double time_ = 0.0;
  long steps_ = 0;
  bool oscillation_expected_ = false;
  std::vector<std::pair<sim::RenderArrow, std::string>> marks_;  // mark(), until moment()
  int collisions_seen_ = 0;
  int false_alarms_ = 0;
  double last_touch_ = -kTouchMemory;
};

/// Numbers a scenario measured beyond its samples (e.g. one row per stiffness of a grid), for a
/// CSV file of its own and a plot.
struct Table {
  std::string name;  ///< file name part: <scenario>_<name>.csv
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;
};

/// What a scenario produced.
struct Outcome {
  std::vector<Result> results;
  std::vector<Sample> samples;  ///< of the scenario's main rig
  /// Parameters the scenario sets instead of the robot's configuration, e.g.
  /// "stiffness.translation = 500 500 500 N/m (configured: 1000 1000 1000)".
  std::vector<std::string> overrides = {};
  std::vector<Table> tables = {};
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
