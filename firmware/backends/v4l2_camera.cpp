#include "firmware/backends/v4l2_camera.hpp"

#include <fcntl.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>

#include "common/error.hpp"
#include "firmware/backends/gpiod_lines.hpp"  // monotonic_now()

namespace fs::fw {
namespace {

std::string fourcc_text(std::uint32_t f) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) s[i] = static_cast<char>((f >> (8 * i)) & 0xFF);
  return s;
}

}  // namespace

V4l2Camera::V4l2Camera(const V4l2Spec& spec, V4l2Io& io, Clock* clock) : spec_(spec), io_(io), clock_(clock) {
  if (spec_.buffers < 4 || spec_.buffers > kMaxBuffers)
    throw Error("V4L2 device '" + spec_.device + "': buffers=" + std::to_string(spec_.buffers) +
                " out of range (4.." + std::to_string(kMaxBuffers) + ")");
  fd_ = io_.open(spec_.device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) fail("cannot open");
  try {
    configure();
  } catch (...) {
    for (std::uint32_t i = 0; i < nbuf_; ++i)
      if (bufs_[i].addr) io_.munmap(bufs_[i].addr, bufs_[i].length);
    if (nbuf_) {
      v4l2_requestbuffers rb{};
      rb.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      rb.memory = V4L2_MEMORY_MMAP;
      io_.ioctl(fd_, VIDIOC_REQBUFS, &rb);
    }
    io_.close(fd_);
    throw;
  }
}

V4l2Camera::~V4l2Camera() {
  stop();
  for (std::uint32_t i = 0; i < nbuf_; ++i)
    if (bufs_[i].addr) io_.munmap(bufs_[i].addr, bufs_[i].length);
  v4l2_requestbuffers rb{};
  rb.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  rb.memory = V4L2_MEMORY_MMAP;
  io_.ioctl(fd_, VIDIOC_REQBUFS, &rb);  // count 0 frees the driver's buffers
  io_.close(fd_);
}

void V4l2Camera::fail(const std::string& what) const {
  throw Error("V4L2 device '" + spec_.device + "': " + what + ": " + std::strerror(errno));
}

int V4l2Camera::xioctl(unsigned long req, void* arg) {
  int r;
  while ((r = io_.ioctl(fd_, req, arg)) < 0 && errno == EINTR) ++stats_.eintr;
  return r;
}

Nanos V4l2Camera::now() const { return clock_ ? clock_->now() : monotonic_now(); }

bool V4l2Camera::owns_pointer(const void* p) const {
  auto* c = static_cast<const std::uint8_t*>(p);
  for (std::uint32_t i = 0; i < nbuf_; ++i) {
    auto* b = static_cast<const std::uint8_t*>(bufs_[i].addr);
    if (c >= b && c < b + bufs_[i].length) return true;
  }
  return false;
}

void V4l2Camera::configure() {
  v4l2_capability cap{};
  if (xioctl(VIDIOC_QUERYCAP, &cap) < 0) fail("VIDIOC_QUERYCAP failed (not a V4L2 device?)");
  driver_ = reinterpret_cast<const char*>(cap.driver);
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
    errno = ENODEV;
    fail("not a single-planar video capture device (driver " + driver_ + ")");
  }
  if (!(caps & V4L2_CAP_STREAMING)) {
    errno = ENOTSUP;
    fail("driver " + driver_ + " has no streaming I/O");
  }

  switch (spec_.format) {
    case V4l2Fourcc::Grey:
      fourcc_ = V4L2_PIX_FMT_GREY;
      format_ = PixelFormat::Mono8;
      break;
    case V4l2Fourcc::Y16:
      fourcc_ = V4L2_PIX_FMT_Y16;
      format_ = PixelFormat::Mono16;
      break;
    case V4l2Fourcc::Yuyv:
      fourcc_ = V4L2_PIX_FMT_YUYV;
      format_ = PixelFormat::Yuyv;
      break;
  }
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = spec_.width;
  fmt.fmt.pix.height = spec_.height;
  fmt.fmt.pix.pixelformat = fourcc_;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(VIDIOC_S_FMT, &fmt) < 0) fail("VIDIOC_S_FMT " + fourcc_text(fourcc_) + " failed");
  if (fmt.fmt.pix.pixelformat != fourcc_) {
    errno = EINVAL;
    fail("format " + fourcc_text(fourcc_) + " not supported (driver chose " +
         fourcc_text(fmt.fmt.pix.pixelformat) + ")");
  }
  width_ = fmt.fmt.pix.width;
  height_ = fmt.fmt.pix.height;
  const std::uint32_t bpp = format_ == PixelFormat::Mono8 ? 1 : 2;
  stride_ = fmt.fmt.pix.bytesperline ? fmt.fmt.pix.bytesperline : width_ * bpp;
  sizeimage_ = fmt.fmt.pix.sizeimage;
  if (width_ == 0 || height_ == 0 || stride_ < width_ * bpp ||
      (sizeimage_ && sizeimage_ < stride_ * height_)) {
    errno = EINVAL;
    fail("driver returned an inconsistent format " + std::to_string(width_) + "x" + std::to_string(height_) +
         " bytesperline " + std::to_string(stride_) + " sizeimage " + std::to_string(sizeimage_));
  }
  if (spec_.fps) set_frame_rate();
  if (spec_.exposure >= 0) set_exposure();

  v4l2_requestbuffers rb{};
  rb.count = spec_.buffers;
  rb.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  rb.memory = V4L2_MEMORY_MMAP;
  if (xioctl(VIDIOC_REQBUFS, &rb) < 0) fail("VIDIOC_REQBUFS (MMAP) failed");
  if (rb.count < 4 || rb.count > kMaxBuffers) {
    nbuf_ = 0;
    errno = ENOBUFS;
    fail("driver granted " + std::to_string(rb.count) + " MMAP buffers, need 4.." +
         std::to_string(kMaxBuffers));
  }
  nbuf_ = rb.count;
  for (std::uint32_t i = 0; i < nbuf_; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (xioctl(VIDIOC_QUERYBUF, &b) < 0) fail("VIDIOC_QUERYBUF " + std::to_string(i) + " failed");
    if (b.length < stride_ * height_) {
      errno = EINVAL;
      fail("buffer " + std::to_string(i) + " is " + std::to_string(b.length) + " bytes, a frame needs " +
           std::to_string(stride_ * height_));
    }
    void* p = io_.mmap(b.length, fd_, static_cast<off_t>(b.m.offset));
    if (p == MAP_FAILED) fail("mmap of buffer " + std::to_string(i) + " failed");
    bufs_[i] = {p, b.length, false, false};
  }
}

void V4l2Camera::set_frame_rate() {
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(VIDIOC_G_PARM, &parm) < 0 || !(parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
    notes_ += "frame rate not settable; ";
    return;
  }
  parm.parm.capture.timeperframe.numerator = 1;
  parm.parm.capture.timeperframe.denominator = spec_.fps;
  if (xioctl(VIDIOC_S_PARM, &parm) < 0) fail("VIDIOC_S_PARM " + std::to_string(spec_.fps) + " fps failed");
  const auto& t = parm.parm.capture.timeperframe;
  if (t.numerator == 0 || t.denominator / t.numerator != spec_.fps)
    notes_ += "driver set " + std::to_string(t.denominator) + "/" + std::to_string(t.numerator) + " fps; ";
}

void V4l2Camera::set_exposure() {
  v4l2_queryctrl q{};
  q.id = V4L2_CID_EXPOSURE_AUTO;
  if (xioctl(VIDIOC_QUERYCTRL, &q) == 0 && !(q.flags & V4L2_CTRL_FLAG_DISABLED)) {
    v4l2_control c{V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL};
    if (xioctl(VIDIOC_S_CTRL, &c) < 0) fail("cannot switch exposure to manual (V4L2_CID_EXPOSURE_AUTO)");
  }
  q = {};
  q.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  if (xioctl(VIDIOC_QUERYCTRL, &q) < 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED)) {
    notes_ += "no exposure control; ";
    return;
  }
  if (spec_.exposure < q.minimum || spec_.exposure > q.maximum) {
    errno = ERANGE;
    fail("exposure=" + std::to_string(spec_.exposure) + " outside the driver's range " +
         std::to_string(q.minimum) + ".." + std::to_string(q.maximum));
  }
  v4l2_control c{V4L2_CID_EXPOSURE_ABSOLUTE, spec_.exposure};
  if (xioctl(VIDIOC_S_CTRL, &c) < 0) fail("VIDIOC_S_CTRL exposure failed");
}

void V4l2Camera::queue(std::uint32_t index) {
  v4l2_buffer b{};
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  b.index = index;
  if (xioctl(VIDIOC_QBUF, &b) < 0) fail("VIDIOC_QBUF " + std::to_string(index) + " failed");
  bufs_[index].queued = true;
  bufs_[index].out = false;
}

void V4l2Camera::start(Nanos) {
  if (streaming_) return;
  for (std::uint32_t i = 0; i < nbuf_; ++i)
    if (!bufs_[i].queued && !bufs_[i].out) queue(i);
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(VIDIOC_STREAMON, &type) < 0) fail("VIDIOC_STREAMON failed");
  streaming_ = true;
  have_seq_ = false;
}

void V4l2Camera::stop() noexcept {
  if (!streaming_) return;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  io_.ioctl(fd_, VIDIOC_STREAMOFF, &type);  // dequeues every buffer
  for (std::uint32_t i = 0; i < nbuf_; ++i) bufs_[i].queued = bufs_[i].out = false;
  streaming_ = false;
}

GrabResult V4l2Camera::grab(Nanos deadline, FrameView& out) {
  if (!streaming_) return GrabResult::Error;
  for (;;) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (io_.ioctl(fd_, VIDIOC_DQBUF, &b) == 0) {
      if (b.index >= nbuf_) return GrabResult::Error;
      Buffer& buf = bufs_[b.index];
      buf.queued = false;
      if (have_seq_) {
        const auto gap = static_cast<std::int32_t>(b.sequence - last_seq_);  // wrap-safe
        if (gap > 1)
          stats_.dropped += static_cast<std::uint32_t>(gap - 1);
        else if (gap <= 0)
          ++stats_.sequence_restarts;  // driver restarted or repeated its count: no drop
      }
      have_seq_ = true;
      last_seq_ = b.sequence;
      const std::uint32_t need = stride_ * height_;
      if ((b.flags & V4L2_BUF_FLAG_ERROR) || (b.bytesused != 0 && b.bytesused < need)) {
        ++stats_.error_buffers;
        ++stats_.dropped;
        queue(b.index);
        continue;
      }
      Nanos ts;
      if ((b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
        ts = Nanos(b.timestamp.tv_sec) * 1'000'000'000 + Nanos(b.timestamp.tv_usec) * 1000;
      } else {
        ++stats_.non_monotonic;
        ts = now();  // unknown / copied timestamps are not on the loop's clock: use the dequeue time
      }
      buf.out = true;
      ++stats_.frames;
      out.data = static_cast<const std::uint8_t*>(buf.addr);
      out.width = width_;
      out.height = height_;
      out.stride = stride_;
      out.format = format_;
      out.sequence = b.sequence;
      out.timestamp = ts;
      out.buffer = static_cast<std::int32_t>(b.index);
      return GrabResult::Ok;
    }
    if (errno == EINTR) {
      ++stats_.eintr;
      continue;
    }
    if (errno != EAGAIN) return GrabResult::Error;
    ++stats_.eagain;
    const Nanos left = deadline - now();
    if (left <= 0) return GrabResult::Timeout;
    const int ms = static_cast<int>((left + 999'999) / 1'000'000);
    const int r = io_.poll_in(fd_, ms);
    if (r < 0 && errno == EINTR) {
      ++stats_.eintr;
      continue;
    }
    if (r < 0) return GrabResult::Error;
    if (r == 0 && deadline - now() <= 0) return GrabResult::Timeout;
  }
}

void V4l2Camera::release(const FrameView& frame) {
  if (frame.buffer < 0 || static_cast<std::uint32_t>(frame.buffer) >= nbuf_ || !bufs_[frame.buffer].out)
    throw Error("V4L2 device '" + spec_.device + "': release of buffer " + std::to_string(frame.buffer) +
                " that is not handed out");
  if (!streaming_) {
    bufs_[frame.buffer].out = false;
    return;
  }
  queue(static_cast<std::uint32_t>(frame.buffer));
}

}  // namespace fs::fw
