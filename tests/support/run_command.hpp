#pragma once
// Test helper: runs a shell command, stdout and stderr together, and returns its exit code (-1 when it did
// not exit normally or could not start) and output.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace fs::test {

struct CmdResult {
  int code = -1;
  std::string out;
};

inline CmdResult run(const std::string& cmd) {
  CmdResult r;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace fs::test
