#pragma once
// "HOST:PORT" addresses (IPv6 in brackets: "[::1]:5555"), shared by the firmware's stream target and the
// host's listen address.
#include <cstdint>
#include <string>
#include <string_view>

namespace fs {

// Splits spec at its last ':' into host (brackets of an IPv6 literal removed) and port in [min_port, 65535].
// Errors (fs::Error) read "<what> '<spec>': expected <form>" or "<what> '<spec>': port must be <min>..65535".
void split_host_port(const std::string& spec, std::string_view what, std::string_view form,
                     std::uint16_t min_port, std::string& host, std::uint16_t& port);

}  // namespace fs
