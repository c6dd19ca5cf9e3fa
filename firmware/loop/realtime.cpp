#include "firmware/loop/realtime.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>

namespace fs::fw {

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
  return r;
}

}  // namespace fs::fw
