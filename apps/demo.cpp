// cartesian_impedance_demo: a scripted tour of the controller on a simulated robot (MuJoCo or
// DART, or both side by side), with what theory predicts next to what was measured, CSV logs,
// plots and pictures.

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/model/rate_check.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/model/start_configuration.hpp"
#include "demo_output.hpp"
#include "scenarios.hpp"

namespace ci = cartesian_impedance;
namespace scenarios = cartesian_impedance::scenarios;
namespace fs = std::filesystem;
using ci::demo::expectation;
using ci::demo::measurement;

namespace {

constexpr const char* kUsage = R"(Usage: cartesian_impedance_demo [options]

Runs the controller on a simulated robot through a scripted tour (reference motion, push and
compliance, stiffness change, wrench against a table, nullspace motion, teaching, trajectory,
stability grid, two arms, energy tank, safety caps, collisions) and prints, for each scenario,
what theory predicts and what was measured. Writes CSV logs, plots and rendered pictures to the output folder.

Options:
  --robot NAME             a robot the project ships: panda, iiwa14 (URDF + MJCF), ur5e,
                           planar3 (URDF only) (default: panda)
  --urdf FILE              your robot's URDF (needs --base-link and --tip-link)
  --mjcf FILE              your robot's MJCF for the simulation (default: simulate the URDF)
  --base-link NAME         first link of the controlled chain (with --urdf)
  --tip-link NAME          end-effector link (with --urdf)
  --boxes-for-missing-meshes
                           simulate a link whose collision mesh cannot be found or read as the
                           box of its inertia (each named) instead of refusing the URDF
  --plant NAME             the simulated arm: nominal (the controller's model, read at once and
                           exactly; default) or realistic (link inertias x 0.7-1.3, centres of
                           mass moved up to 1 cm, joint friction, damping and armature off,
                           readings 1 ms late and noisy, torques 1 ms late and noisy)
  --plant-seed N           the seed of the realistic plant's draws (default 1)
  --package-path DIRS      folders (':'-separated) searched first for the URDF's package://NAME/
                           meshes, as entries of ROS_PACKAGE_PATH: DIR/NAME, or DIR itself if it
                           is named NAME (then ROS_PACKAGE_PATH, AMENT_PREFIX_PATH and the folders
                           beside and above the URDF are searched)
  --flange NAME            site or body at the tip in the simulation (default: the tip link)
  --config FILE            controller parameters (YAML; default: config/<robot>.yaml)
  --start-q Q1,Q2,...      start configuration [rad or m], one value per joint (default: the
                           MJCF's keyframe 'ready', the shipped robot's, or for a URDF alone
                           one the library chooses: well conditioned, inside the limits)
  --engine NAME            physics engine: mujoco, dart (simulates the URDF) or both (every
                           scenario on each, then a table theory / MuJoCo / DART; the output
                           folder gets a subfolder per engine) (default: mujoco)
  --scenario NAME          run only this scenario (repeatable); names: )";

struct Options {
  scenarios::RobotSetup robot;
  std::vector<ci::sim::Engine> engines{ci::sim::Engine::mujoco};
  std::vector<std::string> scenarios;
  bool boxes_for_missing_meshes = false;
  std::string plant = "nominal";
  std::uint64_t plant_seed = 1;
  fs::path out = "demo_output";
  bool render = true;
  bool plots = true;
};

[[noreturn]] void usage_error(const std::string& message) {
  std::cerr << "cartesian_impedance_demo: " << message << "\n"
            << "Run with --help for the options.\n";
  std::exit(2);
}

void print_usage() {
  std::cout << kUsage;
  for (const std::string& name : scenarios::scenario_names()) std::cout << name << " ";
  std::cout << R"(
  --out DIR                output folder (default: demo_output)
  --no-render              skip the rendered pictures
  --no-plots               skip the plots
  --help                   this text

Exit status: 0 every measurement agrees with theory and every file was written; 1 some
disagree (FAIL); 2 bad arguments, robot or configuration, or an output folder that cannot be
created or written to (nothing was run); 3 some scenarios could not run, or a log, plot or
picture could not be written (each named), and every measurement that was made agrees with
theory.
)";
}

// A joint vector as --start-q takes it: comma-separated, 5 significant digits.
const Eigen::IOFormat kList(5, Eigen::DontAlignCols, ", ", ", ");

void require_file(const std::string& option, const std::string& path) {
  if (!fs::is_regular_file(path)) usage_error(option + " '" + path + "': no such file");
}

Options parse(int argc, char** argv) {
  Options options;
  std::string robot = "panda", urdf, mjcf, base, tip, flange, config, start_q, engine, package_path;
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage_error(argument + " needs a value");
      return argv[++i];
    };
    if (argument == "--help" || argument == "-h") {
      print_usage();
      std::exit(0);
    } else if (argument == "--robot") {
      robot = value();
    } else if (argument == "--urdf") {
      urdf = value();
    } else if (argument == "--mjcf") {
      mjcf = value();
    } else if (argument == "--base-link") {
      base = value();
    } else if (argument == "--tip-link") {
      tip = value();
    } else if (argument == "--flange") {
      flange = value();
    } else if (argument == "--package-path") {
      package_path = value();
    } else if (argument == "--boxes-for-missing-meshes") {
      options.boxes_for_missing_meshes = true;
    } else if (argument == "--plant") {
      options.plant = value();
    } else if (argument == "--plant-seed") {
      const std::string text = value();
      char* end = nullptr;
      const unsigned long long seed = std::strtoull(text.c_str(), &end, 10);
      if (text.empty() || *end != '\0' || text[0] == '-') {
        usage_error("--plant-seed '" + text + "' is not a whole number >= 0");
      }
      options.plant_seed = seed;
    } else if (argument == "--config") {
      config = value();
    } else if (argument == "--start-q") {
      start_q = value();
    } else if (argument == "--engine") {
      engine = value();
    } else if (argument == "--scenario") {
      options.scenarios.push_back(value());
    } else if (argument == "--out") {
      options.out = value();
    } else if (argument == "--no-render") {
      options.render = false;
    } else if (argument == "--no-plots") {
      options.plots = false;
    } else {
      usage_error("unknown argument '" + argument +
                  "' (valid: --robot, --urdf, --mjcf, --base-link, --tip-link, --package-path, "
                  "--boxes-for-missing-meshes, --plant, --plant-seed, --flange, --config, "
                  "--start-q, --engine, "
                  "--scenario, --out, --no-render, "
                  "--no-plots, --help)");
    }
  }
  if (!package_path.empty()) {
    std::stringstream folders(package_path);
    std::string folder;
    while (std::getline(folders, folder, ':')) {
      if (!folder.empty() && !fs::is_directory(folder)) {
        usage_error("--package-path '" + package_path + "': '" + folder + "' is not a folder");
      }
    }
    // The simulation finds package:// URIs as ROS tools do, through ROS_PACKAGE_PATH first.
    const char* ros = std::getenv("ROS_PACKAGE_PATH");
    const std::string joined =
        package_path + (ros != nullptr && *ros != '\0' ? ":" + std::string(ros) : "");
    ::setenv("ROS_PACKAGE_PATH", joined.c_str(), 1);
  }
  if (!urdf.empty()) {
    require_file("--urdf", urdf);
    if (!mjcf.empty()) require_file("--mjcf", mjcf);
    if (base.empty() || tip.empty()) usage_error("--urdf needs --base-link and --tip-link");
    options.robot = {"custom", urdf, mjcf, base, tip, flange.empty() ? tip : flange, ""};
    options.robot.boxes_for_missing_meshes = options.boxes_for_missing_meshes;
  } else {
    if (!mjcf.empty()) usage_error("--mjcf needs --urdf (the controller's model)");
    try {
      options.robot = scenarios::builtin_robot(robot, CARTESIAN_IMPEDANCE_SOURCE_DIR);
    } catch (const ci::Error& error) {
      usage_error(std::string("--robot: ") + error.what());
    }
    if (!flange.empty()) options.robot.flange = flange;
  }
  try {
    options.robot.plant = ci::sim::plant_from_name(options.plant, options.plant_seed);
  } catch (const ci::Error& error) {
    usage_error(std::string("--plant: ") + error.what());
  }
  if (!config.empty()) {
    require_file("--config", config);
    try {
      ci::load_parameters(config);  // report a bad file now, not in the middle of the tour
    } catch (const ci::Error& error) {
      usage_error(std::string("--config: ") + error.what());
    }
    options.robot.parameters_file = config;
  }
  // The robot and its configuration are checked once, before any scenario: a URDF that does not
  // load or a per-joint value of the wrong length for this arm is a usage error, not a failure
  // of every scenario.
  std::optional<ci::RobotModel> model;
  try {
    model = ci::RobotModel::from_urdf_file(options.robot.urdf, options.robot.base_link,
                                           options.robot.tip_link);
  } catch (const ci::Error& error) {
    usage_error(std::string("--urdf: ") + error.what());
  }
  for (const std::string& warning : model->warnings()) {
    std::cout << "Warning: --urdf: " << warning << "\n";
  }
  if (options.robot.boxes_for_missing_meshes && options.robot.mjcf.empty()) {
    try {
      ci::sim::SimulationOptions simulation;
      simulation.boxes_for_missing_meshes = true;
      const ci::sim::Simulation loaded =
          ci::sim::Simulation::from_urdf_file(options.robot.urdf, simulation);
      for (const std::string& warning : loaded.warnings()) {
        std::cout << "Warning: --urdf: " << warning << "\n";
      }
    } catch (const ci::Error& error) {
      usage_error(std::string("--urdf: ") + error.what());
    }
  }
  const int joints = model->num_joints();
  try {
    ci::validate(scenarios::base_parameters(options.robot), joints);
  } catch (const ci::Error& error) {
    usage_error((config.empty()
                     ? std::string("the robot's configuration: ")
                     : "--config '" + config + "' for " + std::to_string(joints) + " joints: ") +
                error.what());
  }
  if (!start_q.empty()) {
    std::vector<double> values;
    std::stringstream list(start_q);
    std::string item;
    while (std::getline(list, item, ',')) {
      char* end = nullptr;
      const double value = std::strtod(item.c_str(), &end);
      if (item.empty() || end == item.c_str() || *end != '\0' || !std::isfinite(value)) {
        usage_error("--start-q '" + start_q + "': '" + item + "' is not a number");
      }
      values.push_back(value);
    }
    if (static_cast<int>(values.size()) != joints) {
      usage_error("--start-q '" + start_q + "' has " + std::to_string(values.size()) +
                  " values; the robot has " + std::to_string(joints) + " joints");
    }
    options.robot.start_q = Eigen::Map<const Eigen::VectorXd>(values.data(), joints);
  }
  // A URDF alone has no start: q = 0 is singular on most arms, so the library chooses one (an
  // MJCF starts at its keyframe; the shipped robots and --start-q bring their own).
  if (options.robot.start_q.size() == 0 && options.robot.mjcf.empty()) {
    try {
      const ci::StartChoice choice = ci::find_start_configuration(*model);
      options.robot.start_q = choice.q;
      std::cout << "Start configuration (chosen: " << choice.description << "; --start-q "
                << "to give another): q = [" << choice.q.transpose().format(kList) << "]\n";
    } catch (const ci::Error& error) {
      std::cout << "Warning: start configuration: " << error.what() << "; starting at q = 0\n";
    }
  }
  // A start at a singularity or at a joint limit makes every scenario look broken; say so once.
  // (An MJCF starts at its keyframe, checked by whoever wrote it.)
  if (options.robot.start_q.size() == joints || options.robot.mjcf.empty()) {
    const ci::JointVector q = options.robot.start_q.size() == joints
                                  ? options.robot.start_q
                                  : ci::JointVector::Zero(joints);
    const ci::ConfigurationCheck check = ci::check_configuration(*model, q);
    for (const std::string& warning : check.warnings) {
      std::cout << "Warning: start configuration: " << warning << "\n";
    }
    // The stiffness limits against the torque-rate limit, where the arm starts.
    if (check.limit_distance >= 0.0) {
      try {
        const ci::RateCheck rate =
            ci::check_rate_limit(*model, q, scenarios::base_parameters(options.robot));
        for (const std::string& warning : rate.warnings) {
          std::cout << "Warning: configuration: " << warning << "\n";
        }
      } catch (const ci::Error& error) {
        std::cout << "Warning: configuration: the rate check cannot be made: " << error.what()
                  << "\n";
      }
    }
    if (check.limit_distance < 0.0) {
      usage_error("the start configuration is outside the joint range (" + check.warnings.back() +
                  "); give one inside it with --start-q");
    }
  }
  if (engine == "both") {
    options.engines = {ci::sim::Engine::mujoco, ci::sim::Engine::dart};
  } else if (!engine.empty()) {
    try {
      options.engines = {ci::sim::engine_from_name(engine)};
    } catch (const ci::Error& error) {
      usage_error(std::string("--engine: ") + error.what() + " (or both)");
    }
  }
  for (const ci::sim::Engine e : options.engines) {
    scenarios::RobotSetup setup;
    try {
      setup = scenarios::with_engine(options.robot, e);  // available, the MJCF's start readable
    } catch (const ci::Error& error) {
      usage_error(std::string("--engine: ") + error.what());
    }
    // The simulation of the robot as given (an MJCF that does not match the URDF, a flange it
    // lacks) is the user's argument: refused here, before any scenario, like a broken URDF.
    try {
      const scenarios::Rig probe(setup, scenarios::base_parameters(setup));
    } catch (const ci::Error& error) {
      usage_error(
          std::string(options.robot.mjcf.empty() ? "the simulation of --urdf: " : "--mjcf: ") +
          error.what());
    }
  }
  const std::vector<std::string>& known = scenarios::scenario_names();
  for (const std::string& name : options.scenarios) {
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string names;
      for (const std::string& known_name : known) names += (names.empty() ? "" : ", ") + known_name;
      usage_error("unknown scenario '" + name + "' (valid: " + names + ")");
    }
  }
  if (options.scenarios.empty()) options.scenarios = known;
  return options;
}

// What one engine's tour produced.
struct Tour {
  std::vector<scenarios::Result> results;
  std::vector<std::string> not_run;      // "scenario: why"
  std::vector<std::string> not_written;  // "output file '...' cannot be created: ..."
  bool every_check_passed = true;
};

// Creates `folder` and makes sure a file can be written in it, before anything runs: a folder
// that exists but takes no files (/proc/..., a read-only mount, one of another user's) would
// otherwise show only after the tour. Returns why not, or "".
std::string writable_folder(const fs::path& folder) {
  std::error_code error;
  fs::create_directories(folder, error);
  if (error) return error.message();
  const fs::path probe = folder / ".cartesian_impedance_demo_write_test";
  errno = 0;
  std::ofstream file(probe);
  file << "x";
  file.close();
  const int reason = errno;
  fs::remove(probe, error);
  if (!file) return reason != 0 ? std::strerror(reason) : "a file cannot be written there";
  return "";
}

// Runs the plot script on `folder` and returns "" or why it failed. The folder goes to Python as
// an argument of its own, never through a shell, whatever quotes or spaces its name holds.
std::string make_plots(const fs::path& folder) {
  std::string python = "/usr/bin/python3";
  std::string script = std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/apps/plot_demo.py";
  std::string argument = folder.string();
  char* const argv[] = {python.data(), script.data(), argument.data(), nullptr};
  std::cout << std::flush;  // the script's output after ours
  pid_t child = 0;
  const int error = posix_spawn(&child, python.c_str(), nullptr, nullptr, argv, environ);
  const std::string command = python + " " + script;
  if (error != 0) return "cannot start " + command + ": " + std::strerror(error);
  int status = 0;
  while (waitpid(child, &status, 0) < 0) {
    if (errno != EINTR) return "cannot wait for " + command + ": " + std::strerror(errno);
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return "";
  return command + (WIFEXITED(status) ? " exited with status " + std::to_string(WEXITSTATUS(status))
                                      : " was ended by signal " + std::to_string(WTERMSIG(status)));
}

Tour run_tour(const Options& options, const scenarios::RobotSetup& robot, const fs::path& out,
              bool render) {
  Tour tour;
  int index = 0;
  for (const std::string& name : options.scenarios) {
    std::cout << "\n[" << ++index << "/" << options.scenarios.size() << "] " << name << " ... "
              << std::flush;
    const auto begin = std::chrono::steady_clock::now();
    scenarios::MomentCallback moment;
    if (render) {
      moment = [&](const std::string& label, const ci::sim::Simulation& sim,
                   const ci::sim::RenderOverlay& overlay) {
        ci::sim::RenderOverlay captioned = overlay;
        captioned.caption = name + (robot.engine == ci::sim::Engine::dart ? " (DART)" : "") + ": " +
                            overlay.caption;
        sim.render_png((out / ci::demo::picture_file_name(name, label)).string(), 1024, 768,
                       captioned);
      };
    }
    scenarios::Outcome outcome;
    try {
      outcome = scenarios::run_scenario(name, robot, moment);
    } catch (const ci::Error& failure) {
      std::cout << "could not run: " << failure.what() << "\n";
      tour.not_run.push_back(name + ": " + failure.what());
      continue;
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
    std::printf("%.1f s\n", seconds);
    for (const std::string& line : outcome.overrides) {
      std::printf("    (uses %s)\n", line.c_str());
    }
    for (const scenarios::Result& result : outcome.results) {
      if (!result.applicable) {
        std::printf("    n/a  %-62s %s\n", result.quantity.c_str(), result.note.c_str());
      } else {
        std::printf("    %s %-62s theory %-22s measured %s\n", result.passed ? "ok  " : "FAIL",
                    result.quantity.c_str(), expectation(result).c_str(),
                    measurement(result).c_str());
        if (!result.passed && !result.note.empty()) {
          std::printf("         %s\n", result.note.c_str());
        }
        tour.every_check_passed &= result.passed;
      }
      tour.results.push_back(result);
    }
    try {
      if (!outcome.samples.empty()) {
        ci::demo::write_samples(out / (name + ".csv"), outcome.samples);
      }
      for (const scenarios::Table& table : outcome.tables) {
        ci::demo::write_table(out / (name + "_" + table.name + ".csv"), table);
      }
    } catch (const ci::Error& failure) {
      std::cout << "    " << failure.what() << "\n";
      tour.not_written.push_back(failure.what());
    }
  }
  try {
    ci::demo::write_summary(out / "summary.csv", tour.results);
  } catch (const ci::Error& failure) {
    tour.not_written.push_back(failure.what());
  }
  return tour;
}

void print_summary(const std::vector<scenarios::Result>& results) {
  std::printf("\n%-18s %-62s %-22s %-16s %s\n", "scenario", "what", "theory", "measured", "");
  for (const scenarios::Result& r : results) {
    if (!r.applicable) {
      std::printf("%-18s %-62s %-22s %-16s %s\n", r.scenario.c_str(), r.quantity.c_str(), "-", "-",
                  "n/a");
      continue;
    }
    std::printf("%-18s %-62s %-22s %-16s %s\n", r.scenario.c_str(), r.quantity.c_str(),
                expectation(r).c_str(), measurement(r).c_str(), r.passed ? "ok" : "FAIL");
  }
}

}  // namespace

int main(int argc, char** argv) {
  const Options options = parse(argc, argv);
  const bool both = options.engines.size() > 1;
  const auto folder_of = [&](ci::sim::Engine engine) {
    return both ? options.out / ci::sim::engine_name(engine) : options.out;
  };
  for (const ci::sim::Engine engine : options.engines) {
    const std::string why = writable_folder(folder_of(engine));
    if (!why.empty()) usage_error("--out '" + folder_of(engine).string() + "': " + why);
  }

  std::string why_not;
  const bool render = options.render && ci::sim::offscreen_rendering_available(&why_not);
  std::vector<Tour> tours;
  std::vector<std::string> not_written;  // files that are not there, with why
  for (const ci::sim::Engine engine : options.engines) {
    const fs::path out = folder_of(engine);
    std::cout << (tours.empty() ? "" : "\n") << "Cartesian impedance demo: " << options.robot.name
              << " in " << ci::demo::engine_title(engine) << " at 1 kHz, "
              << options.scenarios.size() << " scenarios, output in " << out.string() << "\n";
    if (!options.robot.plant.nominal()) {
      std::cout << "Plant: " << options.plant << " (seed " << options.plant_seed
                << "): the simulated arm is not the controller's model, and the checks' bounds "
                   "are the nominal plant's\n";
    }
    if (options.render && !render) std::cout << "(no pictures: " << why_not << ")\n";
    tours.push_back(run_tour(options, scenarios::with_engine(options.robot, engine), out, render));
    print_summary(tours.back().results);
    not_written.insert(not_written.end(), tours.back().not_written.begin(),
                       tours.back().not_written.end());
    if (options.plots) {
      const std::string failure = make_plots(out);
      if (!failure.empty()) {
        not_written.push_back("the plots in '" + out.string() + "' were not made: " + failure +
                              " (--no-plots skips them)");
      }
    }
  }
  if (both) {
    std::cout << "\nTheory, MuJoCo and DART side by side (also in "
              << (options.out / "engines.csv").string() << "):\n";
    ci::demo::print_engine_table(tours[0].results, tours[1].results, std::cout);
    try {
      ci::demo::write_engine_table(options.out / "engines.csv", tours[0].results, tours[1].results);
    } catch (const ci::Error& failure) {
      not_written.push_back(failure.what());
    }
  }

  // Three verdicts, three exit codes: a measurement that disagrees with theory (1) is a finding
  // about the controller; a scenario that could not run (3) is not, and says nothing either way.
  std::cout << "\nLogs, plots and pictures: " << fs::absolute(options.out).string() << "\n";
  bool every_check_passed = true;
  std::size_t not_run = 0, not_applicable = 0;
  for (std::size_t t = 0; t < tours.size(); ++t) {
    for (const std::string& why : tours[t].not_run) {
      std::cout << "Could not run " << (both ? ci::sim::engine_name(options.engines[t]) : "")
                << (both ? " " : "") << why << "\n";
    }
    every_check_passed &= tours[t].every_check_passed;
    not_run += tours[t].not_run.size();
    not_applicable += static_cast<std::size_t>(
        std::count_if(tours[t].results.begin(), tours[t].results.end(),
                      [](const scenarios::Result& r) { return !r.applicable; }));
  }
  // A missing log or plot is said last, where it is seen, and is never hidden by a success.
  for (const std::string& why : not_written) std::cout << "Not written: " << why << "\n";
  if (!every_check_passed) {
    std::cout << "Some measurements disagree with theory (FAIL above).\n";
    return 1;
  }
  if (not_run > 0 || !not_written.empty()) {
    if (not_run > 0) {
      std::cout << not_run << " of " << options.scenarios.size() * tours.size()
                << " scenarios could not run";
    } else {
      std::cout << not_written.size() << " outputs could not be written";
    }
    std::cout << "; every measurement that was made agrees with theory.\n";
    return 3;
  }
  if (not_applicable > 0) {
    std::cout << not_applicable << " checks do not apply to this robot (n/a above, with why).\n";
  }
  std::cout << "Every measurement agrees with theory.\n";
  return 0;
}
