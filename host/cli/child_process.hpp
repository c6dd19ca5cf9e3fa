#pragma once
// Child processes of `facetscan demo --fleet`: started with posix_spawn, output to a log file, extra
// environment variables; stopped with a signal. The destructor kills (SIGKILL) and reaps what still runs.
#include <sys/types.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace fs::host::cli {

class ChildProcess {
 public:
  // Starts argv[0] (a path) with `env` added to this process's environment, stdout and stderr appended to
  // `log`. Throws fs::Error naming the program when it cannot be started.
  ChildProcess(std::vector<std::string> argv, const std::map<std::string, std::string>& env,
               const std::filesystem::path& log);
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  bool running();  // false once it exited (reaped)
  // Sends `sig` and waits up to `timeout_ms` (then SIGKILL); returns the exit code (128 + signal).
  int stop(int sig, int timeout_ms);
  // Waits for the exit: the exit code (128 + signal), or -1 after timeout_ms.
  int wait(int timeout_ms);
  const std::string& name() const { return name_; }
  const std::filesystem::path& log() const { return log_; }
  // The last `max_bytes` of the log, for error messages.
  std::string log_tail(std::size_t max_bytes = 2000) const;

 private:
  pid_t pid_ = -1;
  int status_ = 0;
  bool exited_ = false;
  std::string name_;
  std::filesystem::path log_;
};

// The executable `name` in a folder of $PATH (/usr/bin:/usr/sbin when unset); empty when there is none.
std::filesystem::path find_program(const std::string& name);
// A TCP port on 127.0.0.1 that was free a moment ago (bound to port 0, then closed).
int free_local_port();
// True when something accepts TCP connections on 127.0.0.1:port.
bool local_port_open(int port);

}  // namespace fs::host::cli
