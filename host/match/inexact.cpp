#include "host/match/inexact.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

#include <Eigen/Geometry>

#include "common/error.hpp"
#include "host/match/compact_graph.hpp"
#include "host/match/node_set.hpp"
#include "host/match/rotation_fit.hpp"

namespace fs::host::match {

namespace {

class SteadyClock final : public MatchClock {
 public:
  std::int64_t now_ns() const override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};

std::uint64_t pair_key(int r, int s) {
  // splitmix64 of the pair index: order-independent match-set hash = XOR of pair keys (Zobrist hashing).
  std::uint64_t z =
      static_cast<std::uint64_t>(r) * kMaxNodes + static_cast<std::uint64_t>(s) + 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double rel_diss(double a, double b) {
  const double m = std::max(a, b);
  return m > 0 ? std::abs(a - b) / m : 0.0;
}

// Hot fields first (heap keys, tree links, flags), the rotation fit matrices last.
struct State {
  double cost = 0;  // exact when fitted; otherwise a lower bound (see lazy fits below)
  double sum_gamma = 0, d_area = 0, d_border = 0, rotfit = 0;
  double lambda = 0;  // smallest eigenvalue of B: lower bound of the children's
  std::uint64_t hash = 0;
  int parent = -1, child_index = 0, level = 0, r = -1, s = -1;
  int am = 0, ai = 0, ad = 0, children = 0, first_r = -1;
  bool expanded = false, degenerate = true;
  bool fitted = true;      // R, q, lambda, rotfit and cost are final
  NodeSet cr, cs, tr, ts;  // core / terminal sets (reference, scene); rest = complement
};

// The rotation fit data of a state, kept apart from State so that the tree walks, duplicate tests and heap
// keys touch less memory.
struct FitData {
  Mat4 B = Mat4::Zero();          // accumulated sum gamma A (7.5.8)
  Mat3 R = Mat3::Identity();      // best fitting rotation
  Eigen::Vector4d q{0, 0, 0, 1};  // its quaternion (x y z w): warm start of the children's fits
};

// Priority queue entry: the ordering key is copied out of the state (no pool access while sifting).
struct HeapItem {
  double cost;
  int level;
  int id;
};
// Lowest cost first; among equal costs the deeper state (favours well developed paths, 7.2.4), then the older
// one.
inline bool heap_less(const HeapItem& x, const HeapItem& y) {
  if (x.cost != y.cost) return x.cost < y.cost;
  if (x.level != y.level) return x.level > y.level;
  return x.id < y.id;
}

}  // namespace

std::string_view stop_name(StopReason r) {
  switch (r) {
    case StopReason::kNoStates:
      return "no states left";
    case StopReason::kSolutionsFound:
      return "solutions found";
    case StopReason::kStateBudget:
      return "state budget";
    case StopReason::kTimeBudget:
      return "time budget";
  }
  return "?";
}

const MatchClock& steady_match_clock() {
  static const SteadyClock clock;
  return clock;
}

// Speed (issue 9), without changing any result:
//  - Lazy rotation fits. A new state of level >= 2 is created with B and
//    sum gamma but without its eigen solve when the conditions that need e_rotfit (8 cost threshold, 9.3
//    rotation fit similarity) are already decided by bounds of lambda_min(B): from below the parent's
//    lambda_min (Weyl: B = B_parent + gamma A, A PSD), from above the Rayleigh quotient of B at the parent's
//    quaternion, both widened by 1e-9 trace(B) (far above the solver's error). Such a state enters the
//    priority queue with the cost lower bound; when it reaches the top it is fitted (same solver, same
//    inputs, so bit-identical) and re-queued if another state now comes first, so states are expanded in
//    exactly the original order. Most created states are never expanded, and their fits are saved. Reported
//    solutions are fitted on demand, and selected by a lazy top-k over the cost lower bounds instead of
//    sorting every candidate.
//  - The visibility check of new level-2 states (the one check that needs a rotation before the state exists)
//    uses the closed-form two-pair fit (two_pair_fit, rotation_fit.hpp) when it is well conditioned and both
//    rotated normals are more than 1e-7 away from the cone (the solver's rotation differs by < 1e-9 there);
//    otherwise the solver, as before. lambda_min is then known in closed form (bounds +- 1e-9 trace B).
//  - The duplicate-test table starts at 4096 slots and doubles inside its reserved memory; a 16 KB Bloom
//  filter
//    answers most misses without a table probe; the slot is prefetched once the match-set hash is known.
//  - The rotation data (B, R, q) lives in a parallel array (FitData): tree walks, duplicate tests and heap
//  keys
//    touch smaller states.
//  - Per-match tables of the pair-static quantities (gamma, D_area term, node degree condition), supernode
//    candidates counted in bulk, heap entries that carry their key, hash slots that carry the hash, and the
//    candidate state built in place in the pool (no 400-byte temporary per candidate).
struct InexactMatcher::Impl {
  MatcherLimits limits;
  const MatchClock* clock = &steady_match_clock();
  std::unique_ptr<CompactGraph> S = std::make_unique<CompactGraph>();  // scene
  std::unique_ptr<CompactGraph> G = std::make_unique<CompactGraph>();  // reference
  std::vector<State> pool;
  std::vector<FitData> fitdata;  // parallel to pool
  std::vector<HeapItem> heap;    // open states, min key first
  struct Slot {
    std::uint64_t hash = 0;
    std::uint32_t gen = 0;
    int state = -1;
  };
  std::vector<Slot> table;  // duplicate test (new match condition)
  std::uint64_t mask = 0;
  std::uint32_t gen = 0;
  std::vector<int> leaves;  // solution candidates
  std::vector<int> sorted;  // counting sort buffer of the leaves
  // Kept complete solutions of the subset condition, contiguous (core sets and level copied out of the pool).
  struct KeptCore {
    NodeSet cr, cs;
    int level, id;
  };
  std::vector<KeptCore> kept_cores;
  // Inverted index of kept_cores by match pair (r * kMaxNodes + s): each list holds, in insertion (= level-
  // descending) order, the kept complete solutions that contain the pair. A leaf can only be a subset of a
  // solution in the list of each of its pairs, so it scans the shortest one. Entries live in a fixed array;
  // when it is full the scan falls back to all of kept_cores (same answers).
  struct PairEntry {
    int next, kept;
  };
  std::vector<PairEntry> pair_entries;
  std::vector<int> pair_head, pair_tail, pair_count;
  std::vector<int> pair_touched;
  std::vector<HeapItem> topk;  // lazy top-k selection of the reported solutions
  std::vector<int> ranked;     // the reported solutions' states, best first
  std::vector<Solution> solutions;
  std::vector<NodeMatch> match_buf;
  std::vector<int> path_buf;
  std::array<int, kMaxNodes> r2s{}, s2r{}, mark{};
  // Pair tables (index r * kMaxNodes + s), filled per match for the graphs' sizes.
  std::vector<double> pair_gamma, pair_darea;
  std::vector<std::uint8_t> pair_degree_fail;
  std::vector<std::uint8_t> pair_area_fail;  // one-sided area condition (th_area_ratio)
  bool unit_normals = false;                 // every real normal of both graphs has length 1 within 1e-12
  MatchResult result;
  const MatchParams* P = nullptr;
  int n_states = 0;  // used pool entries (root included)
  std::int64_t budget = 0;

  explicit Impl(const MatcherLimits& l) : limits(l) {
    if (limits.max_states < 1) limits.max_states = 1;
    if (limits.max_reported < 1) limits.max_reported = 1;
    const auto cap = static_cast<std::size_t>(limits.max_states) + 1;
    pool.resize(cap + 1);  // + 1: the scratch entry a candidate is built in when the pool is full
    fitdata.resize(cap + 1);
    heap.reserve(cap);
    std::size_t t = 16;
    while (t < 2 * cap) t <<= 1;
    table.resize(t);
    mask = t - 1;
    leaves.reserve(cap);
    sorted.reserve(cap);
    kept_cores.reserve(cap);
    pair_entries.reserve(8 * cap);
    pair_head.assign(static_cast<std::size_t>(kMaxNodes) * kMaxNodes, -1);
    pair_tail.assign(static_cast<std::size_t>(kMaxNodes) * kMaxNodes, -1);
    pair_count.assign(static_cast<std::size_t>(kMaxNodes) * kMaxNodes, 0);
    pair_touched.reserve(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
    topk.reserve(cap);
    ranked.resize(static_cast<std::size_t>(limits.max_reported));
    solutions.resize(static_cast<std::size_t>(limits.max_reported));
    match_buf.resize(static_cast<std::size_t>(limits.max_reported) * kMaxNodes);
    path_buf.resize(static_cast<std::size_t>(limits.max_reported) * kMaxNodes);
    pair_gamma.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
    pair_darea.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
    pair_degree_fail.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
    pair_area_fail.resize(static_cast<std::size_t>(kMaxNodes) * kMaxNodes);
    r2s.fill(-1);
    s2r.fill(-1);
    mark.fill(-1);
  }

  // ---- priority queue (binary heap of keyed entries) ----
  void heap_push(int x) {
    const State& st = pool[static_cast<std::size_t>(x)];
    heap.push_back(
        HeapItem{st.cost, st.level, x});  // capacity reserved for every pool entry: never reallocates
    std::size_t i = heap.size() - 1;
    const HeapItem item = heap[i];
    while (i > 0) {
      const std::size_t p = (i - 1) / 2;
      if (!heap_less(item, heap[p])) break;
      heap[i] = heap[p];
      i = p;
    }
    heap[i] = item;
  }
  int heap_pop() {
    const int top = heap.front().id;
    const HeapItem item = heap.back();
    heap.pop_back();
    const std::size_t n = heap.size();
    if (n == 0) return top;
    std::size_t i = 0;
    for (;;) {
      const std::size_t l = 2 * i + 1, r = l + 1;
      if (l >= n) break;
      std::size_t m = l;
      if (r < n && heap_less(heap[r], heap[l])) m = r;
      if (!heap_less(heap[m], item)) break;
      heap[i] = heap[m];
      i = m;
    }
    heap[i] = item;
    return top;
  }

  // ---- duplicate test ----
  // True when a created state has the same match set as (parent's matches + (r, s)); r2s holds the parent's
  // map.
  bool same_matches(const State& e, int r, int s) const {
    for (int k = static_cast<int>(&e - pool.data()); k > 0; k = pool[static_cast<std::size_t>(k)].parent) {
      const State& x = pool[static_cast<std::size_t>(k)];
      if (!(x.r == r && x.s == s) && r2s[static_cast<std::size_t>(x.r)] != x.s) return false;
    }
    return true;
  }
  bool exists(std::uint64_t h, const NodeSet& cr, const NodeSet& cs, int r, int s) const {
    if (!bloom_test(h)) return false;  // most candidates: no table probe
    for (std::uint64_t i = h & mask;; i = (i + 1) & mask) {
      const Slot& sl = table[i];
      if (sl.gen != gen) return false;
      if (sl.hash != h) continue;
      const State& e = pool[static_cast<std::size_t>(sl.state)];
      if (e.cr == cr && e.cs == cs && same_matches(e, r, s)) return true;
    }
  }
  // The table starts small (cache-resident for the usual few thousand states) and doubles inside the slots
  // reserved up front when it becomes half full: a new generation, and the created states re-inserted.
  static constexpr std::uint64_t kInitialSlots = 4096;
  void next_gen() {
    if (++gen == 0) {  // wrapped: clear the table once every 2^32 generations
      for (auto& sl : table) sl = Slot{};
      gen = 1;
    }
  }
  // A one-hash Bloom filter of the table's hashes (16 KB, stays in L1/L2): a clear bit proves absence.
  static constexpr std::uint64_t kBloomBits = std::uint64_t{1} << 17;
  std::vector<std::uint64_t> bloom = std::vector<std::uint64_t>(kBloomBits / 64);
  static std::uint64_t bloom_bit(std::uint64_t h) { return (h >> 40) & (kBloomBits - 1); }
  bool bloom_test(std::uint64_t h) const { return (bloom[bloom_bit(h) >> 6] >> (bloom_bit(h) & 63)) & 1U; }
  void bloom_set(std::uint64_t h) { bloom[bloom_bit(h) >> 6] |= std::uint64_t{1} << (bloom_bit(h) & 63); }
  void reset_table() {
    std::fill(bloom.begin(), bloom.end(), 0);
    next_gen();
    mask = std::min<std::uint64_t>(kInitialSlots, table.size()) - 1;
  }
  void place(std::uint64_t h, int state) {
    std::uint64_t i = h & mask;
    while (table[i].gen == gen) i = (i + 1) & mask;
    table[i] = Slot{h, gen, state};
  }
  void insert(std::uint64_t h, int state) {
    // state - 1 states are in the table (every created state, root excluded).
    if (2 * static_cast<std::uint64_t>(state) > mask + 1 && mask + 1 < table.size()) {
      mask = 2 * mask + 1;
      next_gen();
      for (int k = 1; k < state; ++k) place(pool[static_cast<std::size_t>(k)].hash, k);
    }
    place(h, state);
    bloom_set(h);
  }

  void load_map(int st, int value_sign) {
    for (int k = st; k > 0; k = pool[static_cast<std::size_t>(k)].parent) {
      const State& x = pool[static_cast<std::size_t>(k)];
      r2s[static_cast<std::size_t>(x.r)] = value_sign > 0 ? x.s : -1;
      s2r[static_cast<std::size_t>(x.s)] = value_sign > 0 ? x.r : -1;
    }
  }

  double cost_of(const State& c) const { return cost_with(c, c.rotfit); }
  // The cost with a given rotation fit error (monotone non-decreasing in it: epsilon >= 0).
  double cost_with(const State& c, double rotfit) const {
    double cost = 0;
    if (c.level > 0) cost += (P->alpha * c.d_area + P->epsilon * rotfit) / c.level;
    const int arcs = c.am + c.ai + c.ad;
    if (arcs > 0) cost += (P->beta * c.d_border + P->gamma * c.ai + P->delta * c.ad) / arcs;
    return cost;
  }
  static double rotfit_of(const State& c, double lambda) {
    return c.sum_gamma > 0 ? lambda / (2.0 * c.sum_gamma) : 0.0;
  }

  FastFitStats fit_stats;
  void fit(int ci, int pi) {
    State& c = pool[static_cast<std::size_t>(ci)];
    FitData& cf = fitdata[static_cast<std::size_t>(ci)];
    const RotationFit f = solve_rotation_fast(cf.B, pool[static_cast<std::size_t>(pi)].lambda,
                                              fitdata[static_cast<std::size_t>(pi)].q, &fit_stats);
    cf.R = f.R;
    cf.q = f.q;
    c.lambda = f.lambda_min;
    c.rotfit = rotfit_of(c, f.lambda_min);
  }
  // Completes a lazily created state: the fit its creation skipped, and the exact cost.
  void finish(int id) {
    State& c = pool[static_cast<std::size_t>(id)];
    if (c.fitted) return;
    fit(id, c.parent);
    c.cost = cost_of(c);
    c.fitted = true;
  }

  void fill_pair_tables() {
    const MatchParams& p = *P;
    const CompactGraph& gr = *G;
    const CompactGraph& gs = *S;
    unit_normals = true;
    for (const CompactGraph* g : {&gr, &gs})
      for (int i = 0; i < g->n; ++i)
        if (!g->supernode[static_cast<std::size_t>(i)] &&
            !(std::abs(g->normal[static_cast<std::size_t>(i)].squaredNorm() - 1.0) <= 1e-12))
          unit_normals = false;
    NodeSet gs_super;
    for (int i = 0; i < gs.n; ++i)
      if (gs.supernode[static_cast<std::size_t>(i)]) gs_super.set(i);
    for (int r = 0; r < gr.n; ++r) {
      const auto ur = static_cast<std::size_t>(r);
      for (int s = 0; s < gs.n; ++s) {
        const auto us = static_cast<std::size_t>(s);
        const std::size_t k = ur * kMaxNodes + us;
        pair_gamma[k] = std::sqrt(gs.area[us] * gr.area[ur]);
        pair_darea[k] = rel_diss(gr.area[ur], gs.area[us]);
        // 6 node degree (7.3.6: only faces not adjacent to invisible parts have comparable degrees; a scene
        // face bordering the supernode may have lost neighbours, so for it only a surplus of scene neighbours
        // counts.)
        const int dr = gr.degree[ur], ds = gs.degree[us];
        const bool open = (gs.adj[us] & gs_super).any();
        pair_degree_fail[k] = open ? (ds - 1 - dr > p.th_nodedegree) : (std::abs(dr - ds) > p.th_nodedegree);
        pair_area_fail[k] = !gs.supernode[us] && !gr.supernode[ur] &&
                            gs.area[us] > p.th_area_ratio * gr.area[ur] + p.th_area_slack_mm2;
      }
    }
  }

  void run(MatchStats& st) {
    const MatchParams& p = *P;
    const CompactGraph& gr = *G;
    const CompactGraph& gs = *S;
    const double cos_omega = std::cos(p.th_omega_deg * std::numbers::pi / 180.0);
    const double cos_vis = std::cos(p.th_visibility_deg * std::numbers::pi / 180.0);
    const double sin_degen = std::sin(p.degenerate_deg * std::numbers::pi / 180.0);
    const bool always_vis = p.th_visibility_deg >= 180.0, always_rigid = p.th_omega_deg >= 180.0;
    const bool vis_on = p.on(Condition::kVisibility) && !always_vis;
    const bool rigid_on = p.on(Condition::kRigidity) && !always_rigid;
    const bool super_on = p.on(Condition::kSupernode);
    const bool cost_on = p.on(Condition::kCostThreshold);
    const bool rotsim_on = p.on(Condition::kRotfitSimilarity);
    const bool lazy_ok = p.epsilon >= 0;  // the cost bounds need a cost non-decreasing in e_rotfit
    const Vec3 obs = gs.observer;
    const std::int64_t t0 = clock->now_ns();
    const bool timed = std::isfinite(p.max_time_ms);
    std::int64_t solutions_found = 0;
    int best_leaf = -1;

    fill_pair_tables();
    NodeSet gs_super;
    for (int i = 0; i < gs.n; ++i)
      if (gs.supernode[static_cast<std::size_t>(i)]) gs_super.set(i);
    NodeSet all_r, all_s;
    for (int i = 0; i < gr.n; ++i) all_r.set(i);
    for (int i = 0; i < gs.n; ++i) all_s.set(i);

    pool[0] = State{};
    fitdata[0] = FitData{};
    n_states = 1;
    heap.clear();
    heap_push(0);
    st.stop = StopReason::kNoStates;
    fit_stats = {};
    bool stop = false;

    while (!stop) {
      if (heap.empty()) {
        st.stop = StopReason::kNoStates;
        break;
      }
      if (timed && (st.states_expanded & 15) == 0 &&
          static_cast<double>(clock->now_ns() - t0) * 1e-6 >= p.max_time_ms) {
        st.stop = StopReason::kTimeBudget;
        break;
      }
      // Pop the state with the lowest exact key: a lazily created state on top is fitted first and goes back
      // when its exact key is no longer the lowest.
      int pi = heap_pop();
      while (!pool[static_cast<std::size_t>(pi)].fitted) {
        finish(pi);
        const State& x = pool[static_cast<std::size_t>(pi)];
        if (heap.empty() || !heap_less(heap.front(), HeapItem{x.cost, x.level, pi})) break;
        heap_push(pi);
        pi = heap_pop();
      }
      const State& par = pool[static_cast<std::size_t>(pi)];
      const FitData& pf = fitdata[static_cast<std::size_t>(pi)];
      const bool root = pi == 0;
      load_map(pi, +1);

      NodeSet cand_r, cand_s;
      if (root || !p.on(Condition::kConnectivity)) {
        cand_r = all_r.minus(par.cr);
        cand_s = all_s.minus(par.cs);
      } else {
        cand_r = par.tr;
        cand_s = par.ts;
        const std::int64_t all = static_cast<std::int64_t>(gr.n - par.level) * (gs.n - par.level);
        st.removed[static_cast<std::size_t>(Condition::kConnectivity)] +=
            all - static_cast<std::int64_t>(cand_r.count()) * cand_s.count();
      }
      const bool use_rot = par.level >= 2 && !par.degenerate;
      // 2 supernode: scene supernode candidates are counted in bulk, the loop visits the others.
      const NodeSet scan_s = super_on ? cand_s.minus(gs_super) : cand_s;
      const NodeSet super_s = super_on ? (cand_s & gs_super) : NodeSet{};
      const int n_cand_s = cand_s.count(), n_super_s = super_s.count();
      // 3 rigidity applies to every candidate of this parent, 4 visibility forward too.
      const bool rigid_now = rigid_on && use_rot;
      const bool rigid_pair = rigid_on && p.rigidity_pairs && par.level == 1;
      const bool vis_forward = vis_on && use_rot;
      const bool vis_backward = vis_on && !use_rot && par.level == 1;
      int created = 0;
      auto removed = [&](Condition c) { ++st.removed[static_cast<std::size_t>(c)]; };

      cand_r.for_each([&](int r) {
        if (stop) return;
        const auto ur = static_cast<std::size_t>(r);
        if (super_on && gr.supernode[ur]) {
          st.candidates += n_cand_s;
          st.removed[static_cast<std::size_t>(Condition::kSupernode)] += n_cand_s;
          return;
        }
        const Vec3 nr = gr.normal[ur];
        const Vec3 pred = pf.R * nr;  // predicted scene normal
        const bool pred_invisible = vis_forward && pred.dot(obs) < cos_vis;
        // |angle(r0, r) - angle(s0, s)| <= TH_omega  <=>  cos(difference) = c_r c_s + s_r s_s >= cos TH_omega
        // (both angles in [0, pi]), so no acos in the candidate loop.
        const double cr0 =
            rigid_pair ? std::clamp(gr.normal[static_cast<std::size_t>(par.r)].dot(nr), -1.0, 1.0) : 0.0;
        const double sr0 = std::sqrt(std::max(0.0, 1.0 - cr0 * cr0));
        int stop_s = -1;
        scan_s.for_each([&](int s) {
          if (stop) return;
          ++st.candidates;
          const auto us = static_cast<std::size_t>(s);
          const Vec3& ns = gs.normal[us];
          // 3 rigidity (forward check from parents of level >= 2)
          if (rigid_now && pred.dot(ns) < cos_omega) return removed(Condition::kRigidity);
          if (rigid_pair) {
            const double cs0 = std::clamp(gs.normal[static_cast<std::size_t>(par.s)].dot(ns), -1.0, 1.0);
            if (cr0 * cs0 + sr0 * std::sqrt(std::max(0.0, 1.0 - cs0 * cs0)) < cos_omega)
              return removed(Condition::kRigidity);
          }
          // 4 visibility: forward from level >= 2 parents; backward check of new level-2 states
          if (pred_invisible) return removed(Condition::kVisibility);
          const std::size_t pk = ur * kMaxNodes + us;
          // The match-set hash, and its table slot fetched early (probed by condition 5, written on
          // creation).
          const std::uint64_t h = par.hash ^ pair_key(r, s);
          __builtin_prefetch(&table[h & mask]);
          State& c = pool[static_cast<std::size_t>(n_states)];  // built in place; committed by ++n_states
          FitData& cf = fitdata[static_cast<std::size_t>(n_states)];
          c.level = par.level + 1;
          bool built = false;
          // Bounds of e_rotfit while the state is not fitted (lazy path): [rot_lo, rot_hi].
          double rot_lo = 0, rot_hi = 0;
          bool lazy = false;
          auto lazy_bounds = [&](double lam_lo, double lam_hi) {
            const double tol = 1e-9 * cf.B.trace();
            rot_lo = rotfit_of(c, std::max(0.0, lam_lo - tol));
            rot_hi = rotfit_of(c, lam_hi + tol);
            lazy = true;
          };
          // Weyl: lambda_min(B) >= the parent's; the Rayleigh quotient at the parent's quaternion bounds it
          // above.
          auto lazy_from_parent = [&] { lazy_bounds(par.lambda, pf.q.dot(cf.B * pf.q)); };
          auto build = [&] {  // B and the flags; the fit separately (fit_now)
            c.sum_gamma = par.sum_gamma;
            cf.B = pf.B;
            const double g = pair_gamma[pk];
            add_pair(cf.B, nr, ns, g);
            c.sum_gamma += g;
            c.first_r = root ? r : par.first_r;
            c.degenerate =
                root || (par.degenerate &&
                         nr.cross(gr.normal[static_cast<std::size_t>(c.first_r)]).norm() < sin_degen);
            built = true;
          };
          auto fit_now = [&] {
            if (root) {
              // One pair: zero error, a one-parameter family of rotations; take the smallest one (no solve).
              const Eigen::Quaterniond q1 = Eigen::Quaterniond::FromTwoVectors(nr, ns);
              cf.R = q1.toRotationMatrix();
              cf.q = Eigen::Vector4d(q1.x(), q1.y(), q1.z(), q1.w());
              c.lambda = 0.0;
              c.rotfit = 0.0;
            } else {
              fit(n_states, pi);
            }
          };
          if (vis_backward) {
            build();
            if (c.degenerate && lazy_ok) {
              lazy_from_parent();  // no visibility check for a degenerate pair: no fit needed yet
            } else {
              const std::size_t pk1 =
                  static_cast<std::size_t>(par.r) * kMaxNodes + static_cast<std::size_t>(par.s);
              const Vec3& n1 = gr.normal[static_cast<std::size_t>(par.r)];
              const TwoPairFit tp = unit_normals && lazy_ok && !c.degenerate
                                        ? two_pair_fit(n1, gs.normal[static_cast<std::size_t>(par.s)],
                                                       pair_gamma[pk1], nr, ns, pair_gamma[pk])
                                        : TwoPairFit{};
              // The closed form decides when both rotated normals are clearly (1e-7) on one side of the cone.
              const double d1 = tp.ok ? tp.Rr1.dot(obs) : 0.0, d2 = tp.ok ? tp.Rr2.dot(obs) : 0.0;
              if (tp.ok && std::abs(d1 - cos_vis) > 1e-7 && std::abs(d2 - cos_vis) > 1e-7) {
                if (d2 < cos_vis || d1 < cos_vis) return removed(Condition::kVisibility);
                lazy_bounds(tp.lambda, tp.lambda);
              } else {
                fit_now();
                if (!c.degenerate && ((cf.R * nr).dot(obs) < cos_vis || (cf.R * n1).dot(obs) < cos_vis))
                  return removed(Condition::kVisibility);
              }
            }
          }
          // 5 new match (no duplicate match sets)
          NodeSet cr = par.cr, cs = par.cs;
          cr.set(r);
          cs.set(s);
          if (p.on(Condition::kNewMatch) && par.level >= 1 && exists(h, cr, cs, r, s))
            return removed(Condition::kNewMatch);
          // 6 node degree
          if (p.on(Condition::kNodeDegree) && pair_degree_fail[pk]) return removed(Condition::kNodeDegree);
          // 9.1 node similarity, one-sided area part (cheap, decided per pair)
          if (p.on(Condition::kNodeSimilarity) && pair_area_fail[pk])
            return removed(Condition::kNodeSimilarity);
          // arcs to the core: matched / inserted (reference only) / deleted (scene only)
          int dam = 0, dai = 0;
          double dborder = 0;
          const NodeSet nrc = gr.adj[ur] & par.cr;
          nrc.for_each([&](int rc) {
            const int sc = r2s[static_cast<std::size_t>(rc)];
            if (gs.adj[us].test(sc)) {
              ++dam;
              dborder += rel_diss(gr.border[ur][static_cast<std::size_t>(rc)],
                                  gs.border[us][static_cast<std::size_t>(sc)]);
            } else {
              ++dai;
            }
          });
          const int dad = (gs.adj[us] & par.cs).count() - dam;
          // 7 neighbour match
          if (p.on(Condition::kNeighborMatch) && par.level >= 1 && dam == 0)
            return removed(Condition::kNeighborMatch);
          c.am = par.am + dam;
          c.ai = par.ai + dai;
          c.ad = par.ad + dad;
          const double darea = pair_darea[pk];
          c.d_area = par.d_area + darea;
          c.d_border = par.d_border + dborder;
          if (!built) {
            // 8 cost threshold, early: the cost without the rotation fit term (epsilon e_rotfit / level >= 0)
            // is a lower bound, so a candidate failing it fails condition 8 anyway; skip its eigen solve.
            if (cost_on && p.epsilon >= 0) {
              if (cost_with(c, 0.0) - par.cost > p.th_cost) return removed(Condition::kCostThreshold);
            }
            build();
            if (!root && lazy_ok)
              lazy_from_parent();
            else
              fit_now();
          }
          // 8 cost threshold
          if (cost_on) {
            if (lazy) {
              if (cost_with(c, rot_lo) - par.cost > p.th_cost) return removed(Condition::kCostThreshold);
              if (cost_with(c, rot_hi) - par.cost > p.th_cost) {  // undecided by the bounds: fit now
                fit_now();
                lazy = false;
              }
            }
            if (!lazy && cost_of(c) - par.cost > p.th_cost) return removed(Condition::kCostThreshold);
          }
          // 9.1 node, 9.2 arc attribute, 9.3 rotation fit similarity
          if (p.on(Condition::kNodeSimilarity) && darea > p.th_node)
            return removed(Condition::kNodeSimilarity);
          if (p.on(Condition::kArcSimilarity) && dborder > p.th_arcatt)
            return removed(Condition::kArcSimilarity);
          if (rotsim_on) {
            if (lazy) {
              if (rot_lo - par.rotfit > p.th_rotfit) return removed(Condition::kRotfitSimilarity);
              if (rot_hi - par.rotfit > p.th_rotfit) {
                fit_now();
                lazy = false;
              }
            }
            if (!lazy && c.rotfit - par.rotfit > p.th_rotfit) return removed(Condition::kRotfitSimilarity);
          }
          // 10 search depth
          if (p.on(Condition::kSearchDepth) && c.level > p.th_maxlevel)
            return removed(Condition::kSearchDepth);
          // create the state
          if (n_states > budget) {
            st.stop = StopReason::kStateBudget;
            stop = true;
            stop_s = s;
            return;
          }
          if (lazy) {
            c.rotfit = rot_lo;
            c.cost = cost_with(c, rot_lo);  // a lower bound of the exact cost: the heap key until fitted
            c.fitted = false;
          } else {
            c.cost = cost_of(c);
            c.fitted = true;
          }
          c.cr = cr;
          c.cs = cs;
          NodeSet tr = par.tr | gr.adj[ur];
          NodeSet ts = par.ts | gs.adj[us];
          c.tr = tr.minus(cr);
          c.ts = ts.minus(cs);
          c.hash = h;
          c.parent = pi;
          c.child_index = ++created;
          c.r = r;
          c.s = s;
          c.children = 0;
          c.expanded = false;
          const int ci = n_states++;
          insert(h, ci);
          heap_push(ci);
          ++st.states_created;
        });
        // Scene supernode candidates of this r (all of them, or those before the stop).
        if (n_super_s > 0) {
          int k = n_super_s;
          if (stop_s >= 0) {
            k = 0;
            super_s.for_each([&](int s) { k += s < stop_s ? 1 : 0; });
          }
          st.candidates += k;
          st.removed[static_cast<std::size_t>(Condition::kSupernode)] += k;
        }
      });
      load_map(pi, -1);
      State& pm = pool[static_cast<std::size_t>(pi)];
      pm.children = created;
      if (stop) {
        if (created == 0) heap_push(pi);  // not expanded: stays an incomplete solution candidate
        break;
      }
      pm.expanded = true;
      ++st.states_expanded;
      if (created == 0 && !root && pm.level >= p.th_minlevel) {
        if (best_leaf < 0 || pm.cost < pool[static_cast<std::size_t>(best_leaf)].cost) {
          best_leaf = pi;
          st.states_to_best = st.states_created;
          st.time_to_best_ms = static_cast<double>(clock->now_ns() - t0) * 1e-6;
        }
        if (++solutions_found >= p.max_solutions) {
          st.stop = StopReason::kSolutionsFound;
          stop = true;
        }
      }
    }
    st.time_ms = static_cast<double>(clock->now_ns() - t0) * 1e-6;
  }

  // Subset condition: is a's match set a proper subset of b's?
  bool subset(const State& a, const State& b) {
    if (a.level >= b.level || !a.cr.subset_of(b.cr) || !a.cs.subset_of(b.cs)) return false;
    const int bi = static_cast<int>(&b - pool.data());
    for (int k = bi; k > 0; k = pool[static_cast<std::size_t>(k)].parent)
      mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] =
          pool[static_cast<std::size_t>(k)].s;
    bool ok = true;
    for (int k = static_cast<int>(&a - pool.data()); k > 0 && ok;
         k = pool[static_cast<std::size_t>(k)].parent)
      ok = mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] ==
           pool[static_cast<std::size_t>(k)].s;
    for (int k = bi; k > 0; k = pool[static_cast<std::size_t>(k)].parent)
      mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] = -1;
    return ok;
  }

  // U of the zeta ranking (params.hpp), two sides, each the area share of the real faces adjacent to a
  // match's faces that it leaves unmatched, weighted by face_weight(i) in [0, 1]: the open area over that
  // plus the matched area of graph g for the core set `core`.
  template <class Weight>
  static double open_neighbour_share(const CompactGraph& g, const NodeSet& core, Weight face_weight) {
    NodeSet around;
    double matched = 0.0;
    core.for_each([&](int i) {
      around = around | g.adj[static_cast<std::size_t>(i)];
      matched += g.area[static_cast<std::size_t>(i)];
    });
    double open = 0.0;
    (around & g.real).minus(core).for_each([&](int i) {
      open += face_weight(i) * g.area[static_cast<std::size_t>(i)];
    });
    return open + matched > 0.0 ? open / (open + matched) : 0.0;
  }
  // Scene side: every unmatched scene face next to the match counts.
  double unexplained(const State& x) const {
    return open_neighbour_share(*S, x.cs, [](int) { return 1.0; });
  }
  // Model side (needs x's rotation, so 0 until x is fitted): unmatched reference faces next to the match
  // count as far as the rotation turns them toward the sensor (weight 1 within 60 deg of the observer,
  // falling to 0 at 90 deg, where faces are seen edge-on): in a wrong pose of a part that looks like another
  // part, such faces should have been seen next to the match.
  double unexplained_model(int id) const {
    const State& x = pool[static_cast<std::size_t>(id)];
    if (!x.fitted || x.degenerate) return 0.0;
    const Mat3& R = fitdata[static_cast<std::size_t>(id)].R;
    constexpr double kCosFull = 0.5;  // cos 60 deg
    return open_neighbour_share(*G, x.cr, [&](int i) {
      return std::clamp((R * G->normal[static_cast<std::size_t>(i)]).dot(S->observer) / kCosFull, 0.0, 1.0);
    });
  }

  void collect(MatchStats& st) {
    const MatchParams& p = *P;
    leaves.clear();
    for (int i = 1; i < n_states; ++i) {
      const State& x = pool[static_cast<std::size_t>(i)];
      const bool leaf = x.expanded && x.children == 0 && x.level >= p.th_minlevel;
      const bool incomplete =
          !x.expanded && st.stop != StopReason::kNoStates && (x.level >= p.th_minlevel || p.keep_partial);
      if (leaf || incomplete) leaves.push_back(i);
    }
    st.leaf_solutions = static_cast<std::int64_t>(leaves.size());
    // Subset condition (7.7.2, 7.7.3): a traditional solution is dropped when its match set is a subset of
    // another traditional solution's; an incomplete one when it is a subset of a traditional solution's.
    // Traditional (complete) solutions first, by level descending, then the incomplete ones.
    // (Counting sort by that key: leaves are gathered by ascending state number, so the result is the order
    // of a comparison sort by (complete first, level descending, state number).)
    {
      std::array<int, 2 * (kMaxNodes + 1) + 1> start{};
      auto bucket = [&](int id) {
        const State& x = pool[static_cast<std::size_t>(id)];
        return (x.expanded ? 0 : kMaxNodes + 1) + (kMaxNodes - x.level);
      };
      for (int id : leaves) ++start[static_cast<std::size_t>(bucket(id)) + 1];
      for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
      sorted.resize(leaves.size());  // capacity reserved for every pool entry: no allocation
      for (int id : leaves)
        sorted[static_cast<std::size_t>(start[static_cast<std::size_t>(bucket(id))]++)] = id;
      leaves.swap(sorted);
    }
    std::size_t n_complete = 0;
    while (n_complete < leaves.size() && pool[static_cast<std::size_t>(leaves[n_complete])].expanded)
      ++n_complete;
    // Each leaf is compared with the complete solutions kept so far that have a higher level (a subset has a
    // lower level). Those are kept in level-descending order; the leaf scans the shortest pair list of the
    // inverted index (or, when the index is full, all of kept_cores), filters by the core sets, and only the
    // survivors walk the search tree. The answers are those of comparing it with every kept solution.
    kept_cores.clear();
    pair_entries.clear();
    bool index_full = false;
    auto pair_key = [](const State& y) {
      return static_cast<std::size_t>(y.r) * kMaxNodes + static_cast<std::size_t>(y.s);
    };
    auto covered = [&](const State& a, const KeptCore& b) {
      return a.cr.subset_of(b.cr) && a.cs.subset_of(b.cs) && subset(a, pool[static_cast<std::size_t>(b.id)]);
    };
    std::size_t kept = 0;
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const int id = leaves[i];
      const State& a = pool[static_cast<std::size_t>(id)];
      // Candidates come in level-descending order; those of a level <= a's cannot hold it.
      bool sub = false;
      auto check = [&](const KeptCore& b) {  // true: stop scanning
        if (b.level <= a.level) return true;
        sub = covered(a, b);
        return sub;
      };
      if (index_full) {
        for (const KeptCore& b : kept_cores)
          if (check(b)) break;
      } else {
        int best = -1, best_count = std::numeric_limits<int>::max();
        for (int q = id; q > 0 && best_count > 0; q = pool[static_cast<std::size_t>(q)].parent) {
          const int k = static_cast<int>(pair_key(pool[static_cast<std::size_t>(q)]));
          if (pair_count[static_cast<std::size_t>(k)] < best_count)
            best = k, best_count = pair_count[static_cast<std::size_t>(k)];
        }
        for (int e = best_count > 0 ? pair_head[static_cast<std::size_t>(best)] : -1; e >= 0;
             e = pair_entries[static_cast<std::size_t>(e)].next)
          if (check(kept_cores[static_cast<std::size_t>(pair_entries[static_cast<std::size_t>(e)].kept)]))
            break;
      }
      if (sub) {
        ++st.subset_removed;
        continue;
      }
      leaves[kept++] = id;
      if (i >= n_complete) continue;
      kept_cores.push_back(KeptCore{a.cr, a.cs, a.level, id});
      if (index_full) continue;
      if (pair_entries.size() + static_cast<std::size_t>(a.level) > pair_entries.capacity()) {
        index_full = true;
        continue;
      }
      const int kept_index = static_cast<int>(kept_cores.size()) - 1;
      for (int q = id; q > 0; q = pool[static_cast<std::size_t>(q)].parent) {
        const std::size_t k = pair_key(pool[static_cast<std::size_t>(q)]);
        const int e = static_cast<int>(pair_entries.size());
        pair_entries.push_back(PairEntry{-1, kept_index});
        if (pair_head[k] < 0) {
          pair_head[k] = e;
          pair_touched.push_back(static_cast<int>(k));
        } else {
          pair_entries[static_cast<std::size_t>(pair_tail[k])].next = e;
        }
        pair_tail[k] = e;
        ++pair_count[k];
      }
    }
    for (int k : pair_touched) {
      pair_head[static_cast<std::size_t>(k)] = pair_tail[static_cast<std::size_t>(k)] = -1;
      pair_count[static_cast<std::size_t>(k)] = 0;
    }
    pair_touched.clear();
    leaves.resize(kept);  // shrinking: no allocation
    st.solutions = static_cast<std::int64_t>(kept);
    // The best n by (cost, state number), as a full sort would give them: a min-heap over the keys, where a
    // lazily created state's key is its cost lower bound until it reaches the top and is fitted.
    const std::size_t n = std::min(kept, solutions.size());
    auto later = [](const HeapItem& a, const HeapItem& b) {
      return a.cost > b.cost || (a.cost == b.cost && a.id > b.id);
    };
    // Ranking key: cost + zeta U. For a state not fitted yet its cost is a lower bound and U_model is 0 (it
    // needs the rotation; it is >= 0 once fitted), so the key is a lower bound of the final one, as the lazy
    // top-k needs.
    auto key = [&](const State& x) {
      if (p.zeta <= 0) return x.cost;
      const int id = static_cast<int>(&x - pool.data());
      return x.cost + p.zeta * (unexplained(x) + unexplained_model(id));
    };
    topk.clear();
    for (int id : leaves) topk.push_back(HeapItem{key(pool[static_cast<std::size_t>(id)]), 0, id});
    std::make_heap(topk.begin(), topk.end(), later);
    std::size_t got = 0;
    while (got < n) {
      std::pop_heap(topk.begin(), topk.end(), later);
      const int id = topk.back().id;
      topk.pop_back();
      State& x = pool[static_cast<std::size_t>(id)];
      if (!x.fitted) {
        finish(id);
        topk.push_back(HeapItem{key(x), 0, id});
        std::push_heap(topk.begin(), topk.end(), later);
        continue;
      }
      ranked[got++] = id;
    }
    for (std::size_t k = 0; k < n; ++k) {
      const State& x = pool[static_cast<std::size_t>(ranked[k])];
      Solution& sol = solutions[k];
      sol.rank = static_cast<int>(k) + 1;
      sol.state = ranked[k];
      sol.level = x.level;
      NodeMatch* m = &match_buf[k * kMaxNodes];
      int* path = &path_buf[k * kMaxNodes];
      int j = x.level;
      for (int q = ranked[k]; q > 0; q = pool[static_cast<std::size_t>(q)].parent) {
        const State& y = pool[static_cast<std::size_t>(q)];
        --j;
        m[j] = NodeMatch{S->id[static_cast<std::size_t>(y.s)], G->id[static_cast<std::size_t>(y.r)]};
        path[j] = y.child_index;
      }
      sol.matches = std::span<const NodeMatch>(m, static_cast<std::size_t>(x.level));
      sol.path = std::span<const int>(path, static_cast<std::size_t>(x.level));
      sol.arcs_matched = x.am;
      sol.arcs_inserted = x.ai;
      sol.arcs_deleted = x.ad;
      sol.node_diss = x.d_area;
      sol.arc_attr_diss = x.d_border;
      sol.arc_struct_diss = x.ai + x.ad;
      sol.rotfit_error = x.rotfit;
      sol.rotation = fitdata[static_cast<std::size_t>(ranked[k])].R;
      sol.cost = x.cost;
      sol.unexplained = unexplained(x) + unexplained_model(ranked[k]);
      sol.complete = x.expanded;
      sol.partial = x.level < p.th_minlevel;
      sol.degenerate = x.degenerate;
    }
    result.solutions = std::span<const Solution>(solutions.data(), n);
    st.best_state = n > 0 ? solutions[0].state : -1;
    if (n >= 2)
      st.cost_ratio = solutions[0].cost > 0 ? solutions[1].cost / solutions[0].cost
                                            : std::numeric_limits<double>::infinity();
    else
      st.cost_ratio = std::numeric_limits<double>::quiet_NaN();
    st.fits_fast = fit_stats.fast;
    st.fits_fallback = fit_stats.fallback;
  }
};

InexactMatcher::InexactMatcher(const MatcherLimits& limits) : impl_(std::make_unique<Impl>(limits)) {}
InexactMatcher::~InexactMatcher() = default;
void InexactMatcher::set_clock(const MatchClock* clock) {
  impl_->clock = clock ? clock : &steady_match_clock();
}
const MatcherLimits& InexactMatcher::limits() const { return impl_->limits; }

const MatchResult& InexactMatcher::match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params) {
  Impl& m = *impl_;
  m.S->load(scene);
  m.G->load(ref);
  m.P = &params;
  m.reset_table();
  m.budget = std::min<std::int64_t>(m.limits.max_states, std::max<std::int64_t>(params.max_states, 1));
  m.result = MatchResult{};
  m.run(m.result.stats);
  m.collect(m.result.stats);
  return m.result;
}

OwnedSolution to_owned(const Solution& s) {
  OwnedSolution o;
  o.rank = s.rank;
  o.state = s.state;
  o.path.assign(s.path.begin(), s.path.end());
  o.matches.assign(s.matches.begin(), s.matches.end());
  o.level = s.level;
  o.arcs_matched = s.arcs_matched;
  o.arcs_inserted = s.arcs_inserted;
  o.arcs_deleted = s.arcs_deleted;
  o.node_diss = s.node_diss;
  o.arc_attr_diss = s.arc_attr_diss;
  o.arc_struct_diss = s.arc_struct_diss;
  o.rotfit_error = s.rotfit_error;
  o.rotation = s.rotation;
  o.cost = s.cost;
  o.unexplained = s.unexplained;
  o.complete = s.complete;
  o.partial = s.partial;
  o.degenerate = s.degenerate;
  return o;
}

std::string state_id(std::string_view prefix, std::span<const int> path) {
  std::string out(prefix);
  char buf[16];
  for (int k : path) {
    const int n = std::snprintf(buf, sizeof buf, ".%d", k);
    out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

}  // namespace fs::host::match
