#pragma once
// What the demo writes besides its console report: CSV logs of the samples and of the scenarios'
// tables, the summary, and the names of the pictures. Every writer throws
// cartesian_impedance::Error naming the file when any of it could not be written (the folder
// refuses it, the disk is full).

#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "scenarios.hpp"

namespace cartesian_impedance::demo {

/// One row per sample: time, phase, positions, errors, every commanded quantity, torques.
void write_samples(const std::filesystem::path& path,
                   const std::vector<scenarios::Sample>& samples);

/// A scenario's table as CSV.
void write_table(const std::filesystem::path& path, const scenarios::Table& table);

/// summary.csv: one row per result line; passed is yes, no or n/a.
void write_summary(const std::filesystem::path& path, const std::vector<scenarios::Result>& all);

/// "hold_holding_a_1_kg_payload.png": the scenario and the moment's label, without spaces.
std::string picture_file_name(const std::string& scenario, const std::string& label);

/// "20 +- 1 mm", "<= 0.5 mm", ">= 3 s": what theory says, for the report.
std::string expectation(const scenarios::Result& result);
/// "20.3 mm"
std::string measurement(const scenarios::Result& result);

/// "MuJoCo", "DART".
const char* engine_title(sim::Engine engine);

/// Per result line: theory, MuJoCo's measurement and DART's, each with its verdict. Lines are
/// matched by scenario and quantity; theory is MuJoCo's, followed by DART's where it differs
/// (a tolerance derived from the simulated friction, say).
void print_engine_table(const std::vector<scenarios::Result>& mujoco,
                        const std::vector<scenarios::Result>& dart, std::ostream& out);
/// The same as CSV: scenario, quantity, unit, theory, mujoco, mujoco_passed, dart, dart_passed.
void write_engine_table(const std::filesystem::path& path,
                        const std::vector<scenarios::Result>& mujoco,
                        const std::vector<scenarios::Result>& dart);

}  // namespace cartesian_impedance::demo
