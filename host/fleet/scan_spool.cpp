#include "host/fleet/scan_spool.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <utility>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/fleet/ids.hpp"

namespace fs::host::fleet {

namespace stdfs = std::filesystem;

namespace {

constexpr std::array<std::pair<ScanStatus, const char*>, 8> kTokens = {{
    {ScanStatus::InProgress, "in-progress"},
    {ScanStatus::Complete, "complete"},
    {ScanStatus::Aborted, "aborted"},
    {ScanStatus::MissingStripes, "missing-stripes"},
    {ScanStatus::Disconnected, "disconnected"},
    {ScanStatus::Superseded, "superseded"},
    {ScanStatus::ProtocolError, "protocol-error"},
    {ScanStatus::OverBudget, "over-budget"},
}};

std::string errno_text() { return std::strerror(errno); }

// Writes all of `data` to a new file and fsyncs it; throws naming the path.
void write_synced(const stdfs::path& path, std::span<const std::uint8_t> data) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(fmt::format("{}: cannot create ({})", path.string(), errno_text()));
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = errno_text();
      ::close(fd);
      ::unlink(path.c_str());
      throw Error(fmt::format("{}: cannot write ({})", path.string(), why));
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const std::string why = errno_text();
    ::unlink(path.c_str());
    throw Error(fmt::format("{}: cannot write ({})", path.string(), why));
  }
}

void sync_dir(const stdfs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// "s<16 hex>": the nonce of a streamed scan's id.
std::optional<std::uint64_t> parse_nonce(const std::string& t) {
  if (t.size() != 17 || t[0] != 's' || t.find_first_not_of("0123456789abcdef", 1) != std::string::npos)
    return std::nullopt;
  return std::stoull(t.substr(1), nullptr, 16);
}

// "<sequence>_<scanner>_<token>[_s<nonce>].fscan" -> entry; nullopt for any other name.
std::optional<SpoolEntry> parse_name(const stdfs::path& p) {
  if (p.extension() != ".fscan") return std::nullopt;
  std::string stem = p.stem().string();
  std::optional<std::uint64_t> nonce;
  if (const auto n = stem.rfind('_'); n != std::string::npos && (nonce = parse_nonce(stem.substr(n + 1))))
    stem.resize(n);
  const auto a = stem.find('_');
  const auto b = stem.rfind('_');
  if (a != 12 || b == a || b == std::string::npos) return std::nullopt;
  SpoolEntry e;
  e.path = p;
  e.stream_nonce = nonce;
  for (std::size_t i = 0; i < a; ++i) {
    if (stem[i] < '0' || stem[i] > '9') return std::nullopt;
    e.sequence = e.sequence * 10 + static_cast<std::uint64_t>(stem[i] - '0');
  }
  e.scanner_id = stem.substr(a + 1, b - a - 1);
  try {
    check_scanner_id(e.scanner_id);
    e.status = parse_status_token(stem.substr(b + 1));
  } catch (const Error&) {
    return std::nullopt;
  }
  return e;
}

}  // namespace

const char* status_token(ScanStatus s) {
  for (const auto& [status, token] : kTokens)
    if (status == s) return token;
  return "complete";
}

ScanStatus parse_status_token(const std::string& token) {
  for (const auto& [status, t] : kTokens)
    if (token == t) return status;
  throw Error("unknown scan status token '" + token + "'");
}

ScanSpool::ScanSpool(stdfs::path dir, std::uint64_t max_bytes) : dir_(std::move(dir)), max_bytes_(max_bytes) {
  std::error_code ec;
  stdfs::create_directories(dir_, ec);
  if (!stdfs::is_directory(dir_))
    throw Error(fmt::format("spool {}: cannot create the directory ({})", dir_.string(),
                            ec ? ec.message() : "not a directory"));
  if (::access(dir_.c_str(), W_OK) != 0)
    throw Error(fmt::format("spool {}: not writable ({})", dir_.string(), errno_text()));
  for (const auto& de : stdfs::directory_iterator(dir_)) {
    const std::string name = de.path().filename().string();
    if (name.rfind(".partial-", 0) == 0) {
      stdfs::remove(de.path(), ec);  // an interrupted write: never published, never acknowledged
      continue;
    }
    if (!de.is_regular_file()) continue;
    if (auto e = parse_name(de.path())) {
      e->bytes = de.file_size();
      entries_.push_back(*e);
    }
  }
  std::sort(entries_.begin(), entries_.end(),
            [](const SpoolEntry& x, const SpoolEntry& y) { return x.sequence < y.sequence; });
  for (const SpoolEntry& e : entries_) bytes_ += e.bytes;
  if (!entries_.empty()) next_sequence_ = entries_.back().sequence + 1;
  if (stdfs::is_directory(dir_ / "rejected"))
    for (const auto& de : stdfs::directory_iterator(dir_ / "rejected"))
      if (de.path().extension() == ".fscan") ++rejected_;
}

bool ScanSpool::has_room(std::uint64_t bytes) const {
  std::lock_guard lock(mu_);
  return entries_.empty() || bytes_ + bytes <= max_bytes_;
}

SpoolEntry ScanSpool::put(std::span<const std::uint8_t> image, const std::string& scanner_id,
                          ScanStatus status, std::optional<std::uint64_t> stream_nonce) {
  check_scanner_id(scanner_id);
  std::uint64_t seq = 0;
  {
    std::lock_guard lock(mu_);
    seq = next_sequence_++;
  }
  SpoolEntry e;
  e.sequence = seq;
  e.scanner_id = scanner_id;
  e.status = status;
  e.bytes = image.size();
  e.stream_nonce = stream_nonce;
  e.path = dir_ / fmt::format("{:012}_{}_{}{}.fscan", seq, scanner_id, status_token(status),
                              stream_nonce ? fmt::format("_s{:016x}", *stream_nonce) : std::string());
  const stdfs::path tmp = dir_ / fmt::format(".partial-{:012}", seq);
  write_synced(tmp, image);
  std::error_code ec;
  stdfs::rename(tmp, e.path, ec);
  if (ec) {
    stdfs::remove(tmp, ec);
    throw Error(fmt::format("{}: cannot rename into place ({})", e.path.string(), ec.message()));
  }
  sync_dir(dir_);
  std::lock_guard lock(mu_);
  // Sequences are taken in order but writes may finish out of order: keep the list sorted.
  const auto at =
      std::upper_bound(entries_.begin(), entries_.end(), e,
                       [](const SpoolEntry& x, const SpoolEntry& y) { return x.sequence < y.sequence; });
  entries_.insert(at, e);
  bytes_ += e.bytes;
  return e;
}

std::optional<SpoolEntry> ScanSpool::oldest() const {
  std::lock_guard lock(mu_);
  if (entries_.empty()) return std::nullopt;
  return entries_.front();
}

std::vector<std::uint8_t> ScanSpool::read(const SpoolEntry& entry) const {
  std::ifstream f(entry.path, std::ios::binary);
  if (!f) throw Error(entry.path.string() + ": cannot open");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) throw Error(entry.path.string() + ": read error");
  return bytes;
}

void ScanSpool::forget(std::uint64_t sequence) {
  const auto it = std::find_if(entries_.begin(), entries_.end(),
                               [&](const SpoolEntry& x) { return x.sequence == sequence; });
  if (it != entries_.end()) {
    bytes_ -= it->bytes;
    entries_.erase(it);
  }
}

void ScanSpool::remove(const SpoolEntry& entry) {
  std::error_code ec;
  stdfs::remove(entry.path, ec);
  if (ec) throw Error(fmt::format("{}: cannot remove ({})", entry.path.string(), ec.message()));
  std::lock_guard lock(mu_);
  forget(entry.sequence);
}

stdfs::path ScanSpool::reject(const SpoolEntry& entry, const std::string& reason) {
  const stdfs::path rdir = dir_ / "rejected";
  std::error_code ec;
  stdfs::create_directories(rdir, ec);
  const stdfs::path to = rdir / entry.path.filename();
  stdfs::rename(entry.path, to, ec);
  if (ec)
    throw Error(fmt::format("{}: cannot move to {} ({})", entry.path.string(), to.string(), ec.message()));
  std::ofstream(to.string() + ".reason") << reason << "\n";
  std::lock_guard lock(mu_);
  forget(entry.sequence);
  ++rejected_;
  return to;
}

std::size_t ScanSpool::count() const {
  std::lock_guard lock(mu_);
  return entries_.size();
}

std::uint64_t ScanSpool::bytes() const {
  std::lock_guard lock(mu_);
  return bytes_;
}

std::size_t ScanSpool::rejected() const {
  std::lock_guard lock(mu_);
  return rejected_;
}

}  // namespace fs::host::fleet
