#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory_resource>
#include <string>
#include <thread>
#include <vector>

#include "common/alloc_counter/alloc_counter.hpp"
#include "common/arena.hpp"
#include "common/fixed_vector.hpp"
#include "common/spsc_ring.hpp"

namespace {

using ::testing::HasSubstr;

// ---- Arena
// ----------------------------------------------------------------------------------------------------

TEST(Arena, ServesPmrContainersWithoutHeap) {
  fs::Arena arena(64 * 1024, "test");
  fs::AllocCounter c;
  {
    std::pmr::vector<int> v(&arena);
    v.reserve(1000);
    for (int i = 0; i < 1000; ++i) v.push_back(i);
    std::pmr::string s("a string long enough to need the heap, but it gets the arena", &arena);
    EXPECT_EQ(v[999], 999);
  }
  EXPECT_EQ(c.allocations(), 0u);
  EXPECT_GE(arena.used(), 4000u);
  EXPECT_LE(arena.used(), arena.capacity());
}

TEST(Arena, ExhaustionThrowsAndNeverFallsBackToHeap) {
  fs::Arena arena(1024, "tiny");
  fs::AllocCounter c;
  auto a = arena.allocate_array<double>(100);  // 800 bytes
  EXPECT_EQ(a.size(), 100u);
  EXPECT_EQ(a[50], 0.0);
  try {
    arena.allocate_array<double>(100);
    FAIL() << "no exception";
  } catch (const fs::ArenaExhausted& e) {
    EXPECT_THAT(e.what(), HasSubstr("arena 'tiny' exhausted: request of 800 bytes"));
    EXPECT_THAT(e.what(), HasSubstr("of 1024 bytes used"));
  }
  std::pmr::vector<char> v(&arena);
  EXPECT_THROW(v.resize(4096), fs::Error);
  EXPECT_THROW(arena.allocate_array<std::uint64_t>(SIZE_MAX / 4), fs::ArenaExhausted);
  // Only the exception objects may touch the heap here; the arena itself never did.
  EXPECT_LE(c.bytes(), 3 * 1024u);
}

TEST(Arena, ResetMakesTheWholeBufferAvailableAgain) {
  fs::Arena arena(4096, "reset");
  for (int round = 0; round < 10; ++round) {
    auto a = arena.allocate_array<std::uint8_t>(3000);
    a[2999] = 1;
    EXPECT_GE(arena.used(), 3000u);
    EXPECT_THROW(arena.allocate_array<std::uint8_t>(2000), fs::ArenaExhausted);
    arena.reset();
    EXPECT_EQ(arena.used(), 0u);
  }
  EXPECT_GE(arena.high_water(), 3000u);
}

TEST(Arena, TryAllocateReportsExhaustionWithoutThrowing) {
  fs::Arena arena(1000, "budget");
  std::size_t got = 0;
  for (;;) {
    auto s = arena.try_allocate_array<std::uint32_t>(30);  // 120 bytes each
    if (s.empty()) break;
    got += s.size();
  }
  EXPECT_EQ(got, 8u * 30u);                                                // 960 of 1000 bytes
  EXPECT_TRUE(arena.try_allocate_array<std::uint32_t>(10).size() == 10u);  // 40 bytes still fit exactly
  EXPECT_TRUE(arena.try_allocate_array<std::uint8_t>(1).empty());
  EXPECT_FALSE(arena.fits(1, 1));
  arena.reset();
  EXPECT_TRUE(arena.fits(1000, 8));
  EXPECT_FALSE(arena.fits(1001, 1));
}

TEST(Arena, OverCallerBufferAndAlignment) {
  alignas(64) std::byte buf[512];
  fs::Arena arena(std::span<std::byte>(buf), "stack");
  struct alignas(32) V {
    double x[4];
  };
  auto* c = arena.make<char>('x');
  auto* v = arena.make<V>();
  EXPECT_EQ(*c, 'x');
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v) % 32, 0u);
  EXPECT_GE(reinterpret_cast<std::byte*>(c), buf);
  EXPECT_LT(reinterpret_cast<std::byte*>(v), buf + 512);
  EXPECT_THROW(arena.allocate_array<V>(100), fs::ArenaExhausted);
}

// ---- FixedVector
// ------------------------------------------------------------------------------------------------

TEST(FixedVector, BasicsAndOverflow) {
  fs::AllocCounter c;
  fs::FixedVector<int, 4> v{1, 2};
  v.push_back(3);
  EXPECT_TRUE(v.try_push_back(4));
  EXPECT_TRUE(v.full());
  EXPECT_FALSE(v.try_push_back(5));
  EXPECT_EQ(v.size(), 4u);
  EXPECT_EQ(c.allocations(), 0u);
  EXPECT_THROW(v.push_back(5), fs::Error);
  EXPECT_THROW(v.at(4), fs::Error);
  EXPECT_THROW(v.resize(5), fs::Error);
  EXPECT_EQ(v.back(), 4);
  v.erase(v.begin() + 1);
  EXPECT_EQ(v, (fs::FixedVector<int, 4>{1, 3, 4}));
  v.insert(v.begin(), 0);
  EXPECT_EQ(v, (fs::FixedVector<int, 4>{0, 1, 3, 4}));
  v.pop_back();
  std::span<const int> s = v;
  EXPECT_EQ(s.size(), 3u);
  v.resize(1);
  EXPECT_EQ(v.size(), 1u);
  v.clear();
  EXPECT_TRUE(v.empty());
}

TEST(FixedVector, NonTrivialElementsAreConstructedAndDestroyed) {
  auto counter = std::make_shared<int>(0);
  {
    fs::FixedVector<std::shared_ptr<int>, 8> v;
    for (int i = 0; i < 5; ++i) v.push_back(counter);
    EXPECT_EQ(counter.use_count(), 6);
    auto w = v;  // copy
    EXPECT_EQ(counter.use_count(), 11);
    auto m = std::move(w);
    EXPECT_TRUE(w.empty());
    EXPECT_EQ(counter.use_count(), 11);
    v.pop_back();
    EXPECT_EQ(counter.use_count(), 10);
    std::string msg;
    try {
      fs::FixedVector<std::string, 2> s{"a", "b"};
      s.emplace_back("c");
    } catch (const fs::Error& e) {
      msg = e.what();
    }
    EXPECT_EQ(msg, "FixedVector capacity 2 exceeded");
  }
  EXPECT_EQ(counter.use_count(), 1);
}

// ---- SpscRing
// ---------------------------------------------------------------------------------------------------

TEST(SpscRing, FifoAndFullEmpty) {
  fs::SpscRing<int> r(3);
  EXPECT_EQ(r.capacity(), 4u);
  int out = 0;
  EXPECT_FALSE(r.try_pop(out));
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(r.try_push(i));
  EXPECT_FALSE(r.try_push(99));
  EXPECT_EQ(r.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(r.try_pop(out));
    EXPECT_EQ(out, i);
  }
  EXPECT_TRUE(r.empty());
  EXPECT_THROW(fs::SpscRing<int>(0), fs::Error);
}

TEST(SpscRing, InPlaceSlotsReuseTheirBuffers) {
  fs::SpscRing<std::vector<std::uint8_t>> r(4);
  r.prepare_slots([](std::vector<std::uint8_t>& v) { v.reserve(4096); });
  fs::AllocCounter c;
  for (int round = 0; round < 100; ++round) {
    auto* slot = r.acquire();
    ASSERT_NE(slot, nullptr);
    slot->assign(1000 + static_cast<std::size_t>(round), static_cast<std::uint8_t>(round));
    r.publish();
    auto* f = r.front();
    ASSERT_NE(f, nullptr);
    EXPECT_EQ(f->size(), 1000u + static_cast<std::size_t>(round));
    EXPECT_EQ(f->back(), static_cast<std::uint8_t>(round));
    r.pop();
  }
  EXPECT_EQ(c.allocations(), 0u);
}

TEST(SpscRing, TwoThreadsTransferEverythingInOrder) {
  constexpr std::uint64_t kCount = 200000;
  fs::SpscRing<std::uint64_t> r(64);
  std::thread producer([&] {
    for (std::uint64_t i = 1; i <= kCount;) {
      if (r.try_push(i))
        ++i;
      else
        std::this_thread::yield();
    }
  });
  std::uint64_t expected = 1, sum = 0;
  bool in_order = true;
  while (expected <= kCount) {
    if (const std::uint64_t* v = r.front()) {
      in_order = in_order && (*v == expected);
      sum += *v;
      r.pop();
      ++expected;
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  EXPECT_TRUE(in_order);
  EXPECT_EQ(sum, kCount * (kCount + 1) / 2);
  EXPECT_TRUE(r.empty());
}

}  // namespace
