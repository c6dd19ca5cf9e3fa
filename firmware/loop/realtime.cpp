#include "firmware/loop/realtime.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>

namespace fs::fw {

bool CpuLatencyLimit::request(int microseconds, std::string* error, const char* device) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = ::open(device, O_WRONLY | O_CLOEXEC);
  if (fd_ < 0) {
    if (error) *error = std::string(device) + ": " + std::strerror(errno);
    return false;
  }
  // The device takes the limit as a binary 32-bit value (microseconds).
  const std::int32_t us = microseconds;
  if (::write(fd_, &us, sizeof us) != static_cast<ssize_t>(sizeof us)) {
    if (error) *error = std::string(device) + ": write: " + std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    return false;
  }
  return true;
}

CpuLatencyLimit& CpuLatencyLimit::operator=(CpuLatencyLimit&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}

CpuLatencyLimit::~CpuLatencyLimit() {
  if (fd_ >= 0) ::close(fd_);
}

RealtimeResult apply_realtime(const RealtimeRequest& req) {
  RealtimeResult r;
  if (req.lock_memory) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0)
      r.locked = true;
    else
      r.warnings.push_back(
          std::string("mlockall failed (") + std::strerror(errno) +
          "): page faults may delay the loop; raise RLIMIT_MEMLOCK or run with CAP_IPC_LOCK");
  }
  sched_param sp{};
  sp.sched_priority = req.priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  if (rc == 0)
    r.fifo = true;
  else
    r.warnings.push_back(std::string("SCHED_FIFO priority ") + std::to_string(req.priority) +
                         " not permitted (" + std::strerror(rc) +
                         "): running with normal scheduling; grant CAP_SYS_NICE or RLIMIT_RTPRIO");
  if (req.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(req.cpu, &set);
    const int arc = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
    if (arc == 0)
      r.pinned = true;
    else
      r.warnings.push_back("cannot pin the loop to CPU " + std::to_string(req.cpu) + " (" +
                           std::strerror(arc) + ")");
  }
  if (req.cpu_latency_us >= 0) {
    std::string err;
    if (!r.cpu_latency.request(req.cpu_latency_us, &err))
      r.warnings.push_back("cannot limit the CPU wake-up latency to " + std::to_string(req.cpu_latency_us) +
                           " us (" + err + "): idle states may delay the loop's wake-ups");
  }
  return r;
}

}  // namespace fs::fw
