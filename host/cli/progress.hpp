#pragma once
// A progress bar on stderr for jobs that take more than a second (library builds, batch recognition, scans
// arriving in the demo). Quiet mode (scripts) prints nothing.
#include <chrono>
#include <cstdio>
#include <string>

namespace fs::host::cli {

class Progress {
 public:
  Progress(std::size_t total, bool quiet, double show_after_s = 1.0)
      : total_(total), quiet_(quiet), show_after_s_(show_after_s), start_(std::chrono::steady_clock::now()) {}
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  void set_total(std::size_t total) { total_ = total; }
  void update(std::size_t done, const std::string& what) {
    if (quiet_) return;
    const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start_;
    if (!shown_ && elapsed.count() < show_after_s_) return;
    shown_ = true;
    constexpr int kWidth = 30;
    const int fill = total_ ? static_cast<int>(kWidth * std::min(done, total_) / total_) : kWidth;
    std::fprintf(
        stderr, "\r[%s%s] %zu/%zu %-40.40s", std::string(static_cast<std::size_t>(fill), '#').c_str(),
        std::string(static_cast<std::size_t>(kWidth - fill), ' ').c_str(), done, total_, what.c_str());
    std::fflush(stderr);
  }
  void finish() {
    if (shown_) std::fprintf(stderr, "\n");
    shown_ = false;
    quiet_ = true;
  }
  ~Progress() { finish(); }

 private:
  std::size_t total_;
  bool quiet_;
  double show_after_s_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace fs::host::cli
