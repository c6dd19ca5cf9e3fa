#pragma once
// Where the controller loop sends its messages. The loop thread calls these; implementations must neither
// block on I/O nor allocate per call (QueuedPublisher: copy into a preallocated ring, an output thread does
// the I/O).
#include <cstdint>

#include "common/messages.hpp"

namespace fs::fw {

class Publisher {
 public:
  virtual ~Publisher() = default;
  // Start of a scan (start-up time: may allocate).
  virtual void begin(const msg::ScanBegin& m) = 0;
  // false when the stripe had to be dropped (queue full); the publisher counts it too.
  virtual bool stripe(const msg::Stripe& m) = 0;
  virtual void heartbeat(const msg::Heartbeat& m) = 0;
  // code + text (text is truncated to msg::kMaxFaultText).
  virtual void fault(std::uint32_t code, const char* text) = 0;
  virtual void end(const msg::ScanEnd& m) = 0;
  // Health of the host link (always true without streaming).
  virtual bool host_connected() const { return true; }
  // Stripes lost so far (queue overflow + host link buffer overflow).
  virtual std::uint32_t stripes_dropped() const = 0;
};

}  // namespace fs::fw
