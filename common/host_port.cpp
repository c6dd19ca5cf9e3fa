#include "common/host_port.hpp"

#include <charconv>

#include "common/error.hpp"

namespace fs {

void split_host_port(const std::string& spec, std::string_view what, std::string_view form,
                     std::uint16_t min_port, std::string& host, std::uint16_t& port) {
  const std::string prefix = std::string(what) + " '" + spec + "': ";
  const std::size_t colon = spec.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == spec.size())
    throw Error(prefix + "expected " + std::string(form));
  host = spec.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  unsigned v = 0;
  const char* b = spec.data() + colon + 1;
  const char* e = spec.data() + spec.size();
  const auto [p, ec] = std::from_chars(b, e, v);
  if (ec != std::errc() || p != e || v < min_port || v > 65535)
    throw Error(prefix + "port must be " + std::to_string(min_port) + "..65535");
  port = static_cast<std::uint16_t>(v);
}

}  // namespace fs
