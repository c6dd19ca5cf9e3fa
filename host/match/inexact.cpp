#include "host/match/inexact.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
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
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};

std::uint64_t pair_key(int r, int s) {
  // splitmix64 of the pair index: order-independent match-set hash = XOR of pair keys (Zobrist hashing).
  std::uint64_t z = static_cast<std::uint64_t>(r) * kMaxNodes + static_cast<std::uint64_t>(s) + 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double rel_diss(double a, double b) {
  const double m = std::max(a, b);
  return m > 0 ? std::abs(a - b) / m : 0.0;
}

struct State {
  NodeSet cr, cs, tr, ts;          // core / terminal sets (reference, scene); rest = complement
  Mat4 B = Mat4::Zero();           // accumulated sum gamma A (7.5.8)
  Mat3 R = Mat3::Identity();       // best fitting rotation
  Eigen::Vector4d q{0, 0, 0, 1};   // its quaternion (x y z w): warm start of the children's fits
  double lambda = 0;               // smallest eigenvalue of B: lower bound of the children's
  double sum_gamma = 0, d_area = 0, d_border = 0, rotfit = 0, cost = 0;
  std::uint64_t hash = 0;
  int parent = -1, child_index = 0, level = 0, r = -1, s = -1;
  int am = 0, ai = 0, ad = 0, children = 0, first_r = -1;
  bool expanded = false, degenerate = true;
};

}  // namespace

std::string_view stop_name(StopReason r) {
  switch (r) {
    case StopReason::kNoStates: return "no states left";
    case StopReason::kSolutionsFound: return "solutions found";
    case StopReason::kStateBudget: return "state budget";
    case StopReason::kTimeBudget: return "time budget";
  }
  return "?";
}

const MatchClock& steady_match_clock() {
  static const SteadyClock clock;
  return clock;
}

struct InexactMatcher::Impl {
  MatcherLimits limits;
  const MatchClock* clock = &steady_match_clock();
  std::unique_ptr<CompactGraph> S = std::make_unique<CompactGraph>();   // scene
  std::unique_ptr<CompactGraph> G = std::make_unique<CompactGraph>();   // reference
  std::vector<State> pool;
  std::vector<int> heap;             // open states, min cost first
  struct Slot {
    std::uint32_t gen = 0;
    int state = -1;
  };
  std::vector<Slot> table;           // duplicate test (new match condition)
  std::uint64_t mask = 0;
  std::uint32_t gen = 0;
  std::vector<int> leaves;           // solution candidates
  std::vector<Solution> solutions;
  std::vector<NodeMatch> match_buf;
  std::vector<int> path_buf;
  std::array<int, kMaxNodes> r2s{}, s2r{}, mark{};
  MatchResult result;
  const MatchParams* P = nullptr;
  int n_states = 0;                  // used pool entries (root included)
  std::int64_t budget = 0;

  explicit Impl(const MatcherLimits& l) : limits(l) {
    if (limits.max_states < 1) limits.max_states = 1;
    if (limits.max_reported < 1) limits.max_reported = 1;
    const auto cap = static_cast<std::size_t>(limits.max_states) + 1;
    pool.resize(cap);
    heap.reserve(cap);
    std::size_t t = 16;
    while (t < 2 * cap) t <<= 1;
    table.resize(t);
    mask = t - 1;
    leaves.reserve(cap);
    solutions.resize(static_cast<std::size_t>(limits.max_reported));
    match_buf.resize(static_cast<std::size_t>(limits.max_reported) * kMaxNodes);
    path_buf.resize(static_cast<std::size_t>(limits.max_reported) * kMaxNodes);
    r2s.fill(-1);
    s2r.fill(-1);
    mark.fill(-1);
  }

  // ---- priority queue (binary heap over pool indices; ties: lower state number first) ----
  // Lowest cost first; among equal costs the deeper state (favours well developed paths, 7.2.4), then the
  // older one.
  bool less(int a, int b) const {
    const State& x = pool[static_cast<std::size_t>(a)];
    const State& y = pool[static_cast<std::size_t>(b)];
    if (x.cost != y.cost) return x.cost < y.cost;
    if (x.level != y.level) return x.level > y.level;
    return a < b;
  }
  void heap_push(int x) {
    heap.push_back(x);   // capacity reserved for every pool entry: never reallocates
    std::size_t i = heap.size() - 1;
    while (i > 0) {
      const std::size_t p = (i - 1) / 2;
      if (!less(heap[i], heap[p])) break;
      std::swap(heap[i], heap[p]);
      i = p;
    }
  }
  int heap_pop() {
    const int top = heap.front();
    heap.front() = heap.back();
    heap.pop_back();
    std::size_t i = 0;
    const std::size_t n = heap.size();
    for (;;) {
      const std::size_t l = 2 * i + 1, r = l + 1;
      std::size_t m = i;
      if (l < n && less(heap[l], heap[m])) m = l;
      if (r < n && less(heap[r], heap[m])) m = r;
      if (m == i) break;
      std::swap(heap[i], heap[m]);
      i = m;
    }
    return top;
  }

  // ---- duplicate test ----
  // True when a created state has the same match set as (parent's matches + (r, s)); r2s holds the parent's map.
  bool same_matches(const State& e, int r, int s) const {
    for (int k = static_cast<int>(&e - pool.data()); k > 0; k = pool[static_cast<std::size_t>(k)].parent) {
      const State& x = pool[static_cast<std::size_t>(k)];
      if (!(x.r == r && x.s == s) && r2s[static_cast<std::size_t>(x.r)] != x.s) return false;
    }
    return true;
  }
  bool exists(std::uint64_t h, const NodeSet& cr, const NodeSet& cs, int r, int s) const {
    for (std::uint64_t i = h & mask;; i = (i + 1) & mask) {
      const Slot& sl = table[i];
      if (sl.gen != gen) return false;
      const State& e = pool[static_cast<std::size_t>(sl.state)];
      if (e.hash == h && e.cr == cr && e.cs == cs && same_matches(e, r, s)) return true;
    }
  }
  void insert(std::uint64_t h, int state) {
    std::uint64_t i = h & mask;
    while (table[i].gen == gen) i = (i + 1) & mask;
    table[i] = Slot{gen, state};
  }

  void load_map(int st, int value_sign) {
    for (int k = st; k > 0; k = pool[static_cast<std::size_t>(k)].parent) {
      const State& x = pool[static_cast<std::size_t>(k)];
      r2s[static_cast<std::size_t>(x.r)] = value_sign > 0 ? x.s : -1;
      s2r[static_cast<std::size_t>(x.s)] = value_sign > 0 ? x.r : -1;
    }
  }

  double cost_of(const State& c) const {
    double cost = 0;
    if (c.level > 0) cost += (P->alpha * c.d_area + P->epsilon * c.rotfit) / c.level;
    const int arcs = c.am + c.ai + c.ad;
    if (arcs > 0) cost += (P->beta * c.d_border + P->gamma * c.ai + P->delta * c.ad) / arcs;
    return cost;
  }

  FastFitStats fit_stats;
  void fit(State& c, const State& par) {
    const RotationFit f = solve_rotation_fast(c.B, par.lambda, par.q, &fit_stats);
    c.R = f.R;
    c.q = f.q;
    c.lambda = f.lambda_min;
    c.rotfit = c.sum_gamma > 0 ? f.lambda_min / (2.0 * c.sum_gamma) : 0.0;
  }

  void run(MatchStats& st) {
    const MatchParams& p = *P;
    const CompactGraph& gr = *G;
    const CompactGraph& gs = *S;
    const double cos_omega = std::cos(p.th_omega_deg * std::numbers::pi / 180.0);
    const double cos_vis = std::cos(p.th_visibility_deg * std::numbers::pi / 180.0);
    const double sin_degen = std::sin(p.degenerate_deg * std::numbers::pi / 180.0);
    const bool always_vis = p.th_visibility_deg >= 180.0, always_rigid = p.th_omega_deg >= 180.0;
    const Vec3 obs = gs.observer;
    const std::int64_t t0 = clock->now_ns();
    const bool timed = std::isfinite(p.max_time_ms);
    std::int64_t solutions_found = 0;
    int best_leaf = -1;

    const NodeSet gs_super = [&] {
      NodeSet x;
      for (int i = 0; i < gs.n; ++i)
        if (gs.supernode[static_cast<std::size_t>(i)]) x.set(i);
      return x;
    }();
    NodeSet all_r, all_s;
    for (int i = 0; i < gr.n; ++i) all_r.set(i);
    for (int i = 0; i < gs.n; ++i) all_s.set(i);

    pool[0] = State{};
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
      const int pi = heap_pop();
      const State& par = pool[static_cast<std::size_t>(pi)];
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
      int created = 0;
      auto removed = [&](Condition c) { ++st.removed[static_cast<std::size_t>(c)]; };

      cand_r.for_each([&](int r) {
        if (stop) return;
        const Vec3 nr = gr.normal[static_cast<std::size_t>(r)];
        const Vec3 pred = par.R * nr;   // predicted scene normal
        cand_s.for_each([&](int s) {
          if (stop) return;
          ++st.candidates;
          // 2 supernode
          if (p.on(Condition::kSupernode) && (gr.supernode[static_cast<std::size_t>(r)] || gs.supernode[static_cast<std::size_t>(s)]))
            return removed(Condition::kSupernode);
          const Vec3& ns = gs.normal[static_cast<std::size_t>(s)];
          // 3 rigidity (forward check from parents of level >= 2)
          if (p.on(Condition::kRigidity) && use_rot && !always_rigid && pred.dot(ns) < cos_omega)
            return removed(Condition::kRigidity);
          State c;
          bool fitted = false;
          auto build = [&] {
            c.level = par.level + 1;
            c.sum_gamma = par.sum_gamma;
            c.B = par.B;
            const double g = std::sqrt(gs.area[static_cast<std::size_t>(s)] * gr.area[static_cast<std::size_t>(r)]);
            add_pair(c.B, nr, ns, g);
            c.sum_gamma += g;
            if (root) {
              // One pair: zero error, a one-parameter family of rotations; take the smallest one (no solve).
              const Eigen::Quaterniond q1 = Eigen::Quaterniond::FromTwoVectors(nr, ns);
              c.R = q1.toRotationMatrix();
              c.q = Eigen::Vector4d(q1.x(), q1.y(), q1.z(), q1.w());
              c.lambda = 0.0;
              c.rotfit = 0.0;
            } else {
              fit(c, par);
            }
            c.first_r = root ? r : par.first_r;
            c.degenerate = root || (par.degenerate && nr.cross(gr.normal[static_cast<std::size_t>(c.first_r)]).norm() < sin_degen);
            fitted = true;
          };
          // 4 visibility: forward from level >= 2 parents; backward check of new level-2 states
          if (p.on(Condition::kVisibility) && !always_vis) {
            if (use_rot) {
              if (pred.dot(obs) < cos_vis) return removed(Condition::kVisibility);
            } else if (par.level == 1) {
              build();
              if (!c.degenerate &&
                  ((c.R * nr).dot(obs) < cos_vis || (c.R * gr.normal[static_cast<std::size_t>(par.r)]).dot(obs) < cos_vis))
                return removed(Condition::kVisibility);
            }
          }
          // 5 new match (no duplicate match sets)
          const std::uint64_t h = par.hash ^ pair_key(r, s);
          NodeSet cr = par.cr, cs = par.cs;
          cr.set(r);
          cs.set(s);
          if (p.on(Condition::kNewMatch) && par.level >= 1 && exists(h, cr, cs, r, s))
            return removed(Condition::kNewMatch);
          // 6 node degree
          // (7.3.6: only faces not adjacent to invisible parts have comparable degrees; a scene face bordering
          // the supernode may have lost neighbours, so for it only a surplus of scene neighbours counts.)
          if (p.on(Condition::kNodeDegree)) {
            const int dr = gr.degree[static_cast<std::size_t>(r)], ds = gs.degree[static_cast<std::size_t>(s)];
            const bool open = (gs.adj[static_cast<std::size_t>(s)] & gs_super).any();
            if (open ? (ds - 1 - dr > p.th_nodedegree) : (std::abs(dr - ds) > p.th_nodedegree))
              return removed(Condition::kNodeDegree);
          }
          // arcs to the core: matched / inserted (reference only) / deleted (scene only)
          int dam = 0, dai = 0;
          double dborder = 0;
          const NodeSet nrc = gr.adj[static_cast<std::size_t>(r)] & par.cr;
          nrc.for_each([&](int rc) {
            const int sc = r2s[static_cast<std::size_t>(rc)];
            if (gs.adj[static_cast<std::size_t>(s)].test(sc)) {
              ++dam;
              dborder += rel_diss(gr.border[static_cast<std::size_t>(r)][static_cast<std::size_t>(rc)],
                                  gs.border[static_cast<std::size_t>(s)][static_cast<std::size_t>(sc)]);
            } else {
              ++dai;
            }
          });
          const int dad = (gs.adj[static_cast<std::size_t>(s)] & par.cs).count() - dam;
          // 7 neighbour match
          if (p.on(Condition::kNeighborMatch) && par.level >= 1 && dam == 0) return removed(Condition::kNeighborMatch);
          c.am = par.am + dam;
          c.ai = par.ai + dai;
          c.ad = par.ad + dad;
          const double darea = rel_diss(gr.area[static_cast<std::size_t>(r)], gs.area[static_cast<std::size_t>(s)]);
          c.d_area = par.d_area + darea;
          c.d_border = par.d_border + dborder;
          if (!fitted) {
            // 8 cost threshold, early: the cost without the rotation fit term (epsilon e_rotfit / level >= 0) is
            // a lower bound, so a candidate failing it fails condition 8 anyway; skip its eigen solve.
            if (p.on(Condition::kCostThreshold) && p.epsilon >= 0) {
              c.level = par.level + 1;
              c.rotfit = 0.0;
              if (cost_of(c) - par.cost > p.th_cost) return removed(Condition::kCostThreshold);
            }
            build();
          }
          c.cost = cost_of(c);
          // 8 cost threshold
          if (p.on(Condition::kCostThreshold) && c.cost - par.cost > p.th_cost) return removed(Condition::kCostThreshold);
          // 9.1 node, 9.2 arc attribute, 9.3 rotation fit similarity
          if (p.on(Condition::kNodeSimilarity) && darea > p.th_node) return removed(Condition::kNodeSimilarity);
          if (p.on(Condition::kArcSimilarity) && dborder > p.th_arcatt) return removed(Condition::kArcSimilarity);
          if (p.on(Condition::kRotfitSimilarity) && c.rotfit - par.rotfit > p.th_rotfit)
            return removed(Condition::kRotfitSimilarity);
          // 10 search depth
          if (p.on(Condition::kSearchDepth) && c.level > p.th_maxlevel) return removed(Condition::kSearchDepth);
          // create the state
          if (n_states > budget) {
            st.stop = StopReason::kStateBudget;
            stop = true;
            return;
          }
          c.cr = cr;
          c.cs = cs;
          NodeSet tr = par.tr | gr.adj[static_cast<std::size_t>(r)];
          NodeSet ts = par.ts | gs.adj[static_cast<std::size_t>(s)];
          c.tr = tr.minus(cr);
          c.ts = ts.minus(cs);
          c.hash = h;
          c.parent = pi;
          c.child_index = ++created;
          c.r = r;
          c.s = s;
          const int ci = n_states++;
          pool[static_cast<std::size_t>(ci)] = c;
          insert(h, ci);
          heap_push(ci);
          ++st.states_created;
        });
      });
      load_map(pi, -1);
      State& pm = pool[static_cast<std::size_t>(pi)];
      pm.children = created;
      if (stop) {
        if (created == 0) heap_push(pi);   // not expanded: stays an incomplete solution candidate
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
    st.fits_fast = fit_stats.fast;
    st.fits_fallback = fit_stats.fallback;
  }

  // Subset condition: is a's match set a proper subset of b's?
  bool subset(const State& a, const State& b) {
    if (a.level >= b.level || !a.cr.subset_of(b.cr) || !a.cs.subset_of(b.cs)) return false;
    const int bi = static_cast<int>(&b - pool.data());
    for (int k = bi; k > 0; k = pool[static_cast<std::size_t>(k)].parent)
      mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] = pool[static_cast<std::size_t>(k)].s;
    bool ok = true;
    for (int k = static_cast<int>(&a - pool.data()); k > 0 && ok; k = pool[static_cast<std::size_t>(k)].parent)
      ok = mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] == pool[static_cast<std::size_t>(k)].s;
    for (int k = bi; k > 0; k = pool[static_cast<std::size_t>(k)].parent)
      mark[static_cast<std::size_t>(pool[static_cast<std::size_t>(k)].r)] = -1;
    return ok;
  }

  void collect(MatchStats& st) {
    const MatchParams& p = *P;
    leaves.clear();
    for (int i = 1; i < n_states; ++i) {
      const State& x = pool[static_cast<std::size_t>(i)];
      const bool leaf = x.expanded && x.children == 0 && x.level >= p.th_minlevel;
      const bool incomplete = !x.expanded && st.stop != StopReason::kNoStates &&
                              (x.level >= p.th_minlevel || p.keep_partial);
      if (leaf || incomplete) leaves.push_back(i);
    }
    st.leaf_solutions = static_cast<std::int64_t>(leaves.size());
    // Subset condition (7.7.2, 7.7.3): a traditional solution is dropped when its match set is a subset of
    // another traditional solution's; an incomplete one when it is a subset of a traditional solution's.
    // Traditional (complete) solutions first, by level descending, then the incomplete ones.
    std::sort(leaves.begin(), leaves.end(), [&](int a, int b) {
      const State& x = pool[static_cast<std::size_t>(a)];
      const State& y = pool[static_cast<std::size_t>(b)];
      if (x.expanded != y.expanded) return x.expanded;
      if (x.level != y.level) return x.level > y.level;
      return a < b;
    });
    std::size_t n_complete = 0;
    while (n_complete < leaves.size() && pool[static_cast<std::size_t>(leaves[n_complete])].expanded) ++n_complete;
    std::size_t kept = 0, kept_complete = 0;
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const State& a = pool[static_cast<std::size_t>(leaves[i])];
      bool sub = false;
      // Compare with the complete solutions kept so far (all of higher or equal level for complete a).
      for (std::size_t k = 0; k < kept_complete && !sub; ++k) {
        const State& b = pool[static_cast<std::size_t>(leaves[k])];
        if (b.level <= a.level) {
          if (i < n_complete) break;   // sorted: no larger complete solutions follow
          continue;
        }
        sub = subset(a, b);
      }
      if (sub) {
        ++st.subset_removed;
        continue;
      }
      leaves[kept++] = leaves[i];
      if (i < n_complete) kept_complete = kept;
    }
    leaves.resize(kept);   // shrinking: no allocation
    std::sort(leaves.begin(), leaves.end(), [&](int a, int b) {
      const double ca = pool[static_cast<std::size_t>(a)].cost, cb = pool[static_cast<std::size_t>(b)].cost;
      return ca < cb || (ca == cb && a < b);
    });
    st.solutions = static_cast<std::int64_t>(kept);
    const std::size_t n = std::min(kept, solutions.size());
    for (std::size_t k = 0; k < n; ++k) {
      const State& x = pool[static_cast<std::size_t>(leaves[k])];
      Solution& sol = solutions[k];
      sol.rank = static_cast<int>(k) + 1;
      sol.state = leaves[k];
      sol.level = x.level;
      NodeMatch* m = &match_buf[k * kMaxNodes];
      int* path = &path_buf[k * kMaxNodes];
      int j = x.level;
      for (int q = leaves[k]; q > 0; q = pool[static_cast<std::size_t>(q)].parent) {
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
      sol.rotation = x.R;
      sol.cost = x.cost;
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
  }
};

InexactMatcher::InexactMatcher(const MatcherLimits& limits) : impl_(std::make_unique<Impl>(limits)) {}
InexactMatcher::~InexactMatcher() = default;
void InexactMatcher::set_clock(const MatchClock* clock) { impl_->clock = clock ? clock : &steady_match_clock(); }
const MatcherLimits& InexactMatcher::limits() const { return impl_->limits; }

const MatchResult& InexactMatcher::match(const Pfrg& scene, const Pfrg& ref, const MatchParams& params) {
  Impl& m = *impl_;
  m.S->load(scene);
  m.G->load(ref);
  m.P = &params;
  if (++m.gen == 0) {   // wrapped: clear the table once every 2^32 matches
    for (auto& s : m.table) s = Impl::Slot{};
    m.gen = 1;
  }
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
