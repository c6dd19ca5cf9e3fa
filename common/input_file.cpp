#include "common/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "common/error.hpp"

namespace fs {

std::string format_bytes(std::uint64_t n) {
  if (n < 10000) return std::to_string(n) + " bytes";
  // Decimal units with one decimal: "1.6 GB".
  char buf[32];
  const double d = static_cast<double>(n);
  if (d >= 1e12)
    std::snprintf(buf, sizeof buf, "%.1f TB", d / 1e12);
  else if (d >= 1e9)
    std::snprintf(buf, sizeof buf, "%.1f GB", d / 1e9);
  else if (d >= 1e6)
    std::snprintf(buf, sizeof buf, "%.1f MB", d / 1e6);
  else
    std::snprintf(buf, sizeof buf, "%.1f kB", d / 1e3);
  return buf;
}

std::string format_cap(std::uint64_t n) {
  // Caps are whole binary multiples: "1 MiB", "4 GiB".
  if (n >= kGiB && n % kGiB == 0) return std::to_string(n / kGiB) + " GiB";
  if (n >= kMiB && n % kMiB == 0) return std::to_string(n / kMiB) + " MiB";
  return format_bytes(n);
}

std::string file_type_name(unsigned mode) {
  switch (mode & S_IFMT) {
    case S_IFREG:
      return "regular file";
    case S_IFDIR:
      return "directory";
    case S_IFCHR:
      return "character device";
    case S_IFBLK:
      return "block device";
    case S_IFIFO:
      return "FIFO";
    case S_IFSOCK:
      return "socket";
    case S_IFLNK:
      return "symbolic link";
    default:
      return "unknown file type";
  }
}

int open_input_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what,
                    std::uint64_t& size) {
  const std::string name = path.string();
  // O_NONBLOCK: opening a FIFO must not wait for a writer (it is refused below anyway).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw Error(name + ": cannot open " + std::string(what) + ": " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw Error(name + ": cannot stat " + std::string(what) + ": " + std::strerror(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw Error(name + ": not a regular file (" + file_type_name(st.st_mode) + ")");
  }
  size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_bytes) {
    ::close(fd);
    throw Error(name + ": " + format_bytes(size) + ", more than the " + format_cap(max_bytes) + " a " +
                std::string(what) + " may have");
  }
  return fd;
}

namespace {

// Reads the whole regular file into a container of 1-byte elements, at most max_bytes even if it grows.
template <class Container>
Container read_all(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what) {
  // A 32-bit process cannot hold more than this in one piece anyway.
  max_bytes = std::min<std::uint64_t>(max_bytes, PTRDIFF_MAX / 2);
  std::uint64_t size = 0;
  const int fd = open_input_file(path, max_bytes, what, size);
  Container out;
  std::size_t got = 0;
  try {
    out.resize(static_cast<std::size_t>(size));
    for (;;) {
      if (got == out.size()) {
        // At the size fstat() gave: the file may have grown since. A small read tells before the container
        // grows (growing would copy the whole file once more); what it finds is appended, to max_bytes + 1.
        if (got > max_bytes) break;
        char probe[4096];
        const ssize_t r = ::read(fd, probe, sizeof probe);
        if (r < 0) {
          if (errno == EINTR) continue;
          throw Error(path.string() + ": read error: " + std::strerror(errno));
        }
        if (r == 0) break;
        const auto take = static_cast<std::size_t>(
            std::min<std::uint64_t>(static_cast<std::uint64_t>(r), max_bytes + 1 - got));
        out.resize(got + take);
        std::memcpy(reinterpret_cast<char*>(out.data()) + got, probe, take);
        got += take;
        continue;
      }
      const ssize_t r = ::read(fd, reinterpret_cast<char*>(out.data()) + got, out.size() - got);
      if (r < 0) {
        if (errno == EINTR) continue;
        throw Error(path.string() + ": read error: " + std::strerror(errno));
      }
      if (r == 0) break;
      got += static_cast<std::size_t>(r);
    }
  } catch (...) {
    ::close(fd);
    throw;
  }
  ::close(fd);
  if (got > max_bytes)
    throw Error(path.string() + ": grew beyond the " + format_cap(max_bytes) + " a " + std::string(what) +
                " may have while being read");
  out.resize(got);
  return out;
}

}  // namespace

std::string read_input_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                            std::string_view what) {
  return read_all<std::string>(path, max_bytes, what);
}

ByteBuffer read_input_bytes(const std::filesystem::path& path, std::uint64_t max_bytes,
                            std::string_view what) {
  return read_all<ByteBuffer>(path, max_bytes, what);
}

void check_declared(const std::string& source, std::string_view field, std::uint64_t declared,
                    std::uint64_t element_bytes, std::uint64_t bytes_left, std::string_view after) {
  // declared * element_bytes without overflow: compare by division.
  if (element_bytes == 0 || declared <= bytes_left / element_bytes) return;
  std::string need;
  if (declared > UINT64_MAX / element_bytes)
    need = "more than 2^64 bytes";
  else
    need = format_bytes(declared * element_bytes);
  throw Error(source + ": " + std::string(field) + " " + std::to_string(declared) + " x " +
              std::to_string(element_bytes) + (element_bytes == 1 ? " byte" : " bytes") + " = " + need +
              " but the file has " + std::to_string(bytes_left) + " bytes " + std::string(after));
}

}  // namespace fs
