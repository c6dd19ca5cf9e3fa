#pragma once
// Two match::ArcIndex objects hold the same data: the same entries (in any order among equal sort keys),
// paths, path starts, flattest angles and fingerprints. Then candidates() gives the same marks for every
// scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <tuple>
#include <vector>

#include "host/match/arc_index.hpp"

namespace fs::test {

inline void expect_same_index(const host::match::ArcIndex& a, const host::match::ArcIndex& b) {
  using Entry = host::match::ArcIndex::Entry;
  auto sorted = [](const host::match::ArcIndex& x) {
    std::vector<Entry> e(x.entry_array().begin(), x.entry_array().end());
    std::sort(e.begin(), e.end(), [](const Entry& p, const Entry& q) {
      return std::tie(p.ref, p.angle, p.a0, p.a1) < std::tie(q.ref, q.angle, q.a0, q.a1);
    });
    return e;
  };
  EXPECT_EQ(a.references(), b.references());
  const auto ea = sorted(a), eb = sorted(b);
  ASSERT_EQ(ea.size(), eb.size());
  for (std::size_t i = 0; i < ea.size(); ++i)
    EXPECT_TRUE(ea[i].ref == eb[i].ref && ea[i].angle == eb[i].angle && ea[i].a0 == eb[i].a0 &&
                ea[i].a1 == eb[i].a1)
        << "entry " << i;
  ASSERT_EQ(a.path_array().size(), b.path_array().size());
  for (std::size_t i = 0; i < a.path_array().size(); ++i) {
    const auto &p = a.path_array()[i], &q = b.path_array()[i];
    EXPECT_TRUE(std::tie(p.xy, p.yz, p.xz, p.ax, p.ay, p.az) == std::tie(q.xy, q.yz, q.xz, q.ax, q.ay, q.az))
        << "path " << i;
  }
  EXPECT_TRUE(std::ranges::equal(a.path_starts(), b.path_starts()));
  EXPECT_TRUE(std::ranges::equal(a.flattest_array(), b.flattest_array()));
  EXPECT_TRUE(std::ranges::equal(a.fingerprints(), b.fingerprints()));
}

}  // namespace fs::test
