#pragma once
// Internal to the recognizer (see README.md): Recognizer::Impl, the working memory of recognize() (sized at
// construction, reused), and the steps recognize() runs, implemented by stage in prepare.cpp,
// scene_parts.cpp, match_round.cpp, hypothesis_round.cpp, verify_round.cpp and accept.cpp.
#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include "host/match/arc_index.hpp"
#include "host/recognize/hypotheses.hpp"
#include "host/recognize/near_symmetry.hpp"
#include "host/recognize/pose.hpp"
#include "host/recognize/recognizer.hpp"
#include "host/recognize/verify.hpp"
#include "host/recognize/worker_pool.hpp"

namespace fs::host::rec {

namespace detail {

using Clock = std::chrono::steady_clock;
inline constexpr std::size_t kMaxMatches =
    128;  // face matches of one hypothesis (matcher graphs hold <= 128 nodes)
inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// The confidence h must reach to be accepted, listed as an alternative or count as a face's passing
// refinement: single_face_hidden_min_confidence for a lone face's partial placement (Hypothesis::
// partial_face), else min_confidence.
inline double pass_confidence(const Hypothesis& h, const RecognizeParams& p) {
  return h.partial_face ? p.single_face_hidden_min_confidence : p.min_confidence;
}

// One reference's kept solutions (buffers reused across scans).
struct SolutionSlot {
  std::vector<int> path;
  std::vector<match::NodeMatch> matches;
  Mat3 rotation = Mat3::Identity();
  double cost = 0, rotfit = 0;
  int level = 0, rank = 0;
  int part_rank = 0;  // k-th solution of its model in its scene part
  bool degenerate = false;
};

struct ModelSlots {
  std::vector<SolutionSlot> slots;
  int count = 0;
  std::int64_t states = 0;
};

}  // namespace detail

struct Recognizer::Impl {
  using ModelSlots = detail::ModelSlots;
  using SolutionSlot = detail::SolutionSlot;

  // Scene node ids: regions 1..kMaxRegions and the supernode after them (by-id tables need this many
  // entries).
  static constexpr std::size_t kMaxRegions = 8192;
  static constexpr std::size_t kMaxNodeIds = kMaxRegions + 2;
  static constexpr std::size_t kLoneFaceRoom =
      4;  // lone faces per round whose single-face hypotheses fit for sure
  explicit Impl(const Library& lib, const RecognizeParams& p, int threads);

  WorkerPool pool;
  std::vector<std::unique_ptr<match::InexactMatcher>> matchers;
  std::vector<Verifier> verifiers;
  std::vector<ModelGeometry> geometry;
  std::vector<std::vector<NearSymmetry>> near_sym;  // by model (RecognizeParams::near_symmetry_share)
  // By model: the faces a search starts from (RecognizeParams::symmetry_roots; empty = every face).
  std::vector<match::NodeSet> search_roots;
  bool second_search = false;  // RecognizeParams::second_search
  int second_search_min_level = 0;
  PlacementCheck placement;  // RecognizeParams::placement
  // References are matched kMatchBatch at a time: batch[k] holds the solutions of model batch_first + k until
  // they are collected into hyps (collect_batch), so this memory does not grow with the library.
  static constexpr std::size_t kMatchBatch = 256;
  std::vector<ModelSlots> batch;
  // By model, bit k: model may hold a solution of parts[k] (match::ArcIndex; all bits when it is off).
  const match::ArcIndex* arc_index = nullptr;  // the library's own (stored with it) or own_arc_index
  match::ArcIndex own_arc_index;
  match::ArcIndex::Scratch arc_scratch;
  bool use_arc_index = false;
  std::vector<std::uint64_t> part_mask;
  std::size_t batch_first = 0;
  std::size_t max_solutions = 0;   // hypotheses the searches may fill (RecognizeParams::max_hypotheses)
  std::vector<std::size_t> worst;  // heap of hyps indices, highest matching cost on top (when full)
  bool pool_full = false;
  int quota = 0;  // solutions kept per model and scene part this round (lowered when the pool fills)
  void collect_batch(std::size_t n, RecognizeStats& stats);
  std::size_t trim_to_quota();
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
  std::vector<std::size_t> picked;        // scratch of select_covering
  std::vector<std::size_t> waiting;       // ... the positions of those that wait their turn
  std::vector<std::size_t> order_copy;    // scratch: order kept aside (screening, second refinement)
  std::vector<std::size_t> coarse_order;  // the coarse-checked hypotheses, best first (refine_again)
  std::vector<char> refined;              // by hypothesis index (refine_again)
  std::vector<double> face_best;          // best coarse confidence by scene node id (refine_again)
  std::size_t slot_base = 0;              // slot of refine task 0 (refine_again's second pass)
  std::vector<int> face_cover;            // by scene node id
  // Conflicts of one hypothesis with each accepted object (accept.cpp): shared inlier cells, shared scene
  // faces, interpenetration depth (mm).
  std::vector<int> conflict_cells, conflict_faces;
  std::vector<double> conflict_depth, conflict_share;
  void measure_conflicts(const Hypothesis& h, const Recognition& out);
  // The measured hypothesis and accepted object k would interpenetrate (RecognizeParams::interpenetration_*).
  bool interpenetrates(const RecognizeParams& p, std::size_t k) const {
    return conflict_depth[k] > p.interpenetration_mm && conflict_share[k] > p.interpenetration_share;
  }
  // The measured hypothesis conflicts with accepted object k: a shared scene face, interpenetrating solids,
  // or more than a tenth of k's inlier points (the objects a replacement would replace).
  bool conflicts_with(const RecognizeParams& p, std::size_t k, const Recognition& out) const {
    return conflict_faces[k] > 0 || interpenetrates(p, k) ||
           static_cast<double>(conflict_cells[k]) >
               0.1 * static_cast<double>(out.objects[k].inlier_cells.size());
  }
  // Removes accepted object k (its cells and faces are free again; its buffers go back to the spare pool).
  void remove_object(Recognition& out, std::size_t k);
  // Matching context.
  const Pfrg* scene = nullptr;
  const Library* library = nullptr;
  match::MatchParams mparams;
  match::MatchParams mparams_second, mparams_small_second;  // the same with the second search's budget
  match::MatchParams mparams_small;  // parts with fewer faces than mparams.th_minlevel (TH_minlevel lowered)
  // Verification context.
  SampleSet coarse, fine, screen;
  bool refine_phase = false;
  // Samples per segmentation region (coarse / fine), to measure how much of its matched regions a hypothesis
  // explains.
  std::vector<std::uint32_t> region_coarse, region_fine, region_screen;
  std::vector<std::uint32_t> region_hits;
  const std::vector<std::int32_t>* labels = nullptr;
  // Connected parts of the scene graph (supernode arcs do not connect), each with >= min_level faces; the
  // matcher searches each on its own. parts[k] holds the supernode(s) and the part's faces and arcs.
  std::vector<Pfrg> parts;
  std::vector<int> part_faces;  // real faces of parts[k]
  std::vector<int> lone_faces;  // indices into the split graph's nodes of faces that border no other face
  // By scene node id: single-face hypotheses made already (1: on the table; 2: raised too,
  // top_face_hypotheses).
  std::vector<char> lone_tried;
  int raised_waiting = 0;  // lone faces of this round whose raised placements come in the next one
  Pfrg rest;               // the scene graph without the faces of accepted objects (rounds after the first)
  std::vector<Eigen::Vector2d> hull, hull_scratch;  // outline of a lone face

  // hull = convex hull of the fine samples of `face` (scene node id = region + 1), in the plane basis (u, v).
  void outline(const PfrgNode& face, const std::vector<std::int32_t>& labels, const Vec3& u, const Vec3& v);
  bool round_small = false;  // this round searches every part with mparams_small

  // By scene node id: 1 for the supernode(s), set per scan (the graphs split below are the scene or part of
  // it, with the same ids). Ids without an entry count as unknown, i.e. as the supernode.
  std::vector<char> super_by_id;
  void mark_supernodes(const Pfrg& g);
  bool is_super(int id) const {
    return id < 0 || static_cast<std::size_t>(id) >= super_by_id.size() ||
           super_by_id[static_cast<std::size_t>(id)];
  }

  // rest = scene without the faces accepted objects hold. A kept face that bordered an accepted one borders
  // the unknown there, so that arc becomes one to the supernode (one per face; the node-degree condition
  // counts a face's neighbours, the supernode included). False when no face is left.
  std::vector<char> rest_super_arc;  // by node id: the kept face has an arc to the supernode in rest
  bool build_rest(const Pfrg& g);

  std::size_t nparts = 0;
  std::vector<int> uf;         // union-find parent by node id
  std::vector<int> part_of;    // node id -> part index (-1); a window's faces: the first window holding them
  std::vector<int> comp_size;  // by root id
  // Parts searched per round. Components beyond them join the last part while it has room; faces that find no
  // part are counted (RecognizeStats::unsearched_faces).
  static constexpr std::size_t kMaxParts = 64;
  // A component of more faces than the matcher takes (match::kMaxNodes with the supernodes) is searched in
  // overlapping windows: breadth-first from its first face not yet in a window, up to the cap, so that each
  // face lies in a window with its graph neighbourhood (an object's faces are few and adjacent).
  std::vector<int> adj_start, adj;            // face-face adjacency by node id (CSR)
  std::vector<int> stamp;                     // by node id: window being built
  std::vector<int> bfs;                       // queue of a window's breadth-first search
  std::array<char, kMaxParts> window_part{};  // parts[k] is a window of a larger component
  int windows = 0, unsearched_faces = 0, largest_component = 0;
  int max_part_faces = 0;  // RecognizeParams::max_part_faces

  int find(int x);
  // The largest number of faces one part may hold (matcher limit minus supernodes, RecognizeParams cap).
  int part_cap(const Pfrg& g) const;
  // New part k (empty: the supernodes of g, the observer); returns false when every part is in use.
  bool open_part(const Pfrg& g, const Vec3& observer);
  // Adds the arcs of g among part k's nodes (and to the supernode) to it, in g's order.
  void add_part_arcs(const Pfrg& g, std::size_t k, int mark);
  // Covers the component `root` (more than cap faces) with overlapping windows.
  void split_windows(const Pfrg& g, int root, int cap, const Vec3& observer);

  // viewpoint: the sensor position; each part then looks at it from its faces' centroid (the visibility
  // condition needs the real viewing direction: a scene's mean normal leans toward its largest faces).
  void split_components(const Pfrg& g, int min_faces, const Vec3* viewpoint = nullptr);

  // The table found in the scene (normal toward the sensor), for the support test.
  bool have_table = false;
  Plane table;
  double support_tol = 3.0, support_radius = 6.0, unsupported_factor = 0.5;
  bool support_hidden_below = true;
  int hidden_below_min_faces = 3;
  double hidden_below_min_fit = 0.9;
  int hidden_below_min_rays = 0;
  double support_own_plane = 0.5;
  double table_snap = 8.0, table_snap_slack = 0.02;

  void support_test(const Model& model, Hypothesis& h) const;
  // The support test's parameters for hypothesis h fitting `fit` (look_below only when it is seen clearly).
  SupportParams support_params(const Hypothesis& h, double fit) const;
  void sink_test(const Model& model, Hypothesis& h) const;
  // RecognizeParams::table_snap_mm: h (refined, fine-checked) moved along its free direction onto the table
  // when that fits about as well.
  void snap_to_table(const Model& model, Hypothesis& h, Verifier& v) const;
  // h failed the support test but rests on an accepted object: its confidence is restored (true).
  bool supported_by_accepted(Hypothesis& h, const Recognition& out) const;
  static constexpr std::size_t kNoHypothesis = static_cast<std::size_t>(-1);
  std::vector<std::size_t> deferred;     // hypotheses waiting for an accepted object to rest on (accept.cpp)
  std::vector<std::size_t> hidden_wait;  // ... for other objects to explain the points in front of them
  static constexpr std::int32_t kWaitingOwner =
      -2;  // cell_owner of a cell a hypothesis waiting for support holds
  void mark_waiting_cells(std::int32_t owner);
  double confidence_with_occluders(const Hypothesis& h, double occluded_weight);
  // Accepted object o (index k of out.objects) was accepted because other objects explain what hides it: the
  // few faces it shows may belong to a larger or another model. The pool's hypotheses of other models on at
  // least half of its scene faces (refined or not) get the same test, occluders included, and those that fit
  // as well are listed as its alternatives (accept.cpp).
  void alternatives_in_hiding(const RecognizeParams& params, std::size_t k, Recognition& out);
  bool accept_one(const RecognizeParams& params, Recognizer& rz, std::size_t i, Recognition& out);

  // ---- the steps of recognize(), by stage ----
  // Per-scan settings and tallies of recognize() (kept across its rounds).
  struct Scan {
    int min_part = 0;          // faces a connected part needs to be searched in the first round
    bool small_parts = false;  // later rounds search parts down to small_part_min_level faces
    double best_rejected = -1.0;
    int best_rejected_model = -1;
    int hypotheses_total = 0;
  };
  // prepare.cpp: the last scan's objects back to the spare pool; segmentation, scene PFRG and table (false:
  // no face to match); matching parameters and by-id tables; the verification samples.
  void reset_output(Recognition& out);
  bool prepare_scene(Recognizer& rz, const OrganizedCloud& cloud, const Plane* table, Recognition& out);
  Scan prepare_matching(Recognizer& rz, const OrganizedCloud& cloud);
  void prepare_samples(Recognizer& rz, const OrganizedCloud& cloud, RecognizeStats& stats);
  // scene_parts.cpp: the graph a round searches (the scene, then what accepted objects leave of it), split
  // into connected parts; nullptr when nothing is left to search.
  const Pfrg* split_scene(Recognizer& rz, const Scan& scan, int round, const Vec3& viewpoint,
                          RecognizeStats& stats);
  // match_round.cpp: every reference against every part (in parallel, one matcher per worker, a batch of
  // references at a time); their solutions become hyps[0 .. nhyp), grouped by model.
  void match_references(const Library& lib, int round, RecognizeStats& stats);
  // hypothesis_round.cpp: hypotheses from the kept solutions (pose, expansion, compatible merge) and the
  // single-face hypotheses of lone faces.
  detail::Clock::time_point hyp_t0;  // start of this round's hypotheses (verify_ms counts from there)
  void make_hypotheses(Recognizer& rz, const HypothesisContext& hc, const Pfrg& graph, Scan& scan,
                       RecognizeStats& stats);
  void lone_face_hypotheses(Recognizer& rz, const Pfrg& graph, RecognizeStats& stats);
  // verify_round.cpp: low-level verification, coarse for the most plausible hypotheses, then ICP refinement
  // and fine verification; leaves the verified ones in order (best ordering key first).
  void verify_hypotheses(Recognizer& rz, const HypothesisContext& hc, const OrganizedCloud& cloud,
                         RecognizeStats& stats);
  // Scales h's confidence by the share of its matched scene regions' samples among `cells` (its inliers).
  void scale_by_explained(Hypothesis& h, const std::vector<std::uint32_t>& cells, bool fine_samples) const;
  // The share of h's matched scene regions' samples (counts: per region) that cells (inliers) explain.
  double explained_share(const Hypothesis& h, const std::vector<std::uint32_t>& cells,
                         const std::vector<std::uint32_t>& counts) const;
  void screen_hypotheses(const RecognizeParams& params);
  void refine_again(const RecognizeParams& params, double min_plausible);
  // reseat.cpp: after its coarse check (scaled by the explained share), hyps[index], a plausible hypothesis
  // of a model with near symmetries, moves to the near-symmetric placement that scores best (fit x support
  // factor), if one scores better (worker: the worker's verifier and plane scratch); then the duplicates this
  // makes leave `order`.
  const HypothesisContext* hctx = nullptr;
  double reseat_min_confidence = 0.0;
  std::vector<std::vector<PlanePair>> worker_pairs;  // by worker (reseat.cpp, match_round.cpp)
  std::vector<std::vector<int>> worker_later;        // by worker: solutions taken last (match_round.cpp)
  std::vector<char> reseated, dropped;               // by hypothesis index
  std::vector<double> raw_confidence;  // coarse, before the explained share; by hypothesis index
  void reseat(std::size_t index, int worker);
  void drop_reseated_duplicates(const RecognizeParams& params);
  void rekey(const RecognizeParams& params);
  // accept.cpp: recognition (ch. 9.4), the compatible set greedily from the best hypothesis; false when the
  // rounds end here. finish_report: the cell owners reset and the note of an empty result.
  bool accept_objects(Recognizer& rz, Scan& scan, int round, Recognition& out);
  void finish_report(Recognizer& rz, const Scan& scan, Recognition& out);
};

}  // namespace fs::host::rec
