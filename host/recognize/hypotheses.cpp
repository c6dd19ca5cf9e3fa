#include "host/recognize/hypotheses.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace fs::host::rec {

namespace {

const PfrgNode* scene_node(const HypothesisContext& c, int id) {
  if (id < 0 || static_cast<std::size_t>(id) >= c.scene_index.size()) return nullptr;
  const int i = c.scene_index[static_cast<std::size_t>(id)];
  return i < 0 ? nullptr : &c.scene.nodes[static_cast<std::size_t>(i)];
}

bool uses_scene(const Hypothesis& h, int id) {
  for (const auto& m : h.matches)
    if (m.scene == id) return true;
  return false;
}
bool uses_ref(const Hypothesis& h, int id) {
  for (const auto& m : h.matches)
    if (m.ref == id) return true;
  return false;
}

double face_radius(const ModelFace& f) {
  double r = 0.0;
  for (const auto& loop : f.loops)
    for (const Vec3& p : loop) r = std::max(r, (p - f.centroid).norm());
  return r;
}

}  // namespace

void update_translation(const HypothesisContext& c, Hypothesis& h, std::vector<PlanePair>& scratch) {
  scratch.clear();
  for (const FaceMatch& m : h.matches) {
    const PfrgNode* n = scene_node(c, m.scene);
    if (!n || !n->has_plane) continue;
    scratch.push_back(plane_pair(*n, m.ref));
  }
  const Model& model = c.library.models[static_cast<std::size_t>(h.model)];
  const TranslationFit fit = fit_translation(model, h.R, scratch);
  h.t = fit.t;
  h.free_dims = fit.free_dims;
  h.free_dir = fit.free_dir;
}

int expand(const HypothesisContext& c, Hypothesis& h, std::vector<PlanePair>& scratch,
           const std::vector<char>* taken) {
  const Model& model = c.library.models[static_cast<std::size_t>(h.model)];
  const double cos_max = std::cos(c.params.expand_angle_deg * M_PI / 180.0);
  int added = 0;
  for (std::size_t f = 0; f < model.faces.size(); ++f) {
    const int fid = static_cast<int>(f);
    if (uses_ref(h, fid)) continue;
    const ModelFace& mf = model.faces[f];
    const Vec3 n = h.R * mf.normal;
    const Vec3 centre = h.R * mf.centroid + h.t;
    if (n.dot(c.viewpoint - centre) <= 0) continue;  // faces away from the sensor
    const double radius = face_radius(mf) + c.params.expand_dist_mm;
    int best = -1;
    double best_cos = cos_max;
    for (const PfrgNode& s : c.scene.nodes) {
      if (s.supernode || !s.has_plane || uses_scene(h, s.id)) continue;
      if (taken && s.id >= 0 && static_cast<std::size_t>(s.id) < taken->size() &&
          (*taken)[static_cast<std::size_t>(s.id)])
        continue;
      const double cs = s.normal.dot(n);
      if (cs < best_cos) continue;
      if (std::abs(s.normal.dot(centre) - s.offset) > c.params.expand_dist_mm) continue;
      if (std::abs(n.dot(s.centroid - centre)) > c.params.expand_dist_mm) continue;
      if ((s.centroid - centre).norm() > radius) continue;
      if (s.area > c.params.expand_area_ratio * mf.area) continue;
      best = s.id;
      best_cos = cs;
    }
    if (best >= 0) {
      h.matches.push_back(FaceMatch{best, fid, true});
      ++added;
    }
  }
  if (added > 0) update_translation(c, h, scratch);
  return added;
}

int merge_compatible(const HypothesisContext& c, std::span<Hypothesis> hyps, std::vector<char>& alive,
                     std::vector<PlanePair>& scratch) {
  int merges = 0;
  for (std::size_t i = 0; i < hyps.size(); ++i) {
    if (!alive[i]) continue;
    // Only hypotheses of the same model merge, and they are grouped by model: the pairs within the group (a
    // scan against 8,000 models holds ~265,000 hypotheses; all pairs took minutes).
    for (std::size_t j = i + 1; j < hyps.size() && hyps[j].model == hyps[i].model; ++j) {
      if (!alive[j]) continue;
      Hypothesis& a = hyps[i];
      Hypothesis& b = hyps[j];
      const Model& model = c.library.models[static_cast<std::size_t>(a.model)];
      // Compare where the model's centre lands: symmetry-equivalent poses differ in t when the model's origin
      // is off its centre.
      const bool close_t =
          ((a.R * model.center + a.t) - (b.R * model.center + b.t)).norm() <= c.params.merge_translation_mm;
      bool shared_scene = false, shared_ref = false;
      for (const FaceMatch& m : b.matches) {
        shared_scene = shared_scene || uses_scene(a, m.scene);
        shared_ref = shared_ref || uses_ref(a, m.ref);
      }
      if (!shared_scene && !shared_ref && close_t &&
          rotation_angle_deg(a.R, b.R) <= c.params.merge_rotation_deg) {
        // Compatible: the same object seen as separated subgraphs; merge b into a.
        for (const FaceMatch& m : b.matches) a.matches.push_back(m);
        a.level += b.level;
        a.merged = true;
        update_translation(c, a, scratch);
        alive[j] = 0;
        ++merges;
      } else if (shared_scene && close_t &&
                 rotation_angle_deg_sym(a.R, b.R, model) <= c.params.merge_rotation_deg) {
        // The same object again (symmetry-equivalent or a sub-solution): keep the cheaper one.
        if (b.cost < a.cost) {
          std::swap(a, b);
        }
        alive[j] = 0;
      }
    }
  }
  return merges;
}

namespace {

// A hypothesis of one face match (scene face -> model face fi) in pose (R, t); the buffers of h are reused.
void one_face_hypothesis(Hypothesis& h, int model, int scene_face, int fi, const Mat3& R, const Vec3& t,
                         double cost, bool partial_face = false, bool raised = false) {
  h.model = model;
  h.rank = 0;
  h.path.clear();
  h.matches.clear();
  h.matches.push_back(FaceMatch{scene_face, fi, false});
  h.level = 1;
  h.R = R;
  h.t = t;
  h.free_dims = 0;
  h.free_dir = Vec3::Zero();
  h.cost = cost;
  h.rotfit_error = 0.0;
  h.degenerate = false;
  h.merged = false;
  h.partial_face = partial_face || raised;
  h.raised = raised;
  h.instance = 0;
  h.verify = VerifyResult{};
  h.inlier_cells.clear();
}

}  // namespace

bool parallel_to_table(const PfrgNode& face, const Plane& table, double min_tilt_deg) {
  return face.normal.cross(table.n).norm() < std::sin(min_tilt_deg * M_PI / 180.0);
}

int single_face_hypotheses(const Library& library, const PfrgNode& face, const Plane& table,
                           const SingleFaceParams& p, std::span<Hypothesis> out) {
  if (face.supernode || !face.has_plane || parallel_to_table(face, table, p.min_tilt_deg)) return 0;
  const Vec3 ns = face.normal;
  const Vec3 down = -table.n;
  const Vec3 u = ns.cross(table.n).normalized();
  const double scene_angle = std::acos(std::clamp(ns.dot(down), -1.0, 1.0));
  const double tol = p.angle_tol_deg * M_PI / 180.0;
  // Target frame of the triad: scene normal, then the common direction of the scene face and the table.
  const Vec3 b2 = ns.cross(down).normalized();
  Mat3 B;
  B << ns, b2, ns.cross(b2);
  Mat3 M;
  M.row(0) = ns.transpose();
  M.row(1) = table.n.transpose();
  M.row(2) = u.transpose();
  const Mat3 Minv = M.inverse();
  int written = 0;
  // First the model faces whose area fits the scene face's, then (hidden) the larger ones it may be the seen
  // part of: these come after every fitting one, so they never take the room of one of this face (they may
  // take the pool's room of lone faces that come later, which wait for the next round, if there is one).
  for (const bool hidden : {false, true}) {
    if (hidden && !(p.extent_known && p.hidden_min_area_ratio > 0.0)) break;
    for (std::size_t mi = 0; mi < library.models.size(); ++mi) {
      const Model& model = library.models[mi];
      for (std::size_t fi = 0; fi < model.faces.size(); ++fi) {
        const ModelFace& f = model.faces[fi];
        const bool fits = p.area.fits(face.area, f.area);
        if (hidden ? fits || face.area > f.area || face.area < p.hidden_min_area_ratio * f.area : !fits)
          continue;
        for (std::size_t gi = 0; gi < model.faces.size(); ++gi) {
          if (gi == fi) continue;
          const ModelFace& g = model.faces[gi];
          const double angle = std::acos(std::clamp(f.normal.dot(g.normal), -1.0, 1.0));
          if (std::abs(angle - scene_angle) > tol) continue;
          const Vec3 a2 = f.normal.cross(g.normal).normalized();
          Mat3 A;
          A << f.normal, a2, f.normal.cross(a2);
          const Mat3 R = B * A.transpose();
          // n_s . t = d_s - off_f (matched plane), n_table . t = d_table + off_g (g on the table),
          // u . t = u . (c_s - R c_f) (the face's centroid along the common line).
          const Vec3 rhs(face.offset - f.offset, table.d + g.offset, u.dot(face.centroid - R * f.centroid));
          std::array<double, 3> along{rhs.z(), 0.0, 0.0};
          int placements = 1;
          if (hidden) {
            // Also either end of the model face's extent along u at the scene face's.
            double lo = std::numeric_limits<double>::infinity(), hi = -lo;
            for (const auto& loop : f.loops)
              for (const Vec3& v : loop) {
                const double s = u.dot(R * v);
                lo = std::min(lo, s);
                hi = std::max(hi, s);
              }
            along[1] = p.extent_min - lo;
            along[2] = p.extent_max - hi;
            placements = 3;
          }
          for (int k = 0; k < placements; ++k) {
            if (written >= static_cast<int>(out.size())) return written;
            one_face_hypothesis(out[static_cast<std::size_t>(written++)], static_cast<int>(mi), face.id,
                                static_cast<int>(fi), R, Minv * Vec3(rhs.x(), rhs.y(), along[k]), 0.0,
                                hidden);
          }
        }
      }
    }
  }
  return written;
}

std::size_t convex_hull_in_place(std::vector<Eigen::Vector2d>& pts, std::vector<Eigen::Vector2d>& scratch) {
  const std::size_t n = pts.size();
  if (n < 3) return n;
  std::sort(pts.begin(), pts.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y();
  });
  // Turn test with a relative tolerance, so that (nearly) collinear points along an edge are dropped.
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const double c = (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
    return c - 1e-9 * (a - o).norm() * (b - o).norm();
  };
  scratch.resize(2 * n);  // capacity reserved by the caller: no allocation once warm
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    while (k >= 2 && cross(scratch[k - 2], scratch[k - 1], pts[i]) <= 0) --k;
    scratch[k++] = pts[i];
  }
  for (std::size_t i = n - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross(scratch[k - 2], scratch[k - 1], pts[i]) <= 0) --k;
    scratch[k++] = pts[i];
  }
  --k;  // the last point repeats the first
  for (std::size_t i = 0; i < k; ++i) pts[i] = scratch[i];
  return k;
}

namespace {

double segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + s * ab - p).norm();
}

template <class Poly>
double boundary_distance(const Eigen::Vector2d& p, const Poly& poly, std::size_t n) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i) best = std::min(best, segment_distance(p, poly[i], poly[(i + 1) % n]));
  return best;
}

}  // namespace

int top_face_hypotheses(const Library& library, const PfrgNode& face, const Plane& table,
                        std::span<const Eigen::Vector2d> hull, const Vec3& u, const Vec3& v,
                        const TopFaceParams& p, std::span<Hypothesis> out) {
  if (face.supernode || !face.has_plane || hull.size() < 3) return 0;
  const double height = face.offset - table.d;  // face plane above the table (normals within a few degrees)
  const double cos_anti = std::cos(p.antiparallel_deg * M_PI / 180.0);
  // Long edges are those of >= 25 % of the longest (hull and polygon alike).
  double hull_max = 0.0;
  for (std::size_t i = 0; i < hull.size(); ++i)
    hull_max = std::max(hull_max, (hull[(i + 1) % hull.size()] - hull[i]).norm());
  constexpr std::size_t kMaxPoly = 64;
  std::array<Eigen::Vector2d, kMaxPoly> poly{}, turned{};
  struct Turn {
    double score, angle;
    Eigen::Vector2d shift;
  };
  std::array<Turn, 8> best{};
  int written = 0;
  for (std::size_t mi = 0; mi < library.models.size(); ++mi) {
    const Model& model = library.models[mi];
    for (std::size_t fi = 0; fi < model.faces.size(); ++fi) {
      const ModelFace& f = model.faces[fi];
      if (!p.area.fits(face.area, f.area)) continue;
      if (f.loops.empty() || f.loops[0].size() < 3 || f.loops[0].size() > kMaxPoly) continue;
      // A resting face g antiparallel to f at the right distance (raised: at less than the face's height).
      int g = -1;
      for (std::size_t gi = 0; gi < model.faces.size() && g < 0; ++gi) {
        const ModelFace& mg = model.faces[gi];
        if (gi == fi || f.normal.dot(mg.normal) > -cos_anti) continue;
        const double above = height - (f.offset + mg.offset);
        if (p.raised ? above > p.height_tol_mm : std::abs(above) <= p.height_tol_mm) g = static_cast<int>(gi);
      }
      if (g < 0) continue;
      // R0: f's normal onto the scene face's; then f's outer polygon and centroid in the (u, v) basis.
      const Mat3 R0 = Eigen::Quaterniond::FromTwoVectors(f.normal, face.normal).toRotationMatrix();
      const auto& loop = f.loops[0];
      const std::size_t n = loop.size();
      double poly_max = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        const Vec3 w = R0 * loop[i];
        poly[i] = Eigen::Vector2d(w.dot(u), w.dot(v));
      }
      for (std::size_t i = 0; i < n; ++i) poly_max = std::max(poly_max, (poly[(i + 1) % n] - poly[i]).norm());
      // Turns about the face's normal that are symmetries of the model (a regular polygon's, on a model that
      // has them): turns that differ by one of these are one placement, not two of the max_turns.
      std::array<double, kMaxPoly> sym_turns{};
      std::size_t nsym = 0;
      {
        const Vec3 a = face.normal.unitOrthogonal();
        for (const Mat3& S : model.symmetries) {
          if (nsym == sym_turns.size()) break;
          // The tolerance of the symmetries themselves (BuildOptions::symmetry_tolerance): their normals come
          // from the mesh's rounded coordinates. Distinct face normals differ by far more.
          if ((S * f.normal - f.normal).norm() > 1e-3) continue;
          const Vec3 b = R0 * (S * (R0.transpose() * a));
          const double turn = std::atan2(face.normal.dot(a.cross(b)), a.dot(b));
          if (std::abs(turn) > 1e-6) sym_turns[nsym++] = turn;
        }
      }
      const Vec3 cf = R0 * f.centroid;
      const Eigen::Vector2d c_poly(cf.dot(u), cf.dot(v));
      const Eigen::Vector2d c_scene(face.centroid.dot(u), face.centroid.dot(v));
      int nbest = 0;
      for (std::size_t hi = 0; hi < hull.size(); ++hi) {
        const Eigen::Vector2d eh = hull[(hi + 1) % hull.size()] - hull[hi];
        if (eh.norm() < 0.25 * hull_max) continue;
        for (std::size_t pi = 0; pi < n; ++pi) {
          const Eigen::Vector2d ep = poly[(pi + 1) % n] - poly[pi];
          if (ep.norm() < 0.25 * poly_max) continue;
          const double angle = std::atan2(eh.y(), eh.x()) - std::atan2(ep.y(), ep.x());
          const Eigen::Rotation2Dd rot(angle);
          const Eigen::Vector2d shift = c_scene - rot * c_poly;
          for (std::size_t i = 0; i < n; ++i) turned[i] = rot * poly[i] + shift;
          double sum = 0.0;
          for (const Eigen::Vector2d& q : hull) sum += boundary_distance(q, turned, n);
          for (std::size_t i = 0; i < n; ++i) sum += boundary_distance(turned[i], hull, hull.size());
          const double score = sum / static_cast<double>(hull.size() + n);
          if (score > p.max_outline_mm) continue;
          // Keep the best max_turns distinct turns (1 deg apart).
          bool dup = false;
          for (int k = 0; k < nbest; ++k) {
            bool same = std::abs(std::remainder(best[static_cast<std::size_t>(k)].angle - angle, 2 * M_PI)) <
                        M_PI / 180.0;
            for (std::size_t j = 0; j < nsym && !same; ++j)
              same = std::abs(std::remainder(best[static_cast<std::size_t>(k)].angle - angle - sym_turns[j],
                                             2 * M_PI)) < M_PI / 180.0;
            if (same) {
              dup = true;
              if (score < best[static_cast<std::size_t>(k)].score)
                best[static_cast<std::size_t>(k)] = Turn{score, angle, shift};
            }
          }
          if (dup) continue;
          const int cap = std::clamp(p.max_turns, 1, static_cast<int>(best.size()));
          if (nbest < cap) {
            best[static_cast<std::size_t>(nbest++)] = Turn{score, angle, shift};
          } else {
            int worst = 0;
            for (int k = 1; k < nbest; ++k)
              if (best[static_cast<std::size_t>(k)].score > best[static_cast<std::size_t>(worst)].score)
                worst = k;
            if (score < best[static_cast<std::size_t>(worst)].score)
              best[static_cast<std::size_t>(worst)] = Turn{score, angle, shift};
          }
        }
      }
      for (int k = 0; k < nbest; ++k) {
        if (written >= static_cast<int>(out.size())) return written;
        const Turn& tr = best[static_cast<std::size_t>(k)];
        const Mat3 R = Eigen::AngleAxisd(tr.angle, face.normal).toRotationMatrix() * R0;
        // In-plane: the turned polygon's shift; along the normal (u, v are orthogonal to it): f on the face's
        // plane.
        const Vec3 t = u * tr.shift.x() + v * tr.shift.y() + face.normal * (face.offset - f.offset);
        // Cost: the outline fit (in m) as a tie-break.
        one_face_hypothesis(out[static_cast<std::size_t>(written++)], static_cast<int>(mi), face.id,
                            static_cast<int>(fi), R, t, tr.score * 1e-3, false, p.raised);
      }
    }
  }
  return written;
}

namespace {

// Weight of a face whose normal makes cosine cs with the direction to a sensor or light: full from 30 degrees
// above grazing, none below 10 degrees (such faces are barely sampled or lit).
double incidence_weight(double cs) { return std::clamp((cs - 0.17) / 0.33, 0.0, 1.0); }

// How much of a posed model face (centre: its posed centroid) the scan can measure, in [0, 1]: the light's
// incidence_weight (as for the camera), times the share of its points (centroid and vertices drawn a quarter
// toward it) that the sweep and the camera image reach.
double measurable_share(const ScannerCalibration& s, const ModelFace& mf, const Mat3& R, const Vec3& t,
                        const Vec3& centre) {
  const Vec3 to_light = s.laser.axis_point - centre;
  const double cs = (R * mf.normal).dot(to_light) / std::max(to_light.norm(), 1e-9);
  const double lit = incidence_weight(cs);
  if (lit <= 0.0) return 0.0;
  int n = 1, in = s.covers(centre) ? 1 : 0;
  for (const auto& loop : mf.loops)
    for (const Vec3& v : loop) {
      ++n;
      in += s.covers(R * (0.75 * v + 0.25 * mf.centroid) + t) ? 1 : 0;
    }
  return lit * static_cast<double>(in) / static_cast<double>(n);
}

}  // namespace

double prescore(const HypothesisContext& c, const Hypothesis& h) {
  const Model& model = c.library.models[static_cast<std::size_t>(h.model)];
  double predicted = 0.0, explained = 0.0, penalty = 1.0;
  for (std::size_t f = 0; f < model.faces.size(); ++f) {
    const ModelFace& mf = model.faces[f];
    const Vec3 centre = h.R * mf.centroid + h.t;
    const Vec3 to_view = c.viewpoint - centre;
    const double cs = (h.R * mf.normal).dot(to_view) / std::max(to_view.norm(), 1e-9);
    double w = incidence_weight(cs);
    if (c.scanner && w > 0.0) w *= measurable_share(*c.scanner, mf, h.R, h.t, centre);
    predicted += w * mf.area;
    for (const FaceMatch& m : h.matches) {
      if (m.ref != static_cast<int>(f)) continue;
      const PfrgNode* n = scene_node(c, m.scene);
      if (!n) continue;
      explained += w * std::min(n->area, mf.area);
      const double allowed = c.params.prescore_area_slack * mf.area + 10.0;
      if (n->area > allowed) penalty *= allowed / n->area;
    }
  }
  if (predicted <= 0.0) return 0.0;
  return std::min(1.0, explained / predicted) * penalty;
}

double matched_scene_area(const HypothesisContext& c, const Hypothesis& h) {
  double area = 0.0;
  for (const FaceMatch& m : h.matches)
    if (const PfrgNode* n = scene_node(c, m.scene)) area += n->area;
  return area;
}

double lowest_point(const Model& model, const Mat3& R, const Vec3& t, const Plane& table, Vec3* where) {
  double low = std::numeric_limits<double>::infinity();
  for (const ModelFace& f : model.faces)
    for (const auto& loop : f.loops)
      for (const Vec3& v : loop) {
        const Vec3 w = R * v + t;
        const double z = table.signed_distance(w);
        if (z < low) {
          low = z;
          if (where) *where = w;
        }
      }
  return low;
}

double support_factor(const Model& model, const Mat3& R, const Vec3& t, const Plane& table,
                      const MeasuredPoints& points, const SupportParams& p, double* lowest) {
  Vec3 v_low = Vec3::Zero();
  const double low = lowest_point(model, R, t, table, &v_low);
  if (lowest) *lowest = low;
  if (std::abs(low) <= p.tol_mm) return 1.0;
  if (low > 0) {
    const double r2 = p.radius_mm * p.radius_mm;
    // Points within radius_mm of v_low lie in the cone from the sensor that holds that ball.
    const Vec3 to_low = v_low - p.viewpoint;
    const double d = to_low.norm();
    const double cone = d > p.radius_mm ? std::asin(p.radius_mm / d) : M_PI;
    const auto on_own_plane = [&](const Vec3& q) {
      if (p.own_plane_mm <= 0.0) return false;
      for (const ModelFace& f : model.faces) {
        const Vec3 n = R * f.normal;
        const double offset = f.offset + n.dot(t);
        if (n.dot(p.viewpoint) > offset && std::abs(n.dot(q) - offset) <= p.own_plane_mm) return true;
      }
      return false;
    };
    const auto near_below = [&](const Eigen::Vector3f& pf) {
      const Vec3 q = pf.cast<double>();
      return (q - v_low).squaredNorm() <= r2 && table.signed_distance(q) < low - 1.0 && !on_own_plane(q);
    };
    if (points.any_in_cone(p.viewpoint, d > 0.0 ? Vec3(to_low / d) : Vec3::UnitZ(), cone, near_below))
      return 1.0;
    if (p.look_below) {
      // The column under the solid's centre of mass, from the height of its lowest point: a solid at rest is
      // held up under it (an overhanging part may have the table seen under it, and the part of the base the
      // solid hides itself says nothing).
      const Vec3 c = R * model.center + t;
      const Vec3 column = c - (table.signed_distance(c) - low) * table.n;
      const SpaceBelow below = look_below(column, table, p.viewpoint, points, p.tol_mm);
      if (below.seen_through == 0 && below.hidden >= p.min_hidden_rays) return 1.0;
    }
  }
  return p.unsupported;
}

SpaceBelow look_below(const Vec3& top, const Plane& table, const Vec3& viewpoint,
                      const MeasuredPoints& points, double tol_mm) {
  constexpr double kStep = 2.0, kRay = 3.0, kMargin = 2.0;
  constexpr std::size_t kMaxProbes = 128;
  SpaceBelow out;
  // Probe heights from tol_mm under `top` down to 1 mm above the table, at most kMaxProbes (the step grows
  // for a solid high above the table).
  const double lift = table.signed_distance(top);
  const double first = lift - tol_mm;
  if (!(first >= 1.0)) return out;
  const double step = std::max(kStep, (first - 1.0) / static_cast<double>(kMaxProbes - 1));
  std::array<Vec3, kMaxProbes> probe;
  std::size_t n = 0;
  for (double h = first; h >= 1.0 && n < probe.size(); h -= step) probe[n++] = top - (lift - h) * table.n;
  // Only rays toward the probes' neighbourhood: the cone from the viewpoint around their middle.
  const Vec3 mid = 0.5 * (probe[0] + probe[n - 1]);
  const double half = 0.5 * (probe[0] - probe[n - 1]).norm() + kRay;
  const Vec3 to_mid = mid - viewpoint;
  const double mid_dist = to_mid.norm();
  if (!(mid_dist > 0.0)) return out;
  const Vec3 axis = to_mid / mid_dist;
  const double cone = std::atan2(half, std::max(mid_dist - half, 1.0));
  const double cos_cone = std::cos(cone);
  points.any_in_cone(viewpoint, axis, cone, [&](const Eigen::Vector3f& pf) {
    const Vec3 d = pf.cast<double>() - viewpoint;
    const double range = d.norm();
    if (!(range > 0.0)) return false;
    const Vec3 u = d / range;
    if (u.dot(axis) < cos_cone) return false;
    bool through = false, in_front = false;
    for (std::size_t k = 0; k < n && !through; ++k) {
      const Vec3 w = probe[k] - viewpoint;
      const double s = w.dot(u);
      if (s <= 0.0 || w.squaredNorm() - s * s > kRay * kRay) continue;
      through = range > s + kMargin;
      in_front = in_front || range < s - kMargin;
    }
    out.seen_through += through ? 1 : 0;
    out.hidden += !through && in_front ? 1 : 0;
    return false;
  });
  return out;
}

int count_visible_faces(const Model& model, const Mat3& R, const Vec3& t, const Vec3& viewpoint) {
  int n = 0;
  for (const ModelFace& f : model.faces) {
    const Vec3 c = R * f.centroid + t;
    n += (R * f.normal).dot(viewpoint - c) > 0 ? 1 : 0;
  }
  return n;
}

int count_incompatible_pairs(std::span<const Hypothesis> hyps, const std::vector<std::size_t>& order) {
  int pairs = 0;
  for (std::size_t x = 0; x < order.size(); ++x)
    for (std::size_t y = x + 1; y < order.size(); ++y) {
      const Hypothesis& a = hyps[order[x]];
      const Hypothesis& b = hyps[order[y]];
      bool shared = false;
      for (const FaceMatch& m : b.matches) shared = shared || uses_scene(a, m.scene);
      pairs += shared ? 1 : 0;
    }
  return pairs;
}

void copy_hypothesis(const Hypothesis& from, Hypothesis& to) {
  // Member-wise copy assignment: each std::vector reuses `to`'s buffer when it is large enough (no allocation
  // once warm; RecognizeScenes.WarmRecognizeAllocatesNothing checks it), and no field can be forgotten.
  to = from;
}

}  // namespace fs::host::rec
