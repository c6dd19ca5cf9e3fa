#pragma once
// Simulated CiA 402 servo drive (the galvo's CAN drive) speaking struct can_frame on a file descriptor: one
// end of an AF_UNIX/SOCK_SEQPACKET socketpair, or a raw CAN socket bound to vcan0. Single-threaded: poll()
// reads every pending frame, advances the motion to clock.now() and sends heartbeats / TPDOs / answers.
//
// Implements: NMT (start/stop/pre-op/reset, boot-up message), expedited SDO read/write of 1017h, 1800h:05,
// 603Fh, 6040h, 6041h, 6060h, 6061h, 6064h, 607Ah, 607Ch, 6081h, 6083h, 6084h, 6098h (aborts for unknown
// objects, wrong sizes, read-only objects, unsupported values), the controlword/statusword state machine,
// profile position mode (new set-point / acknowledge handshake, change immediately, relative, halt,
// trapezoidal motion, target reached), homing mode method 37, heartbeat producer, TPDO1 (statusword +
// position) on change and on the event timer. PDO mapping: see common/cia402_protocol.hpp. Faults:
// no response, heartbeat loss, drive fault (EMCY + fault state), error-passive frames, bus-off with restart;
// scriptable by time (schedule()).
#include <cstdint>
#include <functional>
#include <vector>

#include "common/cia402_protocol.hpp"
#include "firmware/device/clock.hpp"

namespace fs::sim {

struct Cia402TwinConfig {
  std::uint8_t node = 1;
  double start_position = 0.0;         // steps
  double max_velocity = 1e6;           // hardware limit on 6081h, steps/s
  fw::Nanos motion_step = 50'000;      // integration sub-step of the trapezoidal profile
  fw::Nanos homing_time = 20'000'000;  // homing method 37 completes after this
  double following_limit = 0.0;  // > 0: following error bit when a stall leaves the position this far behind
};

struct Cia402TwinStats {
  std::uint64_t frames_rx = 0, frames_tx = 0, sdo_requests = 0, sdo_aborts = 0, rpdos = 0, setpoints = 0,
                heartbeats = 0, tpdos = 0, bad_frames = 0;
};

class Cia402Twin {
 public:
  using PositionCallback = std::function<void(double position_steps, std::int64_t t_ns)>;

  // fd: non-blocking is set here; not owned (the caller closes it).
  Cia402Twin(int fd, fw::Clock& clock, const Cia402TwinConfig& cfg = {});

  void poll();
  // Called with the motor position at every motion sub-step while it moves (at the sub-step's own time, so a
  // mirror fed from it follows the trajectory even when polls are far apart) and at the end of every poll().
  void set_position_callback(PositionCallback cb) { on_position_ = std::move(cb); }

  // --- fault injection ---
  void set_no_response(bool on) { no_response_ = on; }        // ignores every frame, sends nothing
  void set_heartbeat_loss(bool on) { heartbeat_loss_ = on; }  // keeps working, stops heartbeats
  void inject_drive_fault(std::uint16_t error_code);          // fault state + EMCY (e.g. 0x2310 overcurrent)
  void set_stall(bool on) { stalled_ = on; }                  // motor does not follow (following error)
  void inject_error_passive(bool on);                         // CAN_ERR_CRTL error frame (passive / active)
  void inject_bus_off(fw::Nanos duration);  // bus-off frame, silence, then CAN_ERR_RESTARTED
  void schedule(fw::Nanos at, std::function<void(Cia402Twin&)> action);  // runs in poll() once now >= at

  // --- state ---
  double position() const { return pos_; }
  double velocity() const { return vel_; }
  std::int32_t target() const { return target_; }
  std::uint16_t statusword() const;
  cia402::DriveState state() const { return state_; }
  std::uint8_t nmt_state() const { return nmt_; }
  std::int8_t mode() const { return mode_display_; }
  std::uint32_t profile_velocity() const { return prof_vel_; }
  std::uint32_t profile_acceleration() const { return prof_acc_; }
  std::uint16_t heartbeat_ms() const { return hb_ms_; }
  fw::Nanos last_heartbeat_sent() const { return last_hb_; }
  const Cia402TwinStats& stats() const { return stats_; }

 private:
  void handle(const can_frame& f, fw::Nanos now);
  void handle_sdo(const can_frame& f, fw::Nanos now);
  void handle_controlword(std::uint16_t cw, fw::Nanos now);
  bool sdo_write(std::uint16_t index, std::uint8_t sub, std::uint32_t v, int size, std::uint32_t& abort,
                 fw::Nanos now);
  bool sdo_read(std::uint16_t index, std::uint8_t sub, std::uint32_t& v, int& size,
                std::uint32_t& abort) const;
  void advance(fw::Nanos now);
  void send(const can_frame& f);
  void send_tpdo();
  void send_error(std::uint32_t err_id, std::uint8_t d1);
  void reset_communication(fw::Nanos now);

  int fd_;
  fw::Clock& clock_;
  Cia402TwinConfig cfg_;
  PositionCallback on_position_;
  Cia402TwinStats stats_;

  std::uint8_t nmt_ = cia402::kStatePreOperational;
  cia402::DriveState state_ = cia402::DriveState::SwitchOnDisabled;
  std::uint16_t cw_ = 0;
  std::uint16_t error_code_ = 0;
  std::int8_t mode_ = 0, mode_display_ = 0;
  std::int8_t homing_method_ = cia402::kHomingOnCurrentPosition;
  std::int32_t target_ = 0, target_obj_ = 0, home_offset_ = 0;
  std::uint32_t prof_vel_ = 10000, prof_acc_ = 100000, prof_dec_ = 100000;
  std::uint16_t hb_ms_ = 0, tpdo_ms_ = 0;
  bool ack_ = false, reached_ = true, following_error_ = false, halted_ = false;
  bool homing_ = false, homing_attained_ = false;
  fw::Nanos homing_done_ = 0;
  double pos_ = 0.0, vel_ = 0.0;
  fw::Nanos t_ = 0, last_hb_ = 0, last_tpdo_ = 0;
  std::uint16_t last_sw_sent_ = 0xFFFF;

  bool no_response_ = false, heartbeat_loss_ = false, stalled_ = false;
  bool bus_off_ = false;
  fw::Nanos bus_off_until_ = 0;
  struct Scheduled {
    fw::Nanos at;
    std::function<void(Cia402Twin&)> action;
    bool done;
  };
  std::vector<Scheduled> schedule_;
};

}  // namespace fs::sim
