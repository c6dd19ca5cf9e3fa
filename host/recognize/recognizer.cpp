#include "host/recognize/recognizer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include "host/recognize/hypotheses.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/scene_prep.hpp"
#include "host/recognize/worker_pool.hpp"

namespace fs::host::rec {

namespace {

using Clock = std::chrono::steady_clock;
constexpr std::size_t kMaxMatches = 128;  // face matches of one hypothesis (matcher graphs hold <= 128 nodes)
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// One reference's kept solutions (buffers reused across scans).
struct SolutionSlot {
  std::vector<int> path;
  std::vector<match::NodeMatch> matches;
  Mat3 rotation = Mat3::Identity();
  double cost = 0, rotfit = 0;
  int level = 0, rank = 0;
  bool degenerate = false;
};

struct ModelSlots {
  std::vector<SolutionSlot> slots;
  int count = 0;
  std::int64_t states = 0;
};

}  // namespace

struct Recognizer::Impl {
  // Scene node ids: regions 1..kMaxRegions and the supernode after them (by-id tables need this many
  // entries).
  static constexpr std::size_t kMaxRegions = 8192;
  static constexpr std::size_t kMaxNodeIds = kMaxRegions + 2;
  static constexpr std::size_t kLoneFaceRoom =
      4;  // lone faces per round whose single-face hypotheses fit for sure
  explicit Impl(const Library& lib, const RecognizeParams& p, int threads)
      : pool(threads), per_model(lib.models.size()) {
    match::MatcherLimits limits;
    limits.max_states = std::max<std::int64_t>(p.max_states, 16);
    limits.max_reported = std::max(p.solutions_per_model, 1);
    for (int w = 0; w < pool.threads(); ++w) {
      matchers.push_back(std::make_unique<match::InexactMatcher>(limits));
      verifiers.emplace_back(p.verify);
    }
    geometry.reserve(lib.models.size());
    for (const Model& m : lib.models) geometry.emplace_back(m);
    for (auto& pm : per_model) {
      pm.slots.resize(static_cast<std::size_t>(p.solutions_per_model));
      for (auto& s : pm.slots) {
        s.path.reserve(kMaxMatches);
        s.matches.reserve(kMaxMatches);
      }
    }
    // The search solutions of every reference, plus room for the single-face hypotheses of kLoneFaceRoom lone
    // faces.
    const std::size_t max_h = lib.models.size() * static_cast<std::size_t>(p.solutions_per_model) +
                              kLoneFaceRoom * static_cast<std::size_t>(std::max(p.single_face_max, 0));
    hyps.resize(max_h);
    for (auto& h : hyps) {
      h.matches.reserve(kMaxMatches);
      h.path.reserve(kMaxMatches);
    }
    order.reserve(max_h);
    picked.reserve(max_h);
    face_cover.reserve(kMaxNodeIds);
    alive.reserve(max_h);
    pairs.reserve(256);
    node_used.reserve(kMaxNodeIds);
    scene_index.reserve(kMaxNodeIds);
  }

  WorkerPool pool;
  std::vector<std::unique_ptr<match::InexactMatcher>> matchers;
  std::vector<Verifier> verifiers;
  std::vector<ModelGeometry> geometry;
  std::vector<ModelSlots> per_model;
  std::vector<Hypothesis> hyps;  // pool; the first nhyp are live this scan
  std::size_t nhyp = 0;
  std::vector<std::size_t> order;
  std::vector<char> alive;
  std::vector<PlanePair> pairs;
  std::vector<char> node_used;   // by scene node id
  std::vector<int> scene_index;  // scene node id -> index in scene.nodes (-1)
  std::vector<std::int32_t> cell_owner;
  // Inlier cells of the refined hypotheses: slot k belongs to hyps[slot_owner[k]] during a scan (swapped into
  // its inlier_cells and back afterwards, so no buffer is ever reallocated).
  std::vector<std::vector<std::uint32_t>> slot_cells;
  // Buffers of the reported objects: out.objects[k] holds spare_objects[k]'s buffers during a scan (swapped
  // in when reported, swapped back at the next scan), so reporting never allocates.
  std::vector<Hypothesis> spare_objects;
  std::vector<std::size_t> slot_owner;
  std::vector<std::size_t> picked;  // scratch of select_covering
  std::vector<int> face_cover;      // by scene node id
  // Matching context.
  const Pfrg* scene = nullptr;
  const Library* library = nullptr;
  match::MatchParams mparams;
  match::MatchParams mparams_small;  // parts with fewer faces than mparams.th_minlevel (TH_minlevel lowered)
  // Verification context.
  SampleSet coarse, fine;
  bool refine_phase = false;
  // Samples per segmentation region (coarse / fine), to measure how much of its matched regions a hypothesis
  // explains.
  std::vector<std::uint32_t> region_coarse, region_fine;
  std::vector<std::uint32_t> region_hits;
  const std::vector<std::int32_t>* labels = nullptr;
  // Connected parts of the scene graph (supernode arcs do not connect), each with >= min_level faces; the
  // matcher searches each on its own. parts[k] holds the supernode(s) and the part's faces and arcs.
  std::vector<Pfrg> parts;
  std::vector<int> part_faces;   // real faces of parts[k]
  std::vector<int> lone_faces;   // indices into the split graph's nodes of faces that border no other face
  std::vector<char> lone_tried;  // by scene node id: single-face hypotheses made already
  Pfrg rest;  // the scene graph without the faces of accepted objects (rounds after the first)
  std::vector<Eigen::Vector2d> hull, hull_scratch;  // outline of a lone face parallel to the table

  // hull = convex hull of the fine samples of `face` (scene node id = region + 1), in the plane basis (u, v).
  void outline(const PfrgNode& face, const std::vector<std::int32_t>& labels, const Vec3& u, const Vec3& v) {
    hull.clear();
    const auto& cells = fine.cells();
    const auto& pts = fine.points();
    for (std::size_t k = 0; k < cells.size(); ++k)
      if (cells[k] < labels.size() && labels[cells[k]] == face.id - 1) {
        const Vec3 q = pts[k].cast<double>();
        hull.emplace_back(q.dot(u), q.dot(v));
      }
    hull.resize(convex_hull_in_place(hull, hull_scratch));
  }
  bool round_small = false;  // this round searches every part with mparams_small

  // By scene node id: 1 for the supernode(s), set per scan (the graphs split below are the scene or part of
  // it, with the same ids). Ids without an entry count as unknown, i.e. as the supernode.
  std::vector<char> super_by_id;
  void mark_supernodes(const Pfrg& g) {
    int max_id = 0;
    for (const auto& n : g.nodes) max_id = std::max(max_id, n.id);
    super_by_id.assign(static_cast<std::size_t>(max_id) + 1, 0);
    for (const auto& n : g.nodes)
      if (n.supernode) super_by_id[static_cast<std::size_t>(n.id)] = 1;
  }
  bool is_super(int id) const {
    return id < 0 || static_cast<std::size_t>(id) >= super_by_id.size() ||
           super_by_id[static_cast<std::size_t>(id)];
  }

  // rest = scene without the faces accepted objects hold. A kept face that bordered an accepted one borders
  // the unknown there, so that arc becomes one to the supernode (one per face; the node-degree condition
  // counts a face's neighbours, the supernode included). False when no face is left.
  std::vector<char> rest_super_arc;  // by node id: the kept face has an arc to the supernode in rest
  bool build_rest(const Pfrg& g) {
    rest.nodes.clear();
    rest.arcs.clear();
    rest.name = g.name;
    rest.observer = g.observer;
    rest.has_observer = g.has_observer;
    int faces = 0, super_id = -1;
    auto kept = [&](int id) {
      return id >= 0 && static_cast<std::size_t>(id) < node_used.size() &&
             !node_used[static_cast<std::size_t>(id)];
    };
    for (const auto& n : g.nodes)
      if (n.supernode || kept(n.id)) {
        rest.nodes.push_back(n);
        faces += n.supernode ? 0 : 1;
        if (n.supernode && super_id < 0) super_id = n.id;
      }
    rest_super_arc.assign(node_used.size(), 0);
    for (const auto& a : g.arcs) {
      const bool sa = is_super(a.a), sb = is_super(a.b);
      if ((sa || kept(a.a)) && (sb || kept(a.b))) {
        rest.arcs.push_back(a);
        if (sa && kept(a.b)) rest_super_arc[static_cast<std::size_t>(a.b)] = 1;
        if (sb && kept(a.a)) rest_super_arc[static_cast<std::size_t>(a.a)] = 1;
      }
    }
    if (super_id >= 0)
      for (const auto& a : g.arcs) {
        const bool ka = kept(a.a), kb = kept(a.b);
        if (ka == kb || is_super(a.a) || is_super(a.b))
          continue;  // both kept, both accepted, or to the supernode
        const int face = ka ? a.a : a.b;
        if (rest_super_arc[static_cast<std::size_t>(face)]) continue;
        rest_super_arc[static_cast<std::size_t>(face)] = 1;
        rest.arcs.push_back(PfrgArc{face, super_id, a.border});
      }
    return faces > 0;
  }

  std::size_t nparts = 0;
  std::vector<int> uf;                          // union-find parent by node id
  std::vector<int> part_of;                     // node id -> part index (-1)
  std::vector<int> comp_size;                   // by root id
  static constexpr std::size_t kMaxParts = 32;  // further parts are searched together with the last one

  int find(int x) {
    while (uf[static_cast<std::size_t>(x)] != x)
      x = uf[static_cast<std::size_t>(x)] = uf[static_cast<std::size_t>(uf[static_cast<std::size_t>(x)])];
    return x;
  }

  // viewpoint: the sensor position; each part then looks at it from its faces' centroid (the visibility
  // condition needs the real viewing direction: a scene's mean normal leans toward its largest faces).
  void split_components(const Pfrg& g, int min_faces, const Vec3* viewpoint = nullptr) {
    int max_id = 0;
    for (const auto& n : g.nodes) max_id = std::max(max_id, n.id);
    const auto size = static_cast<std::size_t>(max_id) + 1;
    uf.resize(size);
    for (std::size_t i = 0; i < size; ++i) uf[i] = static_cast<int>(i);
    part_of.assign(size, -1);
    comp_size.assign(size, 0);
    for (const auto& a : g.arcs)
      if (!is_super(a.a) && !is_super(a.b)) {
        const int ra = find(a.a), rb = find(a.b);
        if (ra != rb) uf[static_cast<std::size_t>(ra)] = rb;
      }
    for (const auto& n : g.nodes)
      if (!n.supernode) ++comp_size[static_cast<std::size_t>(find(n.id))];
    // Observer of the whole scene, so that every part sees the same viewing direction.
    Vec3 observer = g.observer;
    if (!g.has_observer) {
      Vec3 sum = Vec3::Zero();
      for (const auto& n : g.nodes)
        if (!n.supernode) sum += n.area * n.normal;
      observer = sum.norm() > 1e-12 ? Vec3(sum.normalized()) : Vec3(Vec3::UnitZ());
    }
    nparts = 0;
    lone_faces.clear();
    for (std::size_t i = 0; i < g.nodes.size(); ++i)
      if (!g.nodes[i].supernode && comp_size[static_cast<std::size_t>(find(g.nodes[i].id))] == 1)
        lone_faces.push_back(static_cast<int>(i));
    for (const auto& n : g.nodes) {
      if (n.supernode) continue;
      const int root = find(n.id);
      if (comp_size[static_cast<std::size_t>(root)] < min_faces) continue;
      int& p = part_of[static_cast<std::size_t>(root)];
      if (p < 0) {
        if (nparts < kMaxParts) {
          p = static_cast<int>(nparts++);
          part_faces[static_cast<std::size_t>(p)] = 0;
          Pfrg& part = parts[static_cast<std::size_t>(p)];
          part.nodes.clear();
          part.arcs.clear();
          part.name = g.name;
          part.observer = observer;
          part.has_observer = true;
          for (const auto& sn : g.nodes)
            if (sn.supernode) part.nodes.push_back(sn);
        } else {
          p = static_cast<int>(kMaxParts) - 1;
        }
      }
      part_of[static_cast<std::size_t>(n.id)] = p;
      parts[static_cast<std::size_t>(p)].nodes.push_back(n);
      ++part_faces[static_cast<std::size_t>(p)];
    }
    if (viewpoint && !g.has_observer)
      for (std::size_t k = 0; k < nparts; ++k) {
        Vec3 c = Vec3::Zero();
        double w = 0.0;
        for (const auto& n : parts[k].nodes)
          if (!n.supernode && n.has_plane) c += n.area * n.centroid, w += n.area;
        if (w <= 0.0) continue;
        const Vec3 d = *viewpoint - c / w;
        if (d.norm() > 1e-9) parts[k].observer = d.normalized();
      }
    for (const auto& a : g.arcs) {
      const bool sa = is_super(a.a), sb = is_super(a.b);
      const int pa = sa ? -1 : part_of[static_cast<std::size_t>(a.a)];
      const int pb = sb ? -1 : part_of[static_cast<std::size_t>(a.b)];
      const int p = pa >= 0 ? pa : pb;
      if (p < 0 || (pa >= 0 && pb >= 0 && pa != pb)) continue;
      parts[static_cast<std::size_t>(p)].arcs.push_back(a);
    }
  }

  // The table found in the scene (normal toward the sensor), for the support test.
  bool have_table = false;
  Plane table;
  double support_tol = 3.0, support_radius = 6.0, unsupported_factor = 0.5;

  void support_test(const Model& model, Hypothesis& h) const {
    if (!have_table) return;
    h.verify.support =
        support_factor(model, h.R, h.t, table, fine.points(),
                       SupportParams{support_tol, support_radius, unsupported_factor}, &h.verify.lowest_mm);
    h.verify.confidence *= h.verify.support;
  }
};

namespace {

// Filters im.order (kept in order) to at most `limit` hypotheses that pass `ok` and hold a scene face that
// fewer than `per_face` earlier picks hold.
template <class Ok>
void select_covering(Recognizer::Impl& im, int per_face, std::size_t limit, Ok ok) {
  int max_id = 0;
  for (std::size_t i : im.order)
    for (const FaceMatch& m : im.hyps[i].matches) max_id = std::max(max_id, m.scene);
  im.face_cover.assign(static_cast<std::size_t>(max_id) + 1, 0);
  im.picked.clear();
  for (std::size_t i : im.order) {
    if (im.picked.size() >= limit) break;
    const Hypothesis& h = im.hyps[i];
    if (!ok(h)) continue;
    bool wanted = false;
    for (const FaceMatch& m : h.matches)
      wanted = wanted || im.face_cover[static_cast<std::size_t>(m.scene)] < per_face;
    if (!wanted) continue;
    for (const FaceMatch& m : h.matches) ++im.face_cover[static_cast<std::size_t>(m.scene)];
    im.picked.push_back(i);
  }
  im.order.assign(im.picked.begin(), im.picked.end());
}

// The refined hypotheses of other models that explain the accepted hypothesis h (index `self`) as well: on at
// least half of its scene faces, confidence within alternative_confidence, inliers >= alternative_inliers x
// its own.
void find_alternatives(const Recognizer::Impl& im, std::size_t self, const RecognizeParams& params,
                       Hypothesis& h) {
  h.alternatives = 0;
  for (std::size_t j : im.order) {
    if (h.alternatives >= Hypothesis::kMaxAlternatives) break;
    const Hypothesis& o = im.hyps[j];
    if (j == self || o.model == h.model ||
        o.verify.confidence < h.verify.confidence - params.alternative_confidence ||
        static_cast<double>(o.verify.inliers) <
            params.alternative_inliers * static_cast<double>(h.verify.inliers))
      continue;
    std::size_t shared = 0;
    for (const FaceMatch& m : h.matches)
      for (const FaceMatch& om : o.matches) shared += om.scene == m.scene ? 1 : 0;
    if (2 * shared < h.matches.size()) continue;
    bool listed = false;
    for (const Hypothesis::Alternative& a : h.listed_alternatives()) listed = listed || a.model == o.model;
    if (listed) continue;
    h.alternative[static_cast<std::size_t>(h.alternatives++)] = {o.model, o.verify.confidence};
  }
}

}  // namespace

Recognizer::Recognizer(const Library& library, const RecognizeParams& params, std::size_t max_cells)
    : library_(library),
      params_(params),
      segmenter_(params.segment, seg::SegmentLimits{max_cells, Impl::kMaxRegions, 32768}),
      pfrg_builder_(Impl::kMaxRegions, 32768) {
  segmenter_.prepare(seg_);
  pfrg_builder_.prepare(scene_);
  impl_ = std::make_unique<Impl>(library, params_, params.threads);
  impl_->cell_owner.assign(max_cells, -1);
  impl_->coarse.reserve(max_cells);
  impl_->fine.reserve(max_cells);
  impl_->parts.resize(Impl::kMaxParts);
  impl_->part_faces.resize(Impl::kMaxParts);
  for (Pfrg& part : impl_->parts) {
    part.nodes.reserve(256);
    part.arcs.reserve(2048);
    part.name.reserve(64);
  }
  impl_->uf.reserve(Impl::kMaxNodeIds);
  impl_->lone_faces.reserve(Impl::kMaxNodeIds);
  impl_->lone_tried.reserve(Impl::kMaxNodeIds);
  impl_->rest.nodes.reserve(Impl::kMaxNodeIds);
  impl_->rest_super_arc.reserve(Impl::kMaxNodeIds);
  impl_->super_by_id.reserve(Impl::kMaxNodeIds);
  impl_->rest.arcs.reserve(32768);
  impl_->rest.name.reserve(64);
  impl_->part_of.reserve(Impl::kMaxNodeIds);
  impl_->comp_size.reserve(Impl::kMaxNodeIds);
  // Fine samples of a grid of max_cells cells: at most ceil(h/s) * ceil(w/s) <= cells/s^2 + cells/s + 1.
  const std::size_t step = static_cast<std::size_t>(std::max(1, params.verify.sample_step));
  const std::size_t max_samples = max_cells / (step * step) + max_cells / step + 1;
  impl_->slot_cells.resize(static_cast<std::size_t>(std::max(params.max_refined, 1)));
  for (auto& b : impl_->slot_cells) b.reserve(max_samples);
  impl_->slot_owner.reserve(impl_->slot_cells.size());
  std::size_t max_faces = 0;  // the largest model's front-face list
  for (const Model& m : library_.models) max_faces = std::max(max_faces, m.faces.size());
  for (auto& v : impl_->verifiers) v.reserve(max_samples, max_faces);
  impl_->hull.reserve(max_samples);
  impl_->hull_scratch.reserve(2 * max_samples);
  result_.objects.reserve(static_cast<std::size_t>(std::max(params.max_objects, 1)));
  impl_->spare_objects.resize(result_.objects.capacity());
  for (Hypothesis& h : impl_->spare_objects) {
    h.matches.reserve(kMaxMatches);
    h.path.reserve(kMaxMatches);
    h.inlier_cells.reserve(max_samples);
  }
  result_.note.reserve(512);
}

Recognizer::~Recognizer() = default;

const Recognition& Recognizer::recognize(const OrganizedCloud& cloud, const Plane* table) {
  Impl& im = *impl_;
  const auto t_start = Clock::now();
  Recognition& out = result_;
  // The reported objects' buffers go back to the spare pool (swapped, never freed), see spare_objects.
  for (std::size_t k = 0; k < out.objects.size(); ++k) std::swap(out.objects[k], im.spare_objects[k]);
  out.objects.clear();
  out.stats = RecognizeStats{};
  out.note.clear();

  // 1. Segmentation and scene PFRG.
  auto t0 = Clock::now();
  segmenter_.segment(cloud, seg_);
  out.stats.segment_ms = ms_since(t0);
  t0 = Clock::now();
  pfrg_builder_.build(seg_, scene_);
  out.stats.regions = static_cast<int>(seg_.regions.size());
  out.stats.known_regions = static_cast<int>(seg_.known_count());
  im.have_table = false;
  if (params_.remove_table) {
    out.stats.table_removed = remove_table(scene_, table, cloud.viewpoint, params_.table_angle_deg,
                                           params_.table_dist_mm, &im.table) >= 0;
    im.have_table = out.stats.table_removed;
  }
  im.support_tol = params_.support_tol_mm;
  im.support_radius = params_.support_radius_mm;
  im.unsupported_factor = params_.unsupported_factor;
  out.stats.pfrg_ms = ms_since(t0);
  int known_nodes = 0;
  for (const auto& n : scene_.nodes) known_nodes += n.supernode ? 0 : 1;
  out.stats.scene_nodes = known_nodes;
  out.stats.scene_arcs = static_cast<int>(scene_.arcs.size());
  out.stats.references = static_cast<int>(library_.models.size());
  if (known_nodes == 0) {
    out.note = "no planar face found in the scene (besides the table)";
    out.stats.total_ms = ms_since(t_start);
    return out;
  }

  // Matching parameters: the preset with the recognizer's overrides.
  im.scene = &scene_;
  im.library = &library_;
  im.mparams = params_.match;
  im.mparams.max_states = std::min<std::int64_t>(params_.match.max_states, params_.max_states);
  im.mparams.th_minlevel = params_.min_level;
  if (params_.max_solutions > 0) im.mparams.max_solutions = params_.max_solutions;
  if (params_.rigidity_pairs) im.mparams.rigidity_pairs = true;
  if (params_.rigidity_deg > 0) im.mparams.th_omega_deg = params_.rigidity_deg;
  if (params_.match_area_ratio > 0) {
    im.mparams.th_area_ratio = params_.match_area_ratio;
    im.mparams.th_area_slack_mm2 = params_.match_area_slack_mm2;
  }
  im.mparams_small = im.mparams;
  int min_part = params_.min_level;
  const bool small_parts =
      params_.small_part_min_level > 0 && params_.small_part_min_level < params_.min_level;
  if (small_parts) {
    min_part = params_.small_part_min_level;
    im.mparams_small.th_minlevel = params_.small_part_min_level;
  }
  int max_id = 0;
  for (const auto& n : scene_.nodes) max_id = std::max(max_id, n.id);
  im.scene_index.assign(static_cast<std::size_t>(max_id) + 1, -1);
  for (std::size_t i = 0; i < scene_.nodes.size(); ++i)
    im.scene_index[static_cast<std::size_t>(scene_.nodes[i].id)] = static_cast<int>(i);
  im.node_used.assign(static_cast<std::size_t>(max_id) + 1, 0);
  im.lone_tried.assign(static_cast<std::size_t>(max_id) + 1, 0);
  im.mark_supernodes(scene_);
  if (im.cell_owner.size() < cloud.points.size()) im.cell_owner.resize(cloud.points.size(), -1);
  HypothesisContext hc{library_, scene_, im.scene_index, cloud.viewpoint, params_};
  // The measured points verification looks at (built once per scan).
  auto t_samples = Clock::now();
  const Eigen::Vector2d grid = grid_spacing_mm(cloud);
  const VerifyParams& vp = params_.verify;
  im.coarse.build(cloud, sample_steps(grid, 2 * vp.sample_step, 2.0 * vp.sample_spacing_mm));
  im.fine.build(cloud, sample_steps(grid, vp.sample_step, vp.sample_spacing_mm));
  im.labels = &seg_.labels;
  auto count_regions = [&](const SampleSet& set, std::vector<std::uint32_t>& counts) {
    counts.assign(seg_.regions.size(), 0);
    for (std::uint32_t cell : set.cells()) {
      const std::int32_t r = cell < seg_.labels.size() ? seg_.labels[cell] : -1;
      if (r >= 0 && static_cast<std::size_t>(r) < counts.size()) ++counts[static_cast<std::size_t>(r)];
    }
  };
  count_regions(im.coarse, im.region_coarse);
  count_regions(im.fine, im.region_fine);
  out.stats.verify_ms += ms_since(t_samples);
  double best_rejected = -1.0;
  int best_rejected_model = -1;
  int hypotheses_total = 0;
  for (ModelSlots& ms : im.per_model) ms.count = 0, ms.states = 0;  // no part: no solution (not last scan's)

  // Rounds: the scene graph, then (beyond the thesis) the faces no accepted object explains, searched again
  // with TH_minlevel lowered to small_part_min_level (an object showing two faces next to another object),
  // with single-face hypotheses for faces that border no unexplained face; until a round accepts nothing new.
  const int rounds = std::max(1, params_.rounds);
  for (int round = 0; round < rounds; ++round) {
    // 2. Match the scene (or what is left of it) against every reference (in parallel, one matcher per
    // worker).
    t0 = Clock::now();
    const Pfrg* graph = &scene_;
    if (round == 0) {
      im.split_components(scene_, min_part, &cloud.viewpoint);
      out.stats.components = static_cast<int>(im.nparts);
    } else {
      if (!small_parts || !im.build_rest(scene_)) break;
      graph = &im.rest;
      im.split_components(im.rest, params_.small_part_min_level, &cloud.viewpoint);
    }
    im.round_small = round > 0;
    im.pool.run(
        im.nparts == 0 ? 0 : library_.models.size(),
        [](void* ctx, std::size_t task, int worker) {
          auto& m = *static_cast<Impl*>(ctx);
          const Model& model = m.library->models[task];
          ModelSlots& ms = m.per_model[task];
          ms.states = 0;
          ms.count = 0;
          // Each connected part of the scene graph is searched on its own (a solution is connected, so
          // it lies in one part); the model's solution slots are shared out evenly among the parts.
          const int per_part = static_cast<int>((ms.slots.size() + m.nparts - 1) / m.nparts);
          for (std::size_t part = 0; part < m.nparts; ++part) {
            const bool small = m.round_small || m.part_faces[part] < m.mparams.th_minlevel;
            const match::MatchResult& r = m.matchers[static_cast<std::size_t>(worker)]->match(
                m.parts[part], model.graph, small ? m.mparams_small : m.mparams);
            ms.states += r.stats.states_created;
            int taken = 0;
            for (const match::Solution& s : r.solutions) {
              if (ms.count >= static_cast<int>(ms.slots.size()) || taken >= per_part) break;
              if (s.partial) continue;
              ++taken;
              SolutionSlot& slot = ms.slots[static_cast<std::size_t>(ms.count++)];
              slot.path.assign(s.path.begin(), s.path.end());
              slot.matches.assign(s.matches.begin(), s.matches.end());
              slot.rotation = s.rotation;
              slot.cost = s.cost;
              slot.rotfit = s.rotfit_error;
              slot.level = s.level;
              slot.rank = s.rank;
              slot.degenerate = s.degenerate;
            }
          }
        },
        &im);
    out.stats.match_ms += ms_since(t0);
    out.stats.rounds = round + 1;

    // 3. Hypotheses: pose, expansion, compatible merge.
    t0 = Clock::now();
    im.nhyp = 0;
    for (std::size_t mi = 0; mi < library_.models.size(); ++mi) {
      ModelSlots& ms = im.per_model[mi];
      out.stats.states += ms.states;
      for (int k = 0; k < ms.count; ++k) {
        const SolutionSlot& s = ms.slots[static_cast<std::size_t>(k)];
        Hypothesis& h = im.hyps[im.nhyp++];
        h.model = static_cast<int>(mi);
        h.rank = s.rank;
        h.path.assign(s.path.begin(), s.path.end());
        h.matches.clear();
        for (const auto& m : s.matches) h.matches.push_back(FaceMatch{m.scene, m.ref, false});
        h.level = s.level;
        h.R = s.rotation;
        h.cost = s.cost;
        h.rotfit_error = s.rotfit;
        h.degenerate = s.degenerate;
        h.merged = false;
        h.instance = 0;
        h.verify = VerifyResult{};
        h.inlier_cells.clear();
      }
      ms.count = 0;
      ms.states = 0;
    }
    for (std::size_t i = 0; i < im.nhyp; ++i) {
      Hypothesis& h = im.hyps[i];
      update_translation(hc, h, im.pairs);
      // Expansion takes only faces no accepted object holds.
      out.stats.expanded_faces += expand(hc, h, im.pairs, &im.node_used);
    }
    im.alive.assign(im.nhyp, 1);
    out.stats.merged +=
        merge_compatible(hc, std::span<Hypothesis>(im.hyps.data(), im.nhyp), im.alive, im.pairs);
    // Faces that border no (unexplained) face: single-face hypotheses (model face on it, another on the
    // table).
    if (params_.single_face_min_area_mm2 > 0 && im.have_table) {
      SingleFaceParams sp;
      if (params_.match_area_ratio > 0) {
        sp.area.area_ratio = params_.match_area_ratio;
        sp.area.area_slack_mm2 = params_.match_area_slack_mm2;
      }
      for (int idx : im.lone_faces) {
        const PfrgNode& face = graph->nodes[static_cast<std::size_t>(idx)];
        if (face.area < params_.single_face_min_area_mm2 || im.lone_tried[static_cast<std::size_t>(face.id)])
          continue;
        const std::size_t room = std::min(im.hyps.size() - im.nhyp,
                                          static_cast<std::size_t>(std::max(params_.single_face_max, 0)));
        if (room == 0) break;  // the pool is full this round: the face is tried again in the next one
        int n = 0;
        if (!parallel_to_table(face, im.table, sp.min_tilt_deg)) {
          n = single_face_hypotheses(library_, face, im.table, sp,
                                     std::span<Hypothesis>(im.hyps.data() + im.nhyp, room));
        } else {
          // Parallel to the table: the turn about the vertical comes from the face's outline (fine samples).
          const Vec3 u = face.normal.unitOrthogonal();
          const Vec3 v = face.normal.cross(u);
          im.outline(face, seg_.labels, u, v);
          TopFaceParams tp;
          tp.area = sp.area;
          n = top_face_hypotheses(library_, face, im.table, im.hull, u, v, tp,
                                  std::span<Hypothesis>(im.hyps.data() + im.nhyp, room));
        }
        im.nhyp += static_cast<std::size_t>(n);
        out.stats.single_face += n;
        // Done with this face unless its hypotheses were cut short by the room left.
        if (static_cast<std::size_t>(n) < room) im.lone_tried[static_cast<std::size_t>(face.id)] = 1;
      }
      im.alive.resize(im.nhyp, 1);
    }
    hypotheses_total += static_cast<int>(im.nhyp);
    out.stats.hypotheses = hypotheses_total;
    if (im.nhyp == 0) {
      out.stats.verify_ms += ms_since(t0);
      if (round > 0) break;
      continue;
    }

    // 4. Low-level verification of the most plausible hypotheses (prescore, then matching cost), in parallel.
    im.order.clear();
    for (std::size_t i = 0; i < im.nhyp; ++i)
      if (im.alive[i]) im.order.push_back(i);
    for (std::size_t i : im.order) im.hyps[i].prescore = prescore(hc, im.hyps[i]);
    std::sort(im.order.begin(), im.order.end(), [&](std::size_t a, std::size_t b) {
      const Hypothesis& x = im.hyps[a];
      const Hypothesis& y = im.hyps[b];
      if (x.prescore != y.prescore) return x.prescore > y.prescore;
      return x.cost != y.cost ? x.cost < y.cost : a < b;
    });
    // Keep the order but give every scene face its share: a hypothesis is checked when one of its matched
    // scene faces has been claimed by fewer than verify_per_face better hypotheses (so the faces of a small
    // object are not crowded out by the many hypotheses of a large one).
    select_covering(im, params_.verify_per_face, static_cast<std::size_t>(params_.max_verified),
                    [](const Hypothesis&) { return true; });
    // Phase 1: coarse check of every candidate (no refinement).
    auto verify_task = [](void* ctx, std::size_t task, int worker) {
      auto& m = *static_cast<Impl*>(ctx);
      Hypothesis& h = m.hyps[m.order[task]];
      Verifier& v = m.verifiers[static_cast<std::size_t>(worker)];
      h.verify = v.verify(m.refine_phase ? m.fine : m.coarse, m.geometry[static_cast<std::size_t>(h.model)],
                          h.R, h.t, m.refine_phase);
      const std::vector<std::uint32_t>* cells = &v.inlier_cells();
      if (m.refine_phase) {
        m.slot_owner[task] = m.order[task];
        std::swap(h.inlier_cells, m.slot_cells[task]);
        h.inlier_cells.assign(v.inlier_cells().begin(), v.inlier_cells().end());
        cells = &h.inlier_cells;
      }
      // How much of the matched scene regions the model explains: a model smaller than the faces it claims
      // leaves measured points of those faces unexplained.
      const auto& counts = m.refine_phase ? m.region_fine : m.region_coarse;
      std::uint64_t total = 0, explained = 0;
      for (const FaceMatch& fm : h.matches) {
        const int r = fm.scene - 1;
        if (r >= 0 && static_cast<std::size_t>(r) < counts.size())
          total += counts[static_cast<std::size_t>(r)];
      }
      for (std::uint32_t cell : *cells) {
        const std::int32_t r = (*m.labels)[cell];
        for (const FaceMatch& fm : h.matches)
          if (fm.scene - 1 == r) {
            ++explained;
            break;
          }
      }
      h.verify.explained =
          total > 0 ? std::min(1.0, static_cast<double>(explained) / static_cast<double>(total)) : 0.0;
      h.verify.confidence *= h.verify.explained;
      if (m.refine_phase) m.support_test(m.library->models[static_cast<std::size_t>(h.model)], h);
    };
    im.refine_phase = false;
    im.pool.run(im.order.size(), verify_task, &im);
    auto rekey = [&] {
      // Of two hypotheses that fit equally, the one explaining more measured points goes first: a model that
      // covers only part of an object (a prism for the augmented prism) leaves the rest unexplained.
      int most_inliers = 1;
      for (std::size_t i : im.order) most_inliers = std::max(most_inliers, im.hyps[i].verify.inliers);
      for (std::size_t i : im.order) {
        Hypothesis& h = im.hyps[i];
        h.key =
            h.cost + params_.confidence_weight * (1.0 - h.verify.confidence) -
            params_.inlier_weight * static_cast<double>(h.verify.inliers) / static_cast<double>(most_inliers);
      }
      // std::sort with the index as tie-break (std::stable_sort would take a temporary buffer from the heap).
      std::sort(im.order.begin(), im.order.end(), [&](std::size_t a, std::size_t b) {
        return im.hyps[a].key != im.hyps[b].key ? im.hyps[a].key < im.hyps[b].key : a < b;
      });
    };
    rekey();
    // Phase 2: the plausible ones are refined by ICP and verified on the fine sample set.
    const double min_plausible = 0.5 * params_.min_confidence;
    select_covering(im, params_.refine_per_face, static_cast<std::size_t>(params_.max_refined),
                    [&](const Hypothesis& h) { return h.verify.confidence >= min_plausible; });
    std::size_t plausible = im.order.size();
    im.refine_phase = true;
    im.slot_owner.resize(std::min(plausible, im.slot_cells.size()));
    plausible = im.slot_owner.size();
    im.pool.run(plausible, verify_task, &im);
    im.order.resize(plausible);
    rekey();
    for (std::size_t i : im.order) {
      Hypothesis& h = im.hyps[i];
      h.faces_visible =
          count_visible_faces(library_.models[static_cast<std::size_t>(h.model)], h.R, h.t, cloud.viewpoint);
    }
    out.stats.verify_ms += ms_since(t0);

    // 5. Recognition (ch. 9.4): greedy extraction of the compatible set that holds the best solution.
    out.stats.incompatible_pairs +=
        count_incompatible_pairs(std::span<const Hypothesis>(im.hyps.data(), im.nhyp), im.order);
    const std::size_t accepted_before = out.objects.size();
    for (std::size_t i : im.order) {
      Hypothesis& h = im.hyps[i];
      if (h.verify.confidence < params_.min_confidence) {
        ++out.stats.rejected;
        if (h.verify.confidence > best_rejected) {
          best_rejected = h.verify.confidence;
          best_rejected_model = h.model;
        }
        continue;
      }
      bool clash = false;
      for (const FaceMatch& m : h.matches)
        if (im.node_used[static_cast<std::size_t>(m.scene)]) clash = true;
      if (!clash && !h.inlier_cells.empty()) {
        std::size_t shared = 0;
        for (std::uint32_t c : h.inlier_cells) shared += im.cell_owner[c] >= 0 ? 1 : 0;
        clash = static_cast<double>(shared) >
                params_.max_shared_inliers * static_cast<double>(h.inlier_cells.size());
      }
      if (clash) continue;
      if (static_cast<int>(out.objects.size()) >= params_.max_objects) break;
      for (const FaceMatch& m : h.matches) im.node_used[static_cast<std::size_t>(m.scene)] = 1;
      const auto obj_index = static_cast<std::int32_t>(out.objects.size());
      for (std::uint32_t c : h.inlier_cells) im.cell_owner[c] = obj_index;
      int instance = 0;
      for (const Hypothesis& o : out.objects) instance += o.model == h.model ? 1 : 0;
      h.instance = instance;
      find_alternatives(im, i, params_, h);
      canonical_pose(library_.models[static_cast<std::size_t>(h.model)], h.R, h.t);
      out.objects.emplace_back();
      std::swap(out.objects.back(), im.spare_objects[out.objects.size() - 1]);
      copy_hypothesis(h, out.objects.back());
    }
    // Give the inlier buffers back to their slots (the next round reuses the hypotheses).
    for (std::size_t k = 0; k < im.slot_owner.size(); ++k)
      std::swap(im.hyps[im.slot_owner[k]].inlier_cells, im.slot_cells[k]);
    im.slot_owner.clear();
    if (out.objects.size() == accepted_before && round > 0) break;
    if (static_cast<int>(out.objects.size()) >= params_.max_objects) break;
  }
  // Reset the cell owners touched.
  for (const Hypothesis& o : out.objects)
    for (std::uint32_t c : o.inlier_cells) im.cell_owner[c] = -1;
  if (out.objects.empty()) {
    if (hypotheses_total == 0) {
      out.note = "no reference matched the scene graph";
    } else if (best_rejected_model >= 0) {
      char buf[320];  // formatted without heap temporaries (out.note keeps its reserved capacity)
      std::snprintf(buf, sizeof buf,
                    "no hypothesis passed verification (best: %.200s with confidence %.3f < %.2f)",
                    library_.models[static_cast<std::size_t>(best_rejected_model)].name.c_str(),
                    best_rejected, params_.min_confidence);
      out.note.assign(buf);
    } else {
      out.note = "all hypotheses were incompatible";
    }
  }
  out.stats.total_ms = ms_since(t_start);
  return out;
}

std::vector<const Hypothesis*> Recognizer::candidates() const {
  std::vector<const Hypothesis*> out;
  for (std::size_t i : impl_->order) out.push_back(&impl_->hyps[i]);
  return out;
}

std::vector<const Hypothesis*> Recognizer::all_hypotheses() const {
  std::vector<const Hypothesis*> out;
  for (std::size_t i = 0; i < impl_->nhyp; ++i)
    if (i < impl_->alive.size() && impl_->alive[i]) out.push_back(&impl_->hyps[i]);
  return out;
}

void Recognizer::object_labels(const OrganizedCloud& cloud, std::vector<std::int32_t>& labels) const {
  labels.assign(cloud.points.size(), -1);
  if (seg_.labels.size() != cloud.points.size()) return;
  // scene node id = region + 1
  for (std::size_t o = 0; o < result_.objects.size(); ++o) {
    for (const FaceMatch& m : result_.objects[o].matches) {
      const std::int32_t region = m.scene - 1;
      for (std::size_t i = 0; i < seg_.labels.size(); ++i)
        if (seg_.labels[i] == region) labels[i] = static_cast<std::int32_t>(o);
    }
  }
}

}  // namespace fs::host::rec
