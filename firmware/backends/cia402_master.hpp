#pragma once
// CiA 402 (CANopen drive profile) master for one drive in profile position mode, on a CanPort. Non-blocking:
// commands only queue frames; poll(now) reads every pending frame, advances the protocol and checks timeouts.
//
// enable():  NMT start, expedited SDO writes (1017h heartbeat, 1800h:05 TPDO event timer, 6060h=1 profile
//            position, 6081h/6083h/6084h velocity/acceleration/deceleration), SDO read-back of 6061h and
//            6041h, then controlword 06h -> 07h -> 0Fh until the statusword says "operation enabled".
// move_to(): target position with the new-set-point (cw bit 4) / set-point-acknowledge (sw bit 12) handshake;
//            a target given while a handshake runs is sent after it; in_position = target reached (sw bit
//            10).
// start_homing(): homing mode 6, method 37 (current position is home), then back to profile position.
// Faults: statusword fault bit / EMCY -> DriveFault; SDO timeout (after retries) or heartbeat missing for
// 2x the producer time or an unexpected boot-up -> CommLost; following error -> Stall; CAN_ERR_BUSOFF ->
// BusOff (transmission stops until the controller reports CAN_ERR_RESTARTED). reset_fault(): fault reset
// (cw bit 7) and re-enable for DriveFault/Stall, full re-initialisation for CommLost/BusOff.
// Error-passive/warning error frames are counted and flagged, not faults.
#include <linux/can.h>

#include <array>
#include <cstdint>

#include "common/cia402_protocol.hpp"
#include "firmware/backends/can_port.hpp"
#include "firmware/device/galvo.hpp"

namespace fs::fw {

struct Cia402Config {
  std::uint8_t node = 1;
  std::uint16_t heartbeat_ms = 100;     // drive's producer time (written to 1017h)
  std::uint16_t tpdo_event_ms = 10;     // TPDO1 event timer (written to 1800h:05)
  std::uint32_t velocity = 20000;       // steps/s
  std::uint32_t acceleration = 400000;  // steps/s^2 (deceleration too)
  Nanos sdo_timeout = 50'000'000;       // per attempt
  int sdo_retries = 2;
  Nanos state_timeout = 500'000'000;  // enable / fault reset / homing steps
  std::int32_t position_window = 1;   // |actual - target| for in_position
};

struct Cia402Diagnostics {
  std::uint16_t statusword = 0;
  cia402::DriveState drive_state = cia402::DriveState::NotReadyToSwitchOn;
  std::uint8_t nmt_state = 0xFF;  // last heartbeat state (0xFF: none yet)
  std::uint16_t emcy_code = 0;    // last EMCY error code
  std::uint32_t sdo_abort = 0;    // last SDO abort code
  bool error_passive = false;
  bool bus_off = false;
  std::uint64_t error_frames = 0;
  std::uint64_t frames_rx = 0, frames_tx = 0;
  Nanos last_heartbeat = 0;     // loop time of the last heartbeat
  Nanos last_rx_kernel_ts = 0;  // kernel receive timestamp (CLOCK_MONOTONIC) of the last frame, 0 if none
  Nanos fault_time = 0;         // loop time the current fault was detected
  std::uint32_t setpoints_acknowledged = 0;
};

class Cia402Master {
 public:
  Cia402Master(CanPort& port, const Cia402Config& cfg);
  void enable(Nanos now);
  void start_homing(Nanos now);
  void move_to(std::int32_t step, Nanos now);
  GalvoStatus poll(Nanos now);
  void reset_fault(Nanos now);
  void disable() noexcept;  // controlword "disable voltage" (drive safe state), best effort
  const Cia402Diagnostics& diagnostics() const { return diag_; }
  const Cia402Config& config() const { return cfg_; }

 private:
  enum class Phase : std::uint8_t {
    Idle,
    Configuring,
    Enabling,
    Ready,
    HomingConfig,
    Homing,
    HomingRestore,
    FaultReset,
    Faulted,
    Disabled
  };
  enum class SetPoint : std::uint8_t { Idle, WaitAck, WaitAckClear };
  struct SdoOp {
    std::uint16_t index = 0;
    std::uint8_t sub = 0, size = 0;
    bool read = false;
    std::uint32_t value = 0;
  };

  void handle(const can_frame& f, Nanos now);
  void handle_error_frame(const can_frame& f, Nanos now);
  void handle_sdo(const can_frame& f, Nanos now);
  void step(Nanos now);
  void start_configuration(Nanos now);
  void queue_sdo(const SdoOp& op);
  void send_sdo(Nanos now);
  void send_rpdo();
  void set_cw(std::uint16_t cw);
  void fault(GalvoFault f, Nanos now);
  void issue_setpoint(std::int32_t target, Nanos now);
  bool heartbeat_armed() const;

  CanPort& port_;
  Cia402Config cfg_;
  Cia402Diagnostics diag_;
  Phase phase_ = Phase::Idle;
  GalvoFault fault_ = GalvoFault::None;
  bool recover_after_restart_ = false;

  std::array<SdoOp, 16> sdo_{};
  std::size_t sdo_head_ = 0, sdo_tail_ = 0;
  bool sdo_in_flight_ = false;
  int sdo_attempts_ = 0;
  Nanos sdo_sent_ = 0;

  std::uint16_t cw_ = 0;
  std::int32_t target_ = 0;
  std::int32_t commanded_ = 0;
  bool pending_move_ = false;
  std::int32_t pending_target_ = 0;
  SetPoint sp_ = SetPoint::Idle;
  bool statusword_seen_ = false;
  std::int32_t position_ = 0;
  bool homed_ = false;
  bool heartbeat_expected_ = false;
  Nanos phase_start_ = 0;
  Nanos cw_sent_ = 0;
};

}  // namespace fs::fw
