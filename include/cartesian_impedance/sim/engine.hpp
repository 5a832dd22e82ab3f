#pragma once
/// @file
/// The physics engines a simulation can integrate with: one enum for the simulation, the node
/// settings and both ROS nodes. Header-only and free of MuJoCo and DART, so that code which only
/// names an engine (a node's settings) needs neither library.

#include <array>
#include <string>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::sim {

/// The physics engine that integrates a Simulation.
enum class Engine {
  /// MuJoCo 2.2: soft contacts, implicit joint damping; MJCF and URDF files.
  mujoco,
  /// DART 6.12 (Lee et al. 2018, the simulator of the published controller): articulated-body
  /// dynamics, hard contacts and joint friction solved as a complementarity problem; URDF files
  /// only. The DART build option must be on (engine_available() in simulation.hpp).
  dart,
};

/// Every engine, in the order of the enum.
inline constexpr std::array<Engine, 2> kEngines = {Engine::mujoco, Engine::dart};

/// "mujoco" or "dart".
constexpr const char* engine_name(Engine engine) noexcept {
  return engine == Engine::dart ? "dart" : "mujoco";
}

/// The engine of that name ("mujoco", "dart").
/// @throw Error naming the value and the known engines for any other name.
inline Engine engine_from_name(const std::string& name) {
  for (const Engine engine : kEngines) {
    if (name == engine_name(engine)) return engine;
  }
  throw Error("engine '" + name + "' is not known; the engines are: mujoco, dart");
}

}  // namespace cartesian_impedance::sim
