#include "demo_output.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::demo {
namespace {

// A CSV file being written; finish() closes it and throws if any of it did not reach the file
// (an unwritable folder, a full disk), so that no run reports success over missing logs.
class CsvFile {
 public:
  explicit CsvFile(const std::filesystem::path& path) : path_(path) {
    errno = 0;  // the system's reason, if opening fails, and no older one
    stream_.open(path);
    if (!stream_) fail("cannot be created");
  }
  std::ofstream& stream() { return stream_; }
  void finish() {
    errno = 0;
    stream_.close();  // flushes: a full disk shows here
    if (!stream_) fail("could not be written completely");
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    const int error = errno;
    throw Error("output file '" + path_.string() + "' " + what +
                (error != 0 ? std::string(": ") + std::strerror(error) : std::string()));
  }
  std::filesystem::path path_;
  std::ofstream stream_;
};

std::string csv_field(const std::string& text) {
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

void write_three(std::ostream& csv, const Eigen::Vector3d& v) {
  csv << "," << v.x() << "," << v.y() << "," << v.z();
}

void write_joints(std::ostream& csv, const JointVector& v, int joints) {
  for (int i = 0; i < joints; ++i) csv << "," << (i < v.size() ? v[i] : 0.0);
}

}  // namespace

void write_samples(const std::filesystem::path& path,
                   const std::vector<scenarios::Sample>& samples) {
  CsvFile file(path);
  std::ofstream& csv = file.stream();
  const char* const axes[6] = {"x", "y", "z", "rx", "ry", "rz"};
  csv << "time,phase,x,y,z,reference_x,reference_y,reference_z,commanded_x,commanded_y,"
         "commanded_z";
  for (const char* prefix : {"error_", "stiffness_", "commanded_stiffness_"}) {
    for (const char* axis : axes) csv << "," << prefix << axis;
  }
  csv << ",push_x,push_y,push_z,push_torque_x,push_torque_y,push_torque_z,contact_x,contact_y,"
         "contact_z,wrench_x,wrench_y,wrench_z,commanded_wrench_x,commanded_wrench_y,"
         "commanded_wrench_z,max_torque_rate";
  const int joints = samples.empty() ? 0 : static_cast<int>(samples.front().tau.size());
  for (const char* prefix : {"tau_", "q_", "nullspace_q_", "commanded_nullspace_q_"}) {
    for (int i = 0; i < joints; ++i) csv << "," << prefix << i + 1;
  }
  csv << "\n";
  for (const scenarios::Sample& s : samples) {
    csv << s.time << "," << csv_field(s.phase);
    for (const Eigen::Vector3d* v : {&s.position, &s.reference, &s.commanded}) write_three(csv, *v);
    for (const Vector6d* v : {&s.pose_error, &s.stiffness, &s.commanded_stiffness}) {
      for (int i = 0; i < 6; ++i) csv << "," << (*v)[i];
    }
    for (const Eigen::Vector3d* v :
         {&s.push, &s.push_torque, &s.contact, &s.wrench, &s.commanded_wrench}) {
      write_three(csv, *v);
    }
    csv << "," << s.max_torque_rate;
    for (const JointVector* v :
         {&s.tau, &s.q, &s.nullspace_target, &s.commanded_nullspace_target}) {
      write_joints(csv, *v, joints);
    }
    csv << "\n";
  }
  file.finish();
}

void write_table(const std::filesystem::path& path, const scenarios::Table& table) {
  CsvFile file(path);
  std::ofstream& csv = file.stream();
  for (std::size_t i = 0; i < table.columns.size(); ++i) {
    csv << (i == 0 ? "" : ",") << table.columns[i];
  }
  csv << "\n";
  for (const std::vector<double>& row : table.rows) {
    for (std::size_t i = 0; i < row.size(); ++i) csv << (i == 0 ? "" : ",") << row[i];
    csv << "\n";
  }
  file.finish();
}

void write_summary(const std::filesystem::path& path, const std::vector<scenarios::Result>& all) {
  CsvFile file(path);
  std::ofstream& summary = file.stream();
  summary << "scenario,quantity,theory,measured,unit,tolerance,passed\n";
  for (const scenarios::Result& r : all) {
    summary << csv_field(r.scenario) << "," << csv_field(r.quantity) << "," << r.expected << ","
            << r.measured << "," << csv_field(r.unit) << "," << r.tolerance << ","
            << (!r.applicable ? "n/a"
                : r.passed    ? "yes"
                              : "no")
            << "\n";
  }
  file.finish();
}

std::string picture_file_name(const std::string& scenario, const std::string& label) {
  std::string file = scenario + "_" + label + ".png";
  for (char& c : file) c = c == ' ' || c == ',' ? '_' : c;
  return file;
}

std::string expectation(const scenarios::Result& r) {
  char text[96];
  if (r.bound) {
    std::snprintf(text, sizeof(text), "<= %.4g %s", r.expected, r.unit.c_str());
  } else if (r.tolerance > 0.0) {
    std::snprintf(text, sizeof(text), "%.4g +- %.2g %s", r.expected, r.tolerance, r.unit.c_str());
  } else if (r.note.rfind("at least", 0) == 0) {
    std::snprintf(text, sizeof(text), ">= %.4g %s", r.expected, r.unit.c_str());
  } else {
    std::snprintf(text, sizeof(text), "%.4g %s", r.expected, r.unit.c_str());
  }
  return text;
}

std::string measurement(const scenarios::Result& r) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.4g %s", r.measured, r.unit.c_str());
  return text;
}

const char* engine_title(sim::Engine engine) {
  return engine == sim::Engine::dart ? "DART" : "MuJoCo";
}

namespace {

struct EngineRow {
  const scenarios::Result* mujoco = nullptr;
  const scenarios::Result* dart = nullptr;
};

std::vector<EngineRow> engine_rows(const std::vector<scenarios::Result>& mujoco,
                                   const std::vector<scenarios::Result>& dart) {
  std::vector<EngineRow> rows;
  std::vector<bool> used(dart.size(), false);
  const auto same = [](const scenarios::Result& a, const scenarios::Result& b) {
    return a.scenario == b.scenario && a.quantity == b.quantity;
  };
  for (const scenarios::Result& m : mujoco) {
    EngineRow row{&m, nullptr};
    for (std::size_t i = 0; i < dart.size() && row.dart == nullptr; ++i) {
      if (!used[i] && same(m, dart[i])) {
        used[i] = true;
        row.dart = &dart[i];
      }
    }
    rows.push_back(row);
  }
  for (std::size_t i = 0; i < dart.size(); ++i) {
    if (!used[i]) rows.push_back({nullptr, &dart[i]});
  }
  return rows;
}

std::string verdict(const scenarios::Result* r) {
  if (r == nullptr) return "-";
  if (!r->applicable) return "n/a";
  return measurement(*r) + (r->passed ? " ok" : " FAIL");
}

std::string theory(const EngineRow& row) {
  const scenarios::Result* first = row.mujoco != nullptr ? row.mujoco : row.dart;
  if (!first->applicable) return "-";
  std::string text = expectation(*first);
  if (row.mujoco != nullptr && row.dart != nullptr && row.dart->applicable &&
      expectation(*row.dart) != text) {
    text += " / " + expectation(*row.dart);
  }
  return text;
}

}  // namespace

void print_engine_table(const std::vector<scenarios::Result>& mujoco,
                        const std::vector<scenarios::Result>& dart, std::ostream& out) {
  char line[512];
  std::snprintf(line, sizeof(line), "%-18s %-62s %-26s %-20s %s\n", "scenario", "what", "theory",
                "MuJoCo", "DART");
  out << line;
  for (const EngineRow& row : engine_rows(mujoco, dart)) {
    const scenarios::Result& any = row.mujoco != nullptr ? *row.mujoco : *row.dart;
    std::snprintf(line, sizeof(line), "%-18s %-62s %-26s %-20s %s\n", any.scenario.c_str(),
                  any.quantity.c_str(), theory(row).c_str(), verdict(row.mujoco).c_str(),
                  verdict(row.dart).c_str());
    out << line;
  }
}

void write_engine_table(const std::filesystem::path& path,
                        const std::vector<scenarios::Result>& mujoco,
                        const std::vector<scenarios::Result>& dart) {
  CsvFile file(path);
  std::ofstream& csv = file.stream();
  csv << "scenario,quantity,unit,theory,mujoco,mujoco_passed,dart,dart_passed\n";
  const auto value = [](const scenarios::Result* r) {
    return r == nullptr || !r->applicable ? std::string() : std::to_string(r->measured);
  };
  const auto passed = [](const scenarios::Result* r) {
    return r == nullptr     ? std::string()
           : !r->applicable ? std::string("n/a")
                            : std::string(r->passed ? "yes" : "no");
  };
  for (const EngineRow& row : engine_rows(mujoco, dart)) {
    const scenarios::Result& any = row.mujoco != nullptr ? *row.mujoco : *row.dart;
    csv << csv_field(any.scenario) << "," << csv_field(any.quantity) << "," << csv_field(any.unit)
        << "," << csv_field(theory(row)) << "," << value(row.mujoco) << "," << passed(row.mujoco)
        << "," << value(row.dart) << "," << passed(row.dart) << "\n";
  }
  file.finish();
}

}  // namespace cartesian_impedance::demo
