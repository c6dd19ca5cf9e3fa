// Best-first search of the inexact matcher (thesis ch. 7.2-7.6): the root, the expansion of the lowest-cost
// state with the candidate conditions of table 7.6 in order, the rotation fit of each new state (ch. 7.5,
// lazily, see inexact_impl.hpp), its cost (7.6) and the global stops (7.4).
#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "host/match/inexact_impl.hpp"

namespace fs::host::match {

using detail::pair_key;
using detail::rel_diss;

namespace {

void removed(MatchStats& st, Condition c) { ++st.removed[static_cast<std::size_t>(c)]; }

}  // namespace

// Per-match constants of the search: the parameters as thresholds and switches, and the node sets.
struct InexactMatcher::Impl::SearchSetup {
  double cos_omega = 0, cos_vis = 0, sin_degen = 0;
  bool vis_on = false, rigid_on = false, super_on = false, cost_on = false, rotsim_on = false;
  bool lazy_ok = false;  // the cost bounds need a cost non-decreasing in e_rotfit
  Vec3 obs = Vec3::Zero();
  std::int64_t t0 = 0;
  bool timed = false;
  NodeSet gs_super, all_r, all_s;
  NodeSet root_r;  // the root's reference candidates
};

// The expansion of one state (the parent of the candidates): its candidate sets and the conditions that apply
// to all of its candidates.
struct InexactMatcher::Impl::Expansion {
  int pi = 0;
  const State* par = nullptr;
  const FitData* pf = nullptr;
  bool root = false;
  NodeSet cand_r, scan_s, super_s;
  int n_cand_s = 0, n_super_s = 0;
  bool rigid_now = false, rigid_pair = false, vis_forward = false, vis_backward = false;
  int created = 0;
};

// One reference node r of an expansion: its normal, predicted scene normal and rigidity terms.
struct InexactMatcher::Impl::RefCandidate {
  int r = 0;
  std::size_t ur = 0;
  Vec3 nr, pred;
  bool pred_invisible = false;
  double cr0 = 0, sr0 = 0;
  int stop_s = -1;  // the scene node at which the search stopped (-1: none)
};

// A candidate pair (r, s), its state built in place in the pool entry n_states.
struct InexactMatcher::Impl::Candidate {
  const RefCandidate& rc;
  int s;
  std::size_t us, pk;
  const Vec3& ns;
  std::uint64_t h;
  State& c;
  FitData& cf;
  bool built = false;
  // Bounds of e_rotfit while the state is not fitted (lazy path): [rot_lo, rot_hi].
  double rot_lo = 0, rot_hi = 0;
  bool lazy = false;
};

void InexactMatcher::Impl::run(MatchStats& st) {
  const SearchSetup su = setup_search();
  start_search(st);
  while (!stop) {
    if (global_stop(su, st)) break;
    Expansion ex = begin_expansion(su, pop_fitted(), st);
    ex.cand_r.for_each([&](int r) { expand_reference(su, ex, r, st); });
    end_expansion(su, ex, st);
  }
  st.time_ms = static_cast<double>(clock->now_ns() - su.t0) * 1e-6;
}

InexactMatcher::Impl::SearchSetup InexactMatcher::Impl::setup_search() {
  const MatchParams& p = *P;
  const CompactGraph& gr = *G;
  const CompactGraph& gs = *S;
  SearchSetup su;
  su.cos_omega = std::cos(p.th_omega_deg * std::numbers::pi / 180.0);
  su.cos_vis = std::cos(p.th_visibility_deg * std::numbers::pi / 180.0);
  su.sin_degen = std::sin(p.degenerate_deg * std::numbers::pi / 180.0);
  const bool always_vis = p.th_visibility_deg >= 180.0, always_rigid = p.th_omega_deg >= 180.0;
  su.vis_on = p.on(Condition::kVisibility) && !always_vis;
  su.rigid_on = p.on(Condition::kRigidity) && !always_rigid;
  su.super_on = p.on(Condition::kSupernode);
  su.cost_on = p.on(Condition::kCostThreshold);
  su.rotsim_on = p.on(Condition::kRotfitSimilarity);
  su.lazy_ok = p.epsilon >= 0;
  su.obs = gs.observer;
  su.t0 = clock->now_ns();
  su.timed = std::isfinite(p.max_time_ms);
  fill_pair_tables();
  for (int i = 0; i < gs.n; ++i)
    if (gs.supernode[static_cast<std::size_t>(i)]) su.gs_super.set(i);
  for (int i = 0; i < gr.n; ++i) su.all_r.set(i);
  for (int i = 0; i < gs.n; ++i) su.all_s.set(i);
  su.root_r = su.all_r;
  if (scoped) {
    su.root_r = su.all_r & scope.first_refs;
    su.all_s = su.all_s & scope.scene;
  }
  return su;
}

void InexactMatcher::Impl::fill_pair_tables() {
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
    const double area_bound = area_with_shallow_folds(gr, r, p.th_area_fold_deg);
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
                          gs.area[us] > p.th_area_ratio * area_bound + p.th_area_slack_mm2;
    }
  }
}

// The root state (every pair is a candidate) in the queue.
void InexactMatcher::Impl::start_search(MatchStats& st) {
  solutions_found = 0;
  best_leaf = -1;
  pool[0] = State{};
  fitdata[0] = FitData{};
  n_states = 1;
  heap.clear();
  heap_push(0);
  st.stop = StopReason::kNoStates;
  fit_stats = {};
  stop = false;
}

// Global stops checked before each expansion (7.4): no open state left, time budget.
bool InexactMatcher::Impl::global_stop(const SearchSetup& su, MatchStats& st) const {
  if (heap.empty()) {
    st.stop = StopReason::kNoStates;
    return true;
  }
  if (su.timed && (st.states_expanded & 15) == 0 &&
      static_cast<double>(clock->now_ns() - su.t0) * 1e-6 >= P->max_time_ms) {
    st.stop = StopReason::kTimeBudget;
    return true;
  }
  return false;
}

// Pops the state with the lowest exact key: a lazily created state on top is fitted first and goes back when
// its exact key is no longer the lowest.
int InexactMatcher::Impl::pop_fitted() {
  int pi = heap.pop();
  while (!pool[static_cast<std::size_t>(pi)].fitted) {
    finish(pi);
    const State& x = pool[static_cast<std::size_t>(pi)];
    if (heap.empty() || !detail::heap_less(heap.front(), HeapItem{x.cost, x.level, pi})) break;
    heap_push(pi);
    pi = heap.pop();
  }
  return pi;
}

// The candidate sets of state pi (1 connectivity) and the conditions that apply to all of its candidates.
InexactMatcher::Impl::Expansion InexactMatcher::Impl::begin_expansion(const SearchSetup& su, int pi,
                                                                      MatchStats& st) {
  const MatchParams& p = *P;
  const CompactGraph& gr = *G;
  const CompactGraph& gs = *S;
  Expansion ex;
  ex.pi = pi;
  ex.par = &pool[static_cast<std::size_t>(pi)];
  ex.pf = &fitdata[static_cast<std::size_t>(pi)];
  ex.root = pi == 0;
  const State& par = *ex.par;
  load_map(pi, +1);

  NodeSet cand_s;
  if (ex.root) {
    ex.cand_r = su.root_r;
    cand_s = su.all_s;
  } else if (!p.on(Condition::kConnectivity)) {
    ex.cand_r = su.all_r.minus(par.cr);
    cand_s = su.all_s.minus(par.cs);
  } else {
    ex.cand_r = par.tr;
    cand_s = par.ts & su.all_s;
    const std::int64_t all = static_cast<std::int64_t>(gr.n - par.level) * (gs.n - par.level);
    st.removed[static_cast<std::size_t>(Condition::kConnectivity)] +=
        all - static_cast<std::int64_t>(ex.cand_r.count()) * cand_s.count();
  }
  const bool use_rot = par.level >= 2 && !par.degenerate;
  // 2 supernode: scene supernode candidates are counted in bulk, the loop visits the others.
  ex.scan_s = su.super_on ? cand_s.minus(su.gs_super) : cand_s;
  ex.super_s = su.super_on ? (cand_s & su.gs_super) : NodeSet{};
  ex.n_cand_s = cand_s.count();
  ex.n_super_s = ex.super_s.count();
  // 3 rigidity applies to every candidate of this parent, 4 visibility forward too.
  ex.rigid_now = su.rigid_on && use_rot;
  ex.rigid_pair = su.rigid_on && p.rigidity_pairs && par.level == 1;
  ex.vis_forward = su.vis_on && use_rot;
  ex.vis_backward = su.vis_on && !use_rot && par.level == 1;
  ex.created = 0;
  return ex;
}

// The candidates (r, s) of one reference node r.
void InexactMatcher::Impl::expand_reference(const SearchSetup& su, Expansion& ex, int r, MatchStats& st) {
  if (stop) return;
  const CompactGraph& gr = *G;
  const State& par = *ex.par;
  RefCandidate rc;
  rc.r = r;
  rc.ur = static_cast<std::size_t>(r);
  if (su.super_on && gr.supernode[rc.ur]) {
    st.candidates += ex.n_cand_s;
    st.removed[static_cast<std::size_t>(Condition::kSupernode)] += ex.n_cand_s;
    return;
  }
  rc.nr = gr.normal[rc.ur];
  rc.pred = ex.pf->R * rc.nr;  // predicted scene normal
  rc.pred_invisible = ex.vis_forward && rc.pred.dot(su.obs) < su.cos_vis;
  // |angle(r0, r) - angle(s0, s)| <= TH_omega  <=>  cos(difference) = c_r c_s + s_r s_s >= cos TH_omega
  // (both angles in [0, pi]), so no acos in the candidate loop.
  rc.cr0 = ex.rigid_pair ? std::clamp(gr.normal[static_cast<std::size_t>(par.r)].dot(rc.nr), -1.0, 1.0) : 0.0;
  rc.sr0 = std::sqrt(std::max(0.0, 1.0 - rc.cr0 * rc.cr0));
  ex.scan_s.for_each([&](int s) { try_pair(su, ex, rc, s, st); });
  // Scene supernode candidates of this r (all of them, or those before the stop).
  if (ex.n_super_s > 0) {
    int k = ex.n_super_s;
    if (rc.stop_s >= 0) {
      k = 0;
      ex.super_s.for_each([&](int s) { k += s < rc.stop_s ? 1 : 0; });
    }
    st.candidates += k;
    st.removed[static_cast<std::size_t>(Condition::kSupernode)] += k;
  }
}

// Candidate (r, s): the conditions of table 7.6 in order; a candidate that passes all becomes a new state.
void InexactMatcher::Impl::try_pair(const SearchSetup& su, Expansion& ex, RefCandidate& rc, int s,
                                    MatchStats& st) {
  if (stop) return;
  const MatchParams& p = *P;
  const CompactGraph& gs = *S;
  const State& par = *ex.par;
  ++st.candidates;
  const auto us = static_cast<std::size_t>(s);
  const Vec3& ns = gs.normal[us];
  // 3 rigidity (forward check from parents of level >= 2)
  if (ex.rigid_now && rc.pred.dot(ns) < su.cos_omega) return removed(st, Condition::kRigidity);
  if (ex.rigid_pair) {
    const double cs0 = std::clamp(gs.normal[static_cast<std::size_t>(par.s)].dot(ns), -1.0, 1.0);
    if (rc.cr0 * cs0 + rc.sr0 * std::sqrt(std::max(0.0, 1.0 - cs0 * cs0)) < su.cos_omega)
      return removed(st, Condition::kRigidity);
  }
  // 4 visibility: forward from level >= 2 parents; backward check of new level-2 states
  if (rc.pred_invisible) return removed(st, Condition::kVisibility);
  const std::size_t pk = rc.ur * kMaxNodes + us;
  // The match-set hash, and its table slot fetched early (probed by condition 5, written on creation).
  const std::uint64_t h = par.hash ^ pair_key(rc.r, s);
  table.prefetch(h);
  Candidate cd{rc,
               s,
               us,
               pk,
               ns,
               h,
               pool[static_cast<std::size_t>(n_states)],  // built in place; committed by ++n_states
               fitdata[static_cast<std::size_t>(n_states)]};
  State& c = cd.c;
  c.level = par.level + 1;
  if (ex.vis_backward && !backward_visible(su, ex, cd, st)) return;
  // 5 new match (no duplicate match sets)
  NodeSet cr = par.cr, cs = par.cs;
  cr.set(rc.r);
  cs.set(s);
  if (p.on(Condition::kNewMatch) && par.level >= 1 && exists(h, cr, cs, rc.r, s))
    return removed(st, Condition::kNewMatch);
  // 6 node degree
  if (p.on(Condition::kNodeDegree) && pair_degree_fail[pk]) return removed(st, Condition::kNodeDegree);
  // 9.1 node similarity, one-sided area part (cheap, decided per pair)
  if (p.on(Condition::kNodeSimilarity) && pair_area_fail[pk]) return removed(st, Condition::kNodeSimilarity);
  int dam = 0, dai = 0;
  double dborder = 0;
  count_core_arcs(ex, cd, dam, dai, dborder);
  const int dad = (gs.adj[us] & par.cs).count() - dam;
  // 7 neighbour match
  if (p.on(Condition::kNeighborMatch) && par.level >= 1 && dam == 0)
    return removed(st, Condition::kNeighborMatch);
  c.am = par.am + dam;
  c.ai = par.ai + dai;
  c.ad = par.ad + dad;
  const double darea = pair_darea[pk];
  c.d_area = par.d_area + darea;
  c.d_border = par.d_border + dborder;
  if (!passes_thresholds(su, ex, cd, darea, dborder, st)) return;
  // create the state
  if (n_states > budget) {
    st.stop = StopReason::kStateBudget;
    stop = true;
    rc.stop_s = s;
    return;
  }
  commit_state(ex, cd, cr, cs, st);
}

// B and the flags of the candidate; the fit separately (fit_now).
void InexactMatcher::Impl::build(const SearchSetup& su, const Expansion& ex, Candidate& cd) const {
  const State& par = *ex.par;
  State& c = cd.c;
  c.sum_gamma = par.sum_gamma;
  cd.cf.B = ex.pf->B;
  const double g = pair_gamma[cd.pk];
  add_pair(cd.cf.B, cd.rc.nr, cd.ns, g);
  c.sum_gamma += g;
  c.first_r = ex.root ? cd.rc.r : par.first_r;
  c.degenerate =
      ex.root || (par.degenerate &&
                  cd.rc.nr.cross(G->normal[static_cast<std::size_t>(c.first_r)]).norm() < su.sin_degen);
  cd.built = true;
}

void InexactMatcher::Impl::fit_now(const Expansion& ex, Candidate& cd) {
  if (ex.root) {
    // One pair: zero error, a one-parameter family of rotations; take the smallest one (no solve).
    const Eigen::Quaterniond q1 = Eigen::Quaterniond::FromTwoVectors(cd.rc.nr, cd.ns);
    cd.cf.R = q1.toRotationMatrix();
    cd.cf.q = Eigen::Vector4d(q1.x(), q1.y(), q1.z(), q1.w());
    cd.c.lambda = 0.0;
    cd.c.rotfit = 0.0;
  } else {
    fit(n_states, ex.pi);
  }
}

void InexactMatcher::Impl::lazy_bounds(Candidate& cd, double lam_lo, double lam_hi) const {
  const double tol = 1e-9 * cd.cf.B.trace();
  cd.rot_lo = rotfit_of(cd.c, std::max(0.0, lam_lo - tol));
  cd.rot_hi = rotfit_of(cd.c, lam_hi + tol);
  cd.lazy = true;
}

// Weyl: lambda_min(B) >= the parent's; the Rayleigh quotient at the parent's quaternion bounds it above.
void InexactMatcher::Impl::lazy_from_parent(const Expansion& ex, Candidate& cd) const {
  lazy_bounds(cd, ex.par->lambda, ex.pf->q.dot(cd.cf.B * ex.pf->q));
}

// 4 visibility, backward check of a new level-2 state: both matched normals, rotated by the state's fit, face
// the sensor. False (and counted) when the candidate fails.
bool InexactMatcher::Impl::backward_visible(const SearchSetup& su, const Expansion& ex, Candidate& cd,
                                            MatchStats& st) {
  const State& par = *ex.par;
  const CompactGraph& gr = *G;
  const CompactGraph& gs = *S;
  State& c = cd.c;
  build(su, ex, cd);
  if (c.degenerate && su.lazy_ok) {
    lazy_from_parent(ex, cd);  // no visibility check for a degenerate pair: no fit needed yet
    return true;
  }
  const std::size_t pk1 = static_cast<std::size_t>(par.r) * kMaxNodes + static_cast<std::size_t>(par.s);
  const Vec3& n1 = gr.normal[static_cast<std::size_t>(par.r)];
  const TwoPairFit tp = unit_normals && su.lazy_ok && !c.degenerate
                            ? two_pair_fit(n1, gs.normal[static_cast<std::size_t>(par.s)], pair_gamma[pk1],
                                           cd.rc.nr, cd.ns, pair_gamma[cd.pk])
                            : TwoPairFit{};
  // The closed form decides when both rotated normals are clearly (1e-7) on one side of the cone.
  const double d1 = tp.ok ? tp.Rr1.dot(su.obs) : 0.0, d2 = tp.ok ? tp.Rr2.dot(su.obs) : 0.0;
  if (tp.ok && std::abs(d1 - su.cos_vis) > 1e-7 && std::abs(d2 - su.cos_vis) > 1e-7) {
    if (d2 < su.cos_vis || d1 < su.cos_vis) {
      removed(st, Condition::kVisibility);
      return false;
    }
    lazy_bounds(cd, tp.lambda, tp.lambda);
  } else {
    fit_now(ex, cd);
    if (!c.degenerate &&
        ((cd.cf.R * cd.rc.nr).dot(su.obs) < su.cos_vis || (cd.cf.R * n1).dot(su.obs) < su.cos_vis)) {
      removed(st, Condition::kVisibility);
      return false;
    }
  }
  return true;
}

// Arcs from the candidate to the core: matched (dam, with their border dissimilarity) and inserted (dai,
// reference only).
void InexactMatcher::Impl::count_core_arcs(const Expansion& ex, const Candidate& cd, int& dam, int& dai,
                                           double& dborder) const {
  const CompactGraph& gr = *G;
  const CompactGraph& gs = *S;
  const std::size_t ur = cd.rc.ur, us = cd.us;
  const NodeSet nrc = gr.adj[ur] & ex.par->cr;
  nrc.for_each([&](int rc) {
    const int sc = r2s[static_cast<std::size_t>(rc)];
    if (gs.adj[us].test(sc)) {
      ++dam;
      dborder +=
          rel_diss(gr.border[ur][static_cast<std::size_t>(rc)], gs.border[us][static_cast<std::size_t>(sc)]);
    } else {
      ++dai;
    }
  });
}

// 8 cost threshold, 9 node / arc / rotation fit similarity, 10 search depth (the rotation fit made here, or
// bounded for a lazy state). False (and counted) when the candidate fails.
bool InexactMatcher::Impl::passes_thresholds(const SearchSetup& su, const Expansion& ex, Candidate& cd,
                                             double darea, double dborder, MatchStats& st) {
  const MatchParams& p = *P;
  const State& par = *ex.par;
  State& c = cd.c;
  auto fail = [&](Condition cond) {
    removed(st, cond);
    return false;
  };
  if (!cd.built) {
    // 8 cost threshold, early: the cost without the rotation fit term (epsilon e_rotfit / level >= 0) is a
    // lower bound, so a candidate failing it fails condition 8 anyway; skip its eigen solve.
    if (su.cost_on && p.epsilon >= 0) {
      if (cost_with(c, 0.0) - par.cost > p.th_cost) return fail(Condition::kCostThreshold);
    }
    build(su, ex, cd);
    if (!ex.root && su.lazy_ok)
      lazy_from_parent(ex, cd);
    else
      fit_now(ex, cd);
  }
  // 8 cost threshold
  if (su.cost_on) {
    if (cd.lazy) {
      if (cost_with(c, cd.rot_lo) - par.cost > p.th_cost) return fail(Condition::kCostThreshold);
      if (cost_with(c, cd.rot_hi) - par.cost > p.th_cost) {  // undecided by the bounds: fit now
        fit_now(ex, cd);
        cd.lazy = false;
      }
    }
    if (!cd.lazy && cost_of(c) - par.cost > p.th_cost) return fail(Condition::kCostThreshold);
  }
  // 9.1 node, 9.2 arc attribute, 9.3 rotation fit similarity
  if (p.on(Condition::kNodeSimilarity) && darea > p.th_node) return fail(Condition::kNodeSimilarity);
  if (p.on(Condition::kArcSimilarity) && dborder > p.th_arcatt) return fail(Condition::kArcSimilarity);
  if (su.rotsim_on) {
    if (cd.lazy) {
      if (cd.rot_lo - par.rotfit > p.th_rotfit) return fail(Condition::kRotfitSimilarity);
      if (cd.rot_hi - par.rotfit > p.th_rotfit) {
        fit_now(ex, cd);
        cd.lazy = false;
      }
    }
    if (!cd.lazy && c.rotfit - par.rotfit > p.th_rotfit) return fail(Condition::kRotfitSimilarity);
  }
  // 10 search depth
  if (p.on(Condition::kSearchDepth) && c.level > p.th_maxlevel) return fail(Condition::kSearchDepth);
  return true;
}

// The candidate becomes state n_states: its key (exact, or the cost lower bound of a lazy state), sets and
// tree links; into the duplicate table and the queue.
void InexactMatcher::Impl::commit_state(Expansion& ex, Candidate& cd, const NodeSet& cr, const NodeSet& cs,
                                        MatchStats& st) {
  const State& par = *ex.par;
  State& c = cd.c;
  if (cd.lazy) {
    c.rotfit = cd.rot_lo;
    c.cost = cost_with(c, cd.rot_lo);  // a lower bound of the exact cost: the heap key until fitted
    c.fitted = false;
  } else {
    c.cost = cost_of(c);
    c.fitted = true;
  }
  c.cr = cr;
  c.cs = cs;
  NodeSet tr = par.tr | G->adj[cd.rc.ur];
  NodeSet ts = par.ts | S->adj[cd.us];
  c.tr = tr.minus(cr);
  c.ts = ts.minus(cs);
  c.hash = cd.h;
  c.parent = ex.pi;
  c.child_index = ++ex.created;
  c.r = cd.rc.r;
  c.s = cd.s;
  c.children = 0;
  c.expanded = false;
  const int ci = n_states++;
  table.insert(cd.h, ci, pool);
  heap_push(ci);
  ++st.states_created;
}

// After the expansion of a state: its children counted, a leaf recorded as a solution (7.7), the stops on
// "solutions found" and on the state budget.
void InexactMatcher::Impl::end_expansion(const SearchSetup& su, const Expansion& ex, MatchStats& st) {
  const MatchParams& p = *P;
  const int pi = ex.pi;
  const int created = ex.created;
  load_map(pi, -1);
  State& pm = pool[static_cast<std::size_t>(pi)];
  pm.children = created;
  if (stop) {
    if (created == 0) heap_push(pi);  // not expanded: stays an incomplete solution candidate
    return;
  }
  pm.expanded = true;
  ++st.states_expanded;
  if (created == 0 && !ex.root && pm.level >= p.th_minlevel) {
    if (best_leaf < 0 || pm.cost < pool[static_cast<std::size_t>(best_leaf)].cost) {
      best_leaf = pi;
      st.states_to_best = st.states_created;
      st.time_to_best_ms = static_cast<double>(clock->now_ns() - su.t0) * 1e-6;
    }
    if (++solutions_found >= p.max_solutions) {
      st.stop = StopReason::kSolutionsFound;
      stop = true;
    }
  }
}

void InexactMatcher::Impl::fit(int ci, int pi) {
  State& c = pool[static_cast<std::size_t>(ci)];
  FitData& cf = fitdata[static_cast<std::size_t>(ci)];
  const RotationFit f = solve_rotation_fast(cf.B, pool[static_cast<std::size_t>(pi)].lambda,
                                            fitdata[static_cast<std::size_t>(pi)].q, &fit_stats);
  cf.R = f.R;
  cf.q = f.q;
  c.lambda = f.lambda_min;
  c.rotfit = rotfit_of(c, f.lambda_min);
}

void InexactMatcher::Impl::finish(int id) {
  State& c = pool[static_cast<std::size_t>(id)];
  if (c.fitted) return;
  fit(id, c.parent);
  c.cost = cost_of(c);
  c.fitted = true;
}

// True when a created state has the same match set as (parent's matches + (r, s)); r2s holds the parent's
// map.
bool InexactMatcher::Impl::same_matches(const State& e, int r, int s) const {
  for (int k = static_cast<int>(&e - pool.data()); k > 0; k = pool[static_cast<std::size_t>(k)].parent) {
    const State& x = pool[static_cast<std::size_t>(k)];
    if (!(x.r == r && x.s == s) && r2s[static_cast<std::size_t>(x.r)] != x.s) return false;
  }
  return true;
}

bool InexactMatcher::Impl::exists(std::uint64_t h, const NodeSet& cr, const NodeSet& cs, int r, int s) const {
  return table.contains(h, [&](int id) {
    const State& e = pool[static_cast<std::size_t>(id)];
    return e.cr == cr && e.cs == cs && same_matches(e, r, s);
  });
}

// r2s / s2r = the match map of state st (value_sign > 0), or cleared again (value_sign < 0).
void InexactMatcher::Impl::load_map(int st, int value_sign) {
  for (int k = st; k > 0; k = pool[static_cast<std::size_t>(k)].parent) {
    const State& x = pool[static_cast<std::size_t>(k)];
    r2s[static_cast<std::size_t>(x.r)] = value_sign > 0 ? x.s : -1;
    s2r[static_cast<std::size_t>(x.s)] = value_sign > 0 ? x.r : -1;
  }
}

}  // namespace fs::host::match
