#include "common/alloc_counter/alloc_counter.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/scan_file.hpp"
#include "common/wire.hpp"
#include "tmp_dir.hpp"
#include "wire_samples.hpp"

namespace {

// Keeps the optimizer from eliding allocations.
template <class T>
void escape(T* p) {
  asm volatile("" : : "g"(p) : "memory");
}

TEST(AllocCounter, CountsOperatorNew) {
  fs::AllocCounter c;
  auto* p = new int(5);
  escape(p);
  EXPECT_EQ(c.allocations(), 1u);
  EXPECT_EQ(c.new_calls(), 1u);
  EXPECT_GE(c.bytes(), sizeof(int));
  delete p;
  EXPECT_EQ(c.deallocations(), 1u);
  auto* a = new double[100];
  escape(a);
  delete[] a;
  EXPECT_EQ(c.allocations(), 2u);
  EXPECT_EQ(c.new_calls(), 2u);
  EXPECT_GE(c.bytes(), sizeof(int) + 100 * sizeof(double));
}

TEST(AllocCounter, CountsContainersAndAlignedNew) {
  fs::AllocCounter c;
  {
    std::vector<int> v;
    for (int i = 0; i < 100; ++i) v.push_back(i);  // several reallocations
    escape(v.data());
    std::string s(1000, 'x');
    escape(s.data());
    struct alignas(64) Wide {
      char b[64];
    };
    auto w = std::make_unique<Wide>();
    escape(w.get());
  }
  EXPECT_GE(c.allocations(), 4u);
  EXPECT_EQ(c.allocations(), c.deallocations());
}

TEST(AllocCounter, CountsMallocFamily) {
  ASSERT_TRUE(fs::AllocCounter::counts_malloc()) << "malloc counting must work in this build (ASan or glibc)";
  fs::AllocCounter c;
  void* p = std::malloc(100);
  escape(p);
  void* q = std::calloc(10, 10);
  escape(q);
  p = std::realloc(p, 100000);  // moves
  escape(p);
  std::free(p);
  std::free(q);
  EXPECT_GE(c.allocations(), 3u);
  EXPECT_EQ(c.new_calls(), 0u);
  EXPECT_GE(c.deallocations(), 2u);
}

TEST(AllocCounter, ZeroWhenNothingAllocates) {
  std::vector<int> v(1000);
  fs::AllocCounter c;
  for (int i = 0; i < 1000; ++i) v[static_cast<std::size_t>(i)] = i * i;
  escape(v.data());
  EXPECT_EQ(c.allocations(), 0u);
  EXPECT_EQ(c.bytes(), 0u);
}

TEST(AllocCounter, PerThreadAndProcessWide) {
  fs::AllocCounter c;
  std::thread t([] {
    for (int i = 0; i < 10; ++i) {
      auto* p = new int(i);
      escape(p);
      delete p;
    }
  });
  t.join();  // std::thread itself allocates its state on this thread
  const auto mine = c.allocations();
  EXPECT_LE(mine, 3u);
  EXPECT_GE(c.process_allocations(), mine + 10);
  c.restart();
  EXPECT_EQ(c.allocations(), 0u);
}

// The wire hot paths: after warm-up, encoding and decoding frames allocate nothing.
TEST(AllocCounter, WireEncodeDecodeAllocateNothingPerFrame) {
  std::vector<std::uint8_t> stream(1 << 20);
  auto pts = fs::test::sample_points(1000);
  const auto begin = fs::test::sample_scan_begin();
  const auto fault = fs::test::sample_fault();
  fs::wire::FrameDecoder dec("alloc");
  fs::wire::DecodedMessage out;
  fs::wire::FrameView f;

  fs::AllocCounter c;
  std::size_t n = 0;
  n += fs::wire::encode(std::span(stream).subspan(n), 0, begin);
  for (std::uint32_t k = 0; k < 50; ++k)
    n += fs::wire::encode(std::span(stream).subspan(n), k + 1,
                          fs::msg::Stripe{fs::test::sample_stripe_header(k), pts});
  n += fs::wire::encode(std::span(stream).subspan(n), 51, fault);
  n += fs::wire::encode(std::span(stream).subspan(n), 52, fs::test::sample_scan_end());
  std::span<const std::uint8_t> in(stream.data(), n);
  std::size_t frames = 0;
  while (!in.empty()) {
    in = in.subspan(dec.feed(in.first(std::min<std::size_t>(in.size(), 4093))));
    while (dec.next(f)) {
      fs::wire::decode(f, out);
      ++frames;
    }
  }
  dec.finish();
  EXPECT_EQ(frames, 53u);
  EXPECT_EQ(out.fault.text, fault.text);
  EXPECT_EQ(c.allocations(), 0u);
}

// Replaying a .fscan file: after the reader is constructed, reading every message allocates nothing.
TEST(AllocCounter, ScanFileReplayAllocatesNothingAfterOpen) {
  const auto dir = fs::test::make_tmp_dir("alloc");
  const auto path = dir / "r.fscan";
  {
    fs::ScanFileWriter w(path);
    fs::wire::FrameWriter fw(w);
    auto pts = fs::test::sample_points(1000);
    fw.send(fs::test::sample_scan_begin());
    for (std::uint32_t k = 0; k < 100; ++k) fw.send(fs::msg::Stripe{fs::test::sample_stripe_header(k), pts});
    fw.send(fs::test::sample_scan_end());
  }
  fs::wire::DecodedMessage m;
  fs::ScanFileReader r(path);
  fs::AllocCounter c;
  std::size_t n = 0;
  while (r.next(m)) ++n;
  EXPECT_EQ(n, 102u);
  EXPECT_EQ(c.allocations(), 0u);
  std::filesystem::remove_all(dir);
}

}  // namespace
