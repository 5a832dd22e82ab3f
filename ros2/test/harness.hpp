#pragma once
// What the ROS 2 node tests share: the node as a child process (its own DDS domain, loopback only,
// stderr kept for the checks), a DDS client built on the node's own endpoints, and waiting for
// samples. The independent peers (Fast DDS, @foxglove/ros2) have tests of their own.

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "dds.hpp"
#include "messages.hpp"

namespace cartesian_impedance_ros2::test {

using Clock = std::chrono::steady_clock;

inline std::string repository() {
  return CARTESIAN_IMPEDANCE_SOURCE_DIR;
}

/// A loopback-only Cyclone configuration and a DDS domain of this test process's own, so that
/// parallel tests (and other machines) do not see each other. Set once, before any participant.
inline void use_private_domain() {
  static bool done = false;
  if (done) return;
  done = true;
  const std::string path = std::string(CARTESIAN_IMPEDANCE_BINARY_DIR) + "/cyclonedds_loopback.xml";
  ::setenv("CYCLONEDDS_URI", ("file://" + path).c_str(), 1);
  // Domains 0..232; one per process id, away from 0 (the default a developer's ROS 2 uses).
  ::setenv("ROS_DOMAIN_ID", std::to_string(1 + ::getpid() % 200).c_str(), 1);
}

/// The node (or another program: the simulated robot) as a child process, stopped with SIGTERM
/// (then SIGKILL) when the object goes.
class NodeProcess {
 public:
  explicit NodeProcess(const std::vector<std::string>& ros_arguments)
      : NodeProcess(CARTESIAN_IMPEDANCE_ROS2_NODE, ros_arguments) {}
  NodeProcess(const std::string& program, const std::vector<std::string>& arguments) {
    use_private_domain();
    static int count = 0;
    log_path_ = std::string(CARTESIAN_IMPEDANCE_BINARY_DIR) + "/node_" +
                std::to_string(::getpid()) + "_" + std::to_string(++count) + ".log";
    std::vector<std::string> args = {program};
    args.insert(args.end(), arguments.begin(), arguments.end());
    pid_ = ::fork();
    if (pid_ == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      const int fd = ::open(log_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(fd, STDERR_FILENO);
      ::dup2(fd, STDOUT_FILENO);
      std::vector<char*> argv;
      for (std::string& arg : args) argv.push_back(arg.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
  }
  ~NodeProcess() { stop(); }
  NodeProcess(const NodeProcess&) = delete;
  NodeProcess& operator=(const NodeProcess&) = delete;

  /// SIGTERM, then waits up to 5 s (SIGKILL after); returns the exit code (-signal if killed).
  int stop() {
    if (pid_ <= 0) return status_;
    ::kill(pid_, SIGTERM);
    status_ = wait_for_exit(5.0).value_or(-1);
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      int raw = 0;
      ::waitpid(pid_, &raw, 0);
      pid_ = -1;
      status_ = -SIGKILL;
    }
    return status_;
  }

  /// The exit code if the process ends within `seconds`.
  std::optional<int> wait_for_exit(double seconds) {
    const Clock::time_point end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                     std::chrono::duration<double>(seconds));
    while (pid_ > 0) {
      int raw = 0;
      if (::waitpid(pid_, &raw, WNOHANG) == pid_) {
        pid_ = -1;
        status_ = WIFEXITED(raw) ? WEXITSTATUS(raw) : -WTERMSIG(raw);
        return status_;
      }
      if (Clock::now() > end) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return status_;
  }

  bool running() { return pid_ > 0 && !wait_for_exit(0.0); }

  /// The node's resident memory [kB] (VmRSS), 0 if it is not running.
  long resident_kb() const {
    std::ifstream status("/proc/" + std::to_string(pid_) + "/status");
    for (std::string line; std::getline(status, line);) {
      if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    }
    return 0;
  }

  /// Everything the node wrote so far.
  std::string log() const {
    std::ifstream file(log_path_);
    std::stringstream text;
    text << file.rdbuf();
    return text.str();
  }

 private:
  pid_t pid_ = -1;
  int status_ = 0;
  std::string log_path_;
};

/// Polls `condition` every 5 ms until it holds or `seconds` pass.
inline bool eventually(double seconds, const std::function<bool()>& condition) {
  const Clock::time_point end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(seconds));
  while (Clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return condition();
}

/// The newest sample of a topic, copied out of DDS's memory by `copy`.
template <typename Message, typename Copy>
class Latest {
 public:
  Latest(const Participant& participant, const std::string& topic, Copy copy,
         const TopicQos& qos = TopicQos{})
      : reader_(participant, topic, qos), copy_(std::move(copy)) {}
  /// Takes what arrived; true if anything did.
  bool poll() {
    return reader_.take([&](const Message& message) {
      value_ = copy_(message);
      ++count_;
    }) > 0;
  }
  /// Waits up to `seconds` for a sample that satisfies `condition` (any sample if none given).
  template <typename Condition>
  bool wait(double seconds, Condition condition) {
    return eventually(seconds, [&] {
      poll();
      return count_ > 0 && condition(*value_);
    });
  }
  const auto& value() const { return *value_; }
  int count() const { return count_; }

 private:
  Reader<Message> reader_;
  Copy copy_;
  std::optional<std::invoke_result_t<Copy, const Message&>> value_;
  int count_ = 0;
};

}  // namespace cartesian_impedance_ros2::test
