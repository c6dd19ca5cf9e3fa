#pragma once
// An fd-level fake V4L2 capture driver behind fw::V4l2Io: QUERYCAP, S_FMT, G/S_PARM, QUERYCTRL/S_CTRL,
// REQBUFS/QUERYBUF/QBUF/DQBUF, STREAMON/OFF and mmap, with the driver's queue discipline (only queued buffers
// get filled; DQBUF says EAGAIN when nothing is done), plus injectable EINTR, error buffers, sequence gaps
// and timestamp flags. Time passes in poll_in() on a ManualClock.
#include <linux/videodev2.h>

#include <sys/mman.h>
#include <cerrno>
#include <cstring>
#include <deque>
#include <functional>
#include <set>
#include <vector>

#include "firmware/backends/v4l2_device.hpp"
#include "test_clock.hpp"

namespace fs::test {

class FakeV4l2 final : public fw::V4l2Io {
 public:
  explicit FakeV4l2(ManualClock& clock) : clock_(clock) {}

  // --- configuration ---
  std::uint32_t device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  std::set<std::uint32_t> formats = {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_Y16, V4L2_PIX_FMT_YUYV};
  std::uint32_t fallback_format = V4L2_PIX_FMT_YUYV;
  std::uint32_t max_width = 1280, max_height = 1024;
  std::uint32_t stride_pad = 0;     // extra bytes per line
  std::uint32_t grant_buffers = 0;  // 0: as many as requested
  bool timeperframe = true;
  bool exposure_ctrl = true;
  std::int32_t exposure_min = 1, exposure_max = 5000;
  std::uint32_t timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
  int eintr_dqbuf = 0, eintr_poll = 0;  // that many calls fail with EINTR first

  // --- observed ---
  std::int32_t exposure = -1;
  bool manual_exposure = false;
  std::uint32_t fps_num = 0, fps_den = 0;
  bool streaming = false;
  int open_fds = 0, mapped = 0;

  // Fills the next queued buffer (fill(data, stride)) and makes it ready for DQBUF. False if none is queued.
  bool produce(std::uint32_t sequence, fw::Nanos ts,
               const std::function<void(std::uint8_t*, std::uint32_t)>& fill, std::uint32_t extra_flags = 0,
               std::uint32_t bytesused = 0) {
    if (!streaming || queued_.empty()) return false;
    const int i = queued_.front();
    queued_.pop_front();
    fill(bufs_[i].data(), stride_);
    Done d{};
    d.index = i;
    d.sequence = sequence;
    d.ts = ts;
    d.flags = extra_flags;
    d.bytesused = bytesused ? bytesused : stride_ * fmt_.height;
    done_.push_back(d);
    return true;
  }
  std::size_t queued() const { return queued_.size(); }
  const std::uint8_t* buffer(int i) const { return bufs_[i].data(); }

  int open(const char* path, int) override {
    if (std::strcmp(path, "/dev/fake0") != 0) {
      errno = ENOENT;
      return -1;
    }
    ++open_fds;
    return 42;
  }
  int close(int) override {
    --open_fds;
    return 0;
  }
  void* mmap(std::size_t length, int, off_t offset) override {
    const std::size_t i = static_cast<std::size_t>(offset) / kPage;
    if (i >= bufs_.size() || length > bufs_[i].size()) {
      errno = EINVAL;
      return MAP_FAILED;
    }
    ++mapped;
    return bufs_[i].data();
  }
  int munmap(void*, std::size_t) override {
    --mapped;
    return 0;
  }
  int poll_in(int, int timeout_ms) override {
    if (eintr_poll > 0) {
      --eintr_poll;
      errno = EINTR;
      return -1;
    }
    if (!done_.empty()) return 1;
    clock_.advance(fw::Nanos(timeout_ms) * kMs);
    return 0;
  }

  int ioctl(int, unsigned long req, void* arg) override {
    switch (req) {
      case VIDIOC_QUERYCAP: {
        auto* c = static_cast<v4l2_capability*>(arg);
        std::memset(c, 0, sizeof *c);
        std::strcpy(reinterpret_cast<char*>(c->driver), "fakecam");
        c->capabilities = device_caps | V4L2_CAP_DEVICE_CAPS;
        c->device_caps = device_caps;
        return 0;
      }
      case VIDIOC_S_FMT: {
        auto* f = static_cast<v4l2_format*>(arg);
        if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || streaming || !bufs_.empty()) return fail(EBUSY);
        auto& p = f->fmt.pix;
        if (!formats.count(p.pixelformat)) p.pixelformat = fallback_format;
        p.width = std::min(p.width, max_width);
        p.height = std::min(p.height, max_height);
        const std::uint32_t bpp = p.pixelformat == V4L2_PIX_FMT_GREY ? 1 : 2;
        p.bytesperline = p.width * bpp + stride_pad;
        p.sizeimage = p.bytesperline * p.height;
        fmt_ = p;
        stride_ = p.bytesperline;
        return 0;
      }
      case VIDIOC_G_PARM:
      case VIDIOC_S_PARM: {
        auto* s = static_cast<v4l2_streamparm*>(arg);
        if (req == VIDIOC_S_PARM) {
          if (!timeperframe) return fail(ENOTTY);
          fps_num = s->parm.capture.timeperframe.numerator;
          fps_den = s->parm.capture.timeperframe.denominator;
        }
        std::memset(&s->parm, 0, sizeof s->parm);
        s->parm.capture.capability = timeperframe ? V4L2_CAP_TIMEPERFRAME : 0;
        s->parm.capture.timeperframe = {fps_num ? fps_num : 1, fps_den ? fps_den : 30};
        return 0;
      }
      case VIDIOC_QUERYCTRL: {
        auto* q = static_cast<v4l2_queryctrl*>(arg);
        if (!exposure_ctrl) return fail(EINVAL);
        if (q->id == V4L2_CID_EXPOSURE_AUTO) {
          q->minimum = 0;
          q->maximum = 3;
          q->flags = 0;
          return 0;
        }
        if (q->id == V4L2_CID_EXPOSURE_ABSOLUTE) {
          q->minimum = exposure_min;
          q->maximum = exposure_max;
          q->flags = 0;
          return 0;
        }
        return fail(EINVAL);
      }
      case VIDIOC_S_CTRL: {
        auto* c = static_cast<v4l2_control*>(arg);
        if (c->id == V4L2_CID_EXPOSURE_AUTO)
          manual_exposure = c->value == V4L2_EXPOSURE_MANUAL;
        else if (c->id == V4L2_CID_EXPOSURE_ABSOLUTE && manual_exposure)
          exposure = c->value;
        else
          return fail(EINVAL);
        return 0;
      }
      case VIDIOC_REQBUFS: {
        auto* r = static_cast<v4l2_requestbuffers*>(arg);
        if (r->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
        if (streaming) return fail(EBUSY);
        const std::uint32_t n = r->count == 0 ? 0 : (grant_buffers ? grant_buffers : r->count);
        bufs_.assign(n, std::vector<std::uint8_t>(fmt_.sizeimage + kPage));
        r->count = n;
        queued_.clear();
        done_.clear();
        return 0;
      }
      case VIDIOC_QUERYBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= bufs_.size()) return fail(EINVAL);
        b->length = fmt_.sizeimage;
        b->m.offset = b->index * kPage;
        return 0;
      }
      case VIDIOC_QBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= bufs_.size()) return fail(EINVAL);
        for (int q : queued_)
          if (q == static_cast<int>(b->index)) return fail(EINVAL);  // already queued
        queued_.push_back(static_cast<int>(b->index));
        return 0;
      }
      case VIDIOC_DQBUF: {
        if (eintr_dqbuf > 0) {
          --eintr_dqbuf;
          return fail(EINTR);
        }
        if (!streaming) return fail(EINVAL);
        if (done_.empty()) return fail(EAGAIN);
        auto* b = static_cast<v4l2_buffer*>(arg);
        const Done d = done_.front();
        done_.pop_front();
        b->index = static_cast<std::uint32_t>(d.index);
        b->sequence = d.sequence;
        b->bytesused = d.bytesused;
        b->flags = timestamp_flags | d.flags;
        b->timestamp.tv_sec = d.ts / 1'000'000'000;
        b->timestamp.tv_usec = (d.ts % 1'000'000'000) / 1000;
        return 0;
      }
      case VIDIOC_STREAMON:
        if (bufs_.empty()) return fail(EINVAL);
        streaming = true;
        return 0;
      case VIDIOC_STREAMOFF:
        streaming = false;
        queued_.clear();
        done_.clear();
        return 0;
      default:
        return fail(ENOTTY);
    }
  }

 private:
  static constexpr std::size_t kPage = 1u << 22;  // mmap offsets: buffer index * 4 MiB
  struct Done {
    int index;
    std::uint32_t sequence;
    fw::Nanos ts;
    std::uint32_t flags, bytesused;
  };
  static int fail(int e) {
    errno = e;
    return -1;
  }
  ManualClock& clock_;
  v4l2_pix_format fmt_{};
  std::uint32_t stride_ = 0;
  std::vector<std::vector<std::uint8_t>> bufs_;
  std::deque<int> queued_;
  std::deque<Done> done_;
};

}  // namespace fs::test
