#pragma once
// A named pipe (FIFO) for the tests of loaders that must refuse one. Opening a FIFO to read waits
// for a writer, so a loader that does not refuse it would hang the test forever; a helper thread
// here opens the FIFO itself every `patience` (read-write, which never blocks on Linux, and counts
// as the writer a blocked reader waits for) and closes it again. A loader that refuses the FIFO
// is done long before; one that does not then reads an empty file and fails the test with its
// own message instead of hanging it.

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

namespace cartesian_impedance::test {

class Fifo {
 public:
  explicit Fifo(const std::string& name,
                std::chrono::milliseconds patience = std::chrono::milliseconds(5000))
      : path_((std::filesystem::temp_directory_path() /
               ("ci_fifo_" + std::to_string(::getpid()) + "_" + name))
                  .string()) {
    std::filesystem::remove(path_);
    if (::mkfifo(path_.c_str(), 0600) != 0) throw std::runtime_error("mkfifo " + path_);
    unblocker_ = std::thread([this, patience] {
      std::unique_lock<std::mutex> lock(mutex_);
      while (!done_condition_.wait_for(lock, patience, [this] { return done_; })) {
        const int fd = ::open(path_.c_str(), O_RDWR | O_NONBLOCK);
        if (fd >= 0) ::close(fd);
      }
    });
  }
  Fifo(const Fifo&) = delete;
  Fifo& operator=(const Fifo&) = delete;
  ~Fifo() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    done_condition_.notify_all();
    unblocker_.join();
    std::filesystem::remove(path_);
  }

  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::mutex mutex_;
  std::condition_variable done_condition_;
  bool done_ = false;
  std::thread unblocker_;
};

}  // namespace cartesian_impedance::test
