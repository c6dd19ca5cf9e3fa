#include "host/recognize/verify.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "host/recognize/convex_clip.hpp"
#include "host/recognize/pose.hpp"

namespace fs::host::rec {

ModelGeometry::ModelGeometry(const Model& model)
    : model_(&model), center_(model.center), radius_(model.bounding_radius) {
  faces_.reserve(model.faces.size());
  for (const ModelFace& mf : model.faces) {
    Face f;
    f.n = mf.normal.normalized();
    f.offset = mf.offset;
    f.u = f.n.unitOrthogonal();
    f.v = f.n.cross(f.u);
    f.lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    f.hi = -f.lo;
    for (const auto& loop : mf.loops) {
      f.loop_start.push_back(static_cast<std::uint32_t>(f.pts.size()));
      for (const Vec3& p : loop) {
        const Eigen::Vector2d q(f.u.dot(p), f.v.dot(p));
        f.pts.push_back(q);
        f.lo = f.lo.cwiseMin(q);
        f.hi = f.hi.cwiseMax(q);
      }
    }
    f.loop_start.push_back(static_cast<std::uint32_t>(f.pts.size()));
    if (f.loop_start.size() == 2 && f.pts.size() >= 3) {
      f.convex = true;
      const std::size_t k = f.pts.size();
      for (std::size_t i = 0; i < k && f.convex; ++i) {
        const Eigen::Vector2d e0 = f.pts[(i + 1) % k] - f.pts[i];
        const Eigen::Vector2d e1 = f.pts[(i + 2) % k] - f.pts[(i + 1) % k];
        f.convex = e0.x() * e1.y() - e0.y() * e1.x() > 0.0;  // every turn to the left
      }
      if (f.convex)
        for (std::size_t i = 0; i < k; ++i) {
          const Eigen::Vector2d e = f.pts[(i + 1) % k] - f.pts[i];
          const Eigen::Vector2d in(-e.y(), e.x());
          f.edges.emplace_back(in.x(), in.y(), in.dot(f.pts[i]));
        }
    }
    faces_.push_back(std::move(f));
    all_faces_.push_back(static_cast<std::uint32_t>(all_faces_.size()));
  }
  // Convex: closed, and every vertex on the inner side of every face plane. A ray then enters through exactly
  // one front face, so cast() may stop at the first front face that contains its hit, and cast_convex() may
  // clip. An open model (a face missing) is no solid: a clip would close it.
  convex_ = !model.open;
  for (const Face& f : faces_)
    for (const ModelFace& mf : model.faces)
      for (const auto& loop : mf.loops)
        for (const Vec3& p : loop) convex_ = convex_ && f.n.dot(p) <= f.offset + 1e-6 * (1.0 + radius_);
  if (convex_) {
    for (const ModelFace& mf : model.faces)
      for (const auto& loop : mf.loops) vertices_.insert(vertices_.end(), loop.begin(), loop.end());
    auto before = [](const Vec3& a, const Vec3& b) {
      return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    };
    std::sort(vertices_.begin(), vertices_.end(), before);
    vertices_.erase(std::unique(vertices_.begin(), vertices_.end()), vertices_.end());
  }
  sample_surface();
  sample_volume();
}

void ModelGeometry::sample_surface() {
  if (!convex_) return;  // made as they are asked for (any_surface_sample)
  each_surface_point([this](const Vec3& p) {
    surface_.push_back(p);
    return false;
  });
}

void ModelGeometry::sample_volume() {
  if (!convex_ || faces_.empty()) return;
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const ModelFace& mf : model_->faces)
    for (const auto& loop : mf.loops)
      for (const Vec3& p : loop) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double spacing = std::max(0.5, (hi - lo).maxCoeff() / 14.0);
  for (double x = lo.x() + 0.5 * spacing; x < hi.x(); x += spacing)
    for (double y = lo.y() + 0.5 * spacing; y < hi.y(); y += spacing)
      for (double z = lo.z() + 0.5 * spacing; z < hi.z(); z += spacing)
        if (depth_inside(Vec3(x, y, z)) > 0.0) volume_.emplace_back(x, y, z);
}

double ModelGeometry::depth_inside(const Vec3& p) const {
  if (!convex_) return 0.0;
  double depth = std::numeric_limits<double>::infinity();
  for (const Face& f : faces_) depth = std::min(depth, f.offset - f.n.dot(p));
  return depth;
}

bool ModelGeometry::separated_from(const ModelGeometry& other, const Mat3& R, const Vec3& t,
                                   double margin) const {
  if (!convex_ || !other.convex_ || other.vertices_.empty()) return false;
  for (const Face& f : faces_) {
    // The plane in the other model's frame: n . (R x + t) = offset  <=>  (R^T n) . x = offset - n . t.
    const Vec3 n = R.transpose() * f.n;
    const double level = f.offset - f.n.dot(t) + margin;
    bool all_out = true;
    for (const Vec3& v : other.vertices_)
      if (!(n.dot(v) > level)) {
        all_out = false;
        break;
      }
    if (all_out) return true;
  }
  return false;
}

Interpenetration interpenetration(const ModelGeometry& a, const Mat3& Ra, const Vec3& ta,
                                  const ModelGeometry& b, const Mat3& Rb, const Vec3& tb) {
  Interpenetration r;
  const Vec3 ca = Ra * a.center() + ta, cb = Rb * b.center() + tb;
  if ((ca - cb).norm() >= a.radius() + b.radius() || !a.convex() || !b.convex()) return r;
  // Points of `from` in the frame of `into`: x_into = Rinto^T (Rfrom s + tfrom - tinto).
  auto to_frame = [](const Mat3& Rf, const Vec3& tf, const Mat3& Ri, const Vec3& ti) {
    return std::pair<Mat3, Vec3>(Ri.transpose() * Rf, Ri.transpose() * (tf - ti));
  };
  const auto [Rab, tab] = to_frame(Ra, ta, Rb, tb);
  const auto [Rba, tba] = to_frame(Rb, tb, Ra, ta);
  // A face plane of one with every vertex of the other beyond it: no sample of either lies inside the
  // other, and both results stay 0. The margin is far above how far a mesh's samples may lie outside its
  // own face planes (the convexity tolerance, 1e-6 of the radius), so the samples below would find nothing.
  constexpr double kApartMm = 0.01;
  if (b.separated_from(a, Rab, tab, kApartMm) || a.separated_from(b, Rba, tba, kApartMm)) return r;
  for (const Vec3& s : a.surface_samples()) r.depth_mm = std::max(r.depth_mm, b.depth_inside(Rab * s + tab));
  for (const Vec3& s : b.surface_samples()) r.depth_mm = std::max(r.depth_mm, a.depth_inside(Rba * s + tba));
  // The smaller solid's volume samples inside the other.
  const bool a_small = a.model().volume <= b.model().volume;
  const ModelGeometry& small = a_small ? a : b;
  const ModelGeometry& large = a_small ? b : a;
  const Mat3& R = a_small ? Rab : Rba;
  const Vec3& t = a_small ? tab : tba;
  std::size_t in = 0;
  for (const Vec3& s : small.volume_samples()) in += large.depth_inside(R * s + t) > 0.0 ? 1 : 0;
  if (!small.volume_samples().empty())
    r.volume_share = static_cast<double>(in) / static_cast<double>(small.volume_samples().size());
  return r;
}

bool ModelGeometry::inside(const Face& f, const Eigen::Vector2d& q) const {
  if (q.x() < f.lo.x() || q.y() < f.lo.y() || q.x() > f.hi.x() || q.y() > f.hi.y()) return false;
  if (f.convex) {
    for (const Eigen::Vector3d& e : f.edges)
      if (e.x() * q.x() + e.y() * q.y() < e.z()) return false;
    return true;
  }
  bool in = false;  // even-odd rule over all loops (holes are their own loops)
  for (std::size_t l = 0; l + 1 < f.loop_start.size(); ++l) {
    const std::uint32_t b = f.loop_start[l], e = f.loop_start[l + 1];
    for (std::uint32_t i = b, j = e - 1; i < e; j = i++) {
      const Eigen::Vector2d& a = f.pts[i];
      const Eigen::Vector2d& c = f.pts[j];
      if ((a.y() > q.y()) != (c.y() > q.y()) &&
          q.x() < (c.x() - a.x()) * (q.y() - a.y()) / (c.y() - a.y()) + a.x())
        in = !in;
    }
  }
  return in;
}

bool ModelGeometry::misses_bounding_sphere(const Vec3& origin, const Vec3& dir) const {
  const Vec3 oc = center_ - origin;
  const double along = oc.dot(dir);
  return (oc - along * dir).squaredNorm() > radius_ * radius_ * 1.0001 + 1e-9;
}

void ModelGeometry::front_faces(const Vec3& origin, std::vector<std::uint32_t>& out) const {
  out.clear();
  for (std::size_t i = 0; i < faces_.size(); ++i)
    if (faces_[i].n.dot(origin) > faces_[i].offset) out.push_back(static_cast<std::uint32_t>(i));
}

int ModelGeometry::cast(const Vec3& origin, const Vec3& dir, double& distance,
                        std::span<const std::uint32_t> faces, bool in_sphere) const {
  if (!in_sphere && misses_bounding_sphere(origin, dir)) return -1;
  int best = -1;
  double best_s = std::numeric_limits<double>::infinity();
  for (const std::uint32_t i : faces) {
    const Face& f = faces_[i];
    const double den = f.n.dot(dir);
    if (den >= -1e-9) continue;  // back-facing or grazing
    const double s = (f.offset - f.n.dot(origin)) / den;
    if (s <= 0.0 || s >= best_s) continue;
    const Vec3 h = origin + s * dir;
    if (!inside(f, Eigen::Vector2d(f.u.dot(h), f.v.dot(h)))) continue;
    best_s = s;
    best = static_cast<int>(i);
    if (convex_) break;
  }
  distance = best_s;
  return best;
}

void ModelGeometry::clip_faces(const Vec3& origin, ClipFaces& out) const {
  out.clear();
  for (std::size_t i = 0; i < faces_.size(); ++i) {
    const Face& f = faces_[i];
    out.add(f.n.x(), f.n.y(), f.n.z(), f.n.dot(origin) - f.offset, static_cast<int>(i));
  }
  out.pad();
}

int ModelGeometry::cast_convex(const Vec3& origin, const Vec3& dir, double& distance, const ClipFaces& faces,
                               bool in_sphere) const {
  distance = std::numeric_limits<double>::infinity();
  if (!in_sphere && misses_bounding_sphere(origin, dir)) return -1;
  return clip_convex(faces, dir.x(), dir.y(), dir.z(), distance);
}

int ModelGeometry::cast(const Vec3& origin, const Vec3& dir, double& distance) const {
  return cast(origin, dir, distance, all_faces_);
}

void SampleSet::reserve(std::size_t max_cells) {
  points_.reserve(max_cells);
  rays_.reserve(max_cells);
  cells_.reserve(max_cells);
  blocks_.reserve(max_cells / 16 + 16);
}

Eigen::Vector2d grid_spacing_mm(const OrganizedCloud& cloud) {
  // Mean distance of depth-continuous (< 5 mm) grid neighbours along a row (x) and a column (y), over a
  // subsample.
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  Eigen::Vector2i n = Eigen::Vector2i::Zero();
  if (!cloud.organized || cloud.width < 2 || cloud.height < 2) return Eigen::Vector2d::Zero();
  const std::uint32_t rstep = std::max<std::uint32_t>(1, cloud.height / 64);
  const std::uint32_t cstep = std::max<std::uint32_t>(1, cloud.width / 64);
  for (std::uint32_t r = 0; r + 1 < cloud.height; r += rstep)
    for (std::uint32_t c = 0; c + 1 < cloud.width; c += cstep) {
      const Eigen::Vector3f& p = cloud.at(r, c);
      if (!OrganizedCloud::valid(p)) continue;
      const Eigen::Vector3f& right = cloud.at(r, c + 1);
      const Eigen::Vector3f& down = cloud.at(r + 1, c);
      const float dr = OrganizedCloud::valid(right) ? (right - p).norm() : 5.0f;
      const float dd = OrganizedCloud::valid(down) ? (down - p).norm() : 5.0f;
      if (dr < 5.0f) {
        sum.x() += dr;
        ++n.x();
      }
      if (dd < 5.0f) {
        sum.y() += dd;
        ++n.y();
      }
    }
  return {n.x() > 0 ? sum.x() / n.x() : 0.0, n.y() > 0 ? sum.y() / n.y() : 0.0};
}

SampleSteps sample_steps(const Eigen::Vector2d& grid, int sample_step, double spacing_mm) {
  const auto least = static_cast<std::uint32_t>(std::max(1, sample_step));
  SampleSteps st{least, least};
  if (spacing_mm > 0.0) {
    // No closer than spacing_mm (and no denser than every sample_step-th cell) in either direction.
    if (grid.x() > 0.0)
      st.col = std::max(least, static_cast<std::uint32_t>(std::lround(spacing_mm / grid.x())));
    if (grid.y() > 0.0)
      st.row = std::max(least, static_cast<std::uint32_t>(std::lround(spacing_mm / grid.y())));
  }
  return st;
}

void SampleSet::build(const OrganizedCloud& cloud, SampleSteps steps, int block) {
  points_.clear();
  rays_.clear();
  cells_.clear();
  blocks_.clear();
  viewpoint_ = cloud.viewpoint;
  const Eigen::Vector3f v = cloud.viewpoint.cast<float>();
  const std::uint32_t cstep = std::max<std::uint32_t>(1, steps.col),
                      rstep = std::max<std::uint32_t>(1, steps.row);
  const auto ublock = static_cast<std::uint32_t>(std::max(1, block));
  const std::uint32_t cspan = cstep * ublock, rspan = rstep * ublock;
  for (std::uint32_t r0 = 0; r0 < cloud.height; r0 += rspan) {
    for (std::uint32_t c0 = 0; c0 < cloud.width; c0 += cspan) {
      Block b;
      b.begin = static_cast<std::uint32_t>(points_.size());
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (std::uint32_t r = r0; r < std::min(cloud.height, r0 + rspan); r += rstep)
        for (std::uint32_t c = c0; c < std::min(cloud.width, c0 + cspan); c += cstep) {
          const std::size_t i = cloud.index(r, c);
          const Eigen::Vector3f& p = cloud.points[i];
          if (!OrganizedCloud::valid(p)) continue;
          points_.push_back(p);
          Ray ray;
          const Vec3 w = p.cast<double>() - viewpoint_;
          ray.range = w.norm();
          if (ray.range > 1e-9) ray.dir = w / ray.range;
          rays_.push_back(ray);
          cells_.push_back(static_cast<std::uint32_t>(i));
          sum += (p - v).normalized();
        }
      b.end = static_cast<std::uint32_t>(points_.size());
      if (b.end == b.begin) continue;
      b.dir = sum.normalized();
      float min_cos = 1.0f;
      for (std::uint32_t k = b.begin; k < b.end; ++k)
        min_cos = std::min(min_cos, (points_[k] - v).normalized().dot(b.dir));
      b.angle = std::acos(std::clamp(min_cos, -1.0f, 1.0f)) + 1e-4f;
      blocks_.push_back(b);
    }
  }
}

VerifyResult Verifier::evaluate(const SampleSet& samples, const ModelGeometry& g, const Mat3& R,
                                const Vec3& t, double floor) {
  VerifyResult r;
  inlier_cells_.clear();
  occluded_cells_.clear();
  inlier_sample_.clear();
  inlier_face_.clear();
  const Mat3 Rt = R.transpose();
  const Vec3& view = samples.viewpoint();
  const Vec3 origin_m = Rt * (view - t);
  if (g.convex())
    g.clip_faces(origin_m, clip_);
  else
    g.front_faces(origin_m, front_);
  const double tol = params_.inlier_mm;
  // The object's bounding sphere as seen from the viewpoint.
  const Vec3 cs = R * g.center() + t;
  const double dist = (cs - view).norm();
  if (dist <= g.radius()) return r;  // the sensor inside the object: nothing sensible to verify
  const Eigen::Vector3f dir_obj = ((cs - view) / dist).cast<float>();
  const float ang_obj = static_cast<float>(std::asin(std::min(1.0, g.radius() / dist)));
  // Rays that pass the bounding sphere by (world frame, a little wider than the cast's own test, which
  // decides) are not turned into the model frame: about half of those in the blocks' cones.
  const Vec3 oc = cs - view;
  const double oc2 = oc.squaredNorm();
  const double r2 = g.radius() * g.radius() * 1.001 + 1e-6;
  // Rays this far inside it pass the cast's own test (1.0001 r^2 in the model frame) whatever the two frames'
  // rounding (about 1e-9 mm^2 here): they are marked, and the cast does not test them again.
  const double r2_inside = g.radius() * g.radius() * 0.999;
  constexpr std::uint32_t kInside = 1u << 31;  // sample indices stay far below
  const auto& rays = samples.rays();
  candidates_.clear();
  for (const SampleSet::Block& b : samples.blocks()) {
    const float c = std::clamp(b.dir.dot(dir_obj), -1.0f, 1.0f);
    if (std::acos(c) > b.angle + ang_obj) continue;
    for (std::uint32_t k = b.begin; k < b.end; ++k) {
      const SampleSet::Ray& ray = rays[k];
      if (ray.range <= 1e-9) continue;
      const double along = oc.dot(ray.dir);
      const double off2 = oc2 - along * along;  // squared distance of the sphere's centre from the ray's line
      if (off2 <= r2) candidates_.push_back(off2 <= r2_inside ? k | kInside : k);
    }
  }
  // With a floor, every kCheckEvery samples: the confidence if every sample left were an inlier must still
  // beat it.
  constexpr std::size_t kCheckEvery = 16;
  const double w = params_.occluded_weight;
  const std::size_t n = candidates_.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (floor >= 0.0 && i % kCheckEvery == 0 && i > 0) {
      const double most = static_cast<double>(r.inliers) + static_cast<double>(n - i);
      if (most < (floor - 1e-12) * (most + r.violations + w * r.occluded)) return VerifyResult{};
    }
    const std::uint32_t k = candidates_[i] & ~kInside;
    const bool inside = (candidates_[i] & kInside) != 0;
    const double range = rays[k].range;
    const Vec3 d = Rt * rays[k].dir;  // model frame; the point lies at origin_m + range d
    double s = 0.0;
    const int face =
        g.convex() ? g.cast_convex(origin_m, d, s, clip_, inside) : g.cast(origin_m, d, s, front_, inside);
    if (face < 0) continue;
    ++r.hits;
    if (range > s + tol) {
      ++r.violations;
    } else if (range < s - tol) {
      ++r.occluded;
      occluded_cells_.push_back(samples.cells()[k]);
    } else {
      ++r.inliers;
      inlier_cells_.push_back(samples.cells()[k]);
      inlier_sample_.push_back(k);
      inlier_face_.push_back(face);
    }
  }
  const double denom = static_cast<double>(r.inliers + r.violations) +
                       params_.occluded_weight * static_cast<double>(r.occluded);
  r.confidence = denom > 0 ? static_cast<double>(r.inliers) / denom : 0.0;
  if (r.inliers < params_.min_inliers)
    r.confidence *= static_cast<double>(r.inliers) / static_cast<double>(std::max(1, params_.min_inliers));
  r.coverage = r.hits > 0 ? static_cast<double>(r.inliers) / r.hits : 0.0;
  return r;
}

VerifyResult Verifier::check_above(const SampleSet& samples, const ModelGeometry& g, const Mat3& R,
                                   const Vec3& t, double floor) {
  VerifyResult r = evaluate(samples, g, R, t, std::max(0.0, floor));
  if (r.confidence <= floor) r.confidence = 0.0;
  return r;
}

VerifyResult Verifier::verify(const SampleSet& samples, const ModelGeometry& g, Mat3& R, Vec3& t,
                              bool refine) {
  VerifyResult r = evaluate(samples, g, R, t);
  if (!refine || params_.icp_iterations <= 0) return r;
  const Model& model = g.model();
  const auto& pts = samples.points();
  int iterations = 0;
  for (int it = 0; it < params_.icp_iterations; ++it) {
    if (inlier_sample_.size() < 6) break;
    // Centre for conditioning.
    Vec3 c = Vec3::Zero();
    for (std::uint32_t k : inlier_sample_) c += pts[k].cast<double>();
    c /= static_cast<double>(inlier_sample_.size());
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    int used = 0;
    for (std::size_t k = 0; k < inlier_sample_.size(); ++k) {
      const ModelFace& f = model.faces[static_cast<std::size_t>(inlier_face_[k])];
      const Vec3 n = R * f.normal;
      const double d = f.offset + n.dot(t);
      const Vec3 q = pts[inlier_sample_[k]].cast<double>() - c;
      const double res = n.dot(q) - (d - n.dot(c));
      if (std::abs(res) > params_.icp_max_dist_mm) continue;
      Eigen::Matrix<double, 6, 1> J;
      J << q.cross(n), n;
      A += J * J.transpose();
      b -= J * res;
      ++used;
    }
    if (used < 6) break;
    A.diagonal().array() += 1e-6 * (A.trace() / 6.0 + 1e-12);
    const Eigen::Matrix<double, 6, 1> x = A.ldlt().solve(b);
    const Vec3 w = x.head<3>();
    const Vec3 tau = x.tail<3>();
    const double angle = w.norm();
    const Mat3 Rd = angle > 1e-15 ? Mat3(Eigen::AngleAxisd(angle, w / angle)) : Mat3::Identity();
    // Points moved by y -> Rd (y - c) + tau + c fit the model; move the model by the inverse instead.
    R = nearest_rotation(Rd.transpose() * R);
    t = Rd.transpose() * (t - c - tau) + c;
    iterations = it + 1;
    if (angle < 1e-7 && tau.norm() < 1e-5) break;
    evaluate(samples, g, R, t);
  }
  r = evaluate(samples, g, R, t);
  r.refine_iterations = iterations;
  // RMS of the inliers' plane distances in the final pose.
  double s2 = 0.0;
  for (std::size_t k = 0; k < inlier_sample_.size(); ++k) {
    const ModelFace& f = model.faces[static_cast<std::size_t>(inlier_face_[k])];
    const Vec3 n = R * f.normal;
    const double res = n.dot(pts[inlier_sample_[k]].cast<double>()) - (f.offset + n.dot(t));
    s2 += res * res;
  }
  r.rms_mm = inlier_sample_.empty() ? 0.0 : std::sqrt(s2 / static_cast<double>(inlier_sample_.size()));
  return r;
}

VerifyResult Verifier::verify_sliding(const SampleSet& samples, const SampleSet& search,
                                      const ModelGeometry& g, Mat3& R, Vec3& t, const Vec3& free_dir) {
  VerifyResult r = verify(samples, g, R, t, true);
  const double step = params_.slide_step_mm;
  if (step <= 0.0 || params_.slide_range_mm < step || free_dir.squaredNorm() < 0.25) return r;
  // The planes fix the other directions; the free one came from face centroids, biased when a face is seen
  // only in part (occluded, shadowed, cut by the segmentation). The best fit among the offsets that explain
  // at least as many points: sliding off the seen faces also removes violations (a pose turned a little too
  // far), but loses the points it was matched to.
  const Vec3 u = free_dir.normalized();
  const Vec3 t0 = t;
  const VerifyResult here = evaluate(search, g, R, t0);
  double best = here.confidence, best_off = 0.0;
  const double keep = params_.slide_keep_inliers * here.inliers;
  auto score = [&](double off) {
    const VerifyResult e = evaluate(search, g, R, t0 + off * u);
    if (e.inliers >= keep && e.confidence > best) best = e.confidence, best_off = off;
  };
  const int n = static_cast<int>(params_.slide_range_mm / step);
  for (int k = -n; k <= n; ++k)
    if (k != 0) score(k * step);
  const double centre = best_off;
  score(centre - 0.5 * step);
  score(centre + 0.5 * step);
  const bool moved = best_off != 0.0 && best > here.confidence + params_.slide_gain;
  if (moved) {
    t = t0 + best_off * u;
    const int iterations = r.refine_iterations;
    r = verify(samples, g, R, t, true);  // ICP at the new offset (it may turn the pose a little)
    r.refine_iterations += iterations;
  }
  // Finer steps on the fine samples, from where the pose now is (ICP leaves the free direction alone).
  const Vec3 t1 = t;
  double fine_off = 0.0;
  VerifyResult fine = r;
  if (params_.slide_fine_mm > 0.0)
    for (double h = 0.25 * step; h >= params_.slide_fine_mm; h *= 0.5) {
      const double from = fine_off;
      for (const double off : {from - h, from + h}) {
        const VerifyResult e = evaluate(samples, g, R, t1 + off * u);
        if (e.inliers >= fine.inliers && e.confidence > fine.confidence) fine = e, fine_off = off;
      }
    }
  if (fine_off == 0.0) {
    if (!moved || params_.slide_fine_mm > 0.0)
      evaluate(samples, g, R, t);  // the inlier lists of the pose kept
    return r;
  }
  t = t1 + fine_off * u;
  const int iterations = r.refine_iterations;
  r = verify(samples, g, R, t, true);
  r.refine_iterations += iterations;
  return r;
}

}  // namespace fs::host::rec
