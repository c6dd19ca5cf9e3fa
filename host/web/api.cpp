#include "host/web/api.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include <fmt/format.h>

#include "host/io/cloud_writers.hpp"

namespace fs::host::web {

namespace {

nlohmann::json vec(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json model_json(const Model& m) {
  nlohmann::json faces = nlohmann::json::array();
  for (const ModelFace& f : m.faces) {
    nlohmann::json loops = nlohmann::json::array();
    for (const auto& loop : f.loops) {
      nlohmann::json l = nlohmann::json::array();
      for (const Vec3& p : loop) l.push_back(vec(p));
      loops.push_back(std::move(l));
    }
    faces.push_back({{"normal", vec(f.normal)}, {"loops", std::move(loops)}});
  }
  return {{"center", vec(m.center)}, {"faces", std::move(faces)}, {"symmetry_order", m.symmetry_order()}};
}

nlohmann::json links_json(const ScanInfo& info) {
  nlohmann::json l = nlohmann::json::object();
  const std::string base = fmt::format("/scans/{}/files/", info.id);
  l["points"] = fmt::format("/api/scans/{}/points", info.id);
  if (info.has_report) {
    l["report"] = base + "report/index.html";
    l["segmentation"] = base + "report/segmentation.png";
    l["top_view"] = base + "report/scene.svg";
    l["pfrg"] = base + "report/pfrg.svg";
    l["enm"] = base + "report/enm.svg";
    l["ply"] = base + "report/objects.ply";
  }
  if (info.has_result) l["result"] = base + "result.json";
  if (info.has_recording) l["fscan"] = fmt::format("/scans/{}/recording.fscan", info.id);
  return l;
}

nlohmann::json scan_json(const ScanInfo& info) {
  return {{"id", info.id},           {"scan_id", info.scan_id},
          {"title", info.title},     {"status", info.status},
          {"partial", info.partial}, {"stripes", info.stripes},
          {"steps", info.steps},     {"result_unix_ms", info.result_unix_ms}};
}

template <typename T>
void put(std::string& out, const T& v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));  // little-endian hosts only (x86-64, arm64, armhf)
  out.append(b, sizeof(T));
}

}  // namespace

nlohmann::json status_json(const LiveStatus& s) {
  nlohmann::json j = {{"mode", s.mode},
                      {"connected", s.connected},
                      {"scanning", s.scanning},
                      {"recognizing", s.recognizing},
                      {"scan_id", s.scan_id},
                      {"stripes", s.stripes},
                      {"steps", s.steps},
                      {"stripes_per_s", std::round(s.stripes_per_s * 10.0) / 10.0},
                      {"faults", s.faults},
                      {"last_fault_code", s.last_fault_code},
                      {"connections", s.connections},
                      {"disconnects", s.disconnects},
                      {"protocol_errors", s.protocol_errors},
                      {"frames", s.frames},
                      {"scans", s.scans}};
  if (s.has_loop)
    j["loop"] = {{"lateness_median_us", s.loop.lateness_median_ns / 1000.0},
                 {"lateness_p99_us", s.loop.lateness_p99_ns / 1000.0},
                 {"lateness_max_us", s.loop.lateness_max_ns / 1000.0},
                 {"overruns", s.loop.overruns}};
  else
    j["loop"] = nullptr;
  return j;
}

std::string object_colour(std::size_t o) {
  return fmt::format("#{:06x}", label_colour(static_cast<std::int32_t>(o) + 1) & 0xffffff);
}

nlohmann::json scan_detail_json(const ScanInfo& info, const rec::Recognition& r, const Library& library,
                                const OrganizedCloud& cloud, const Plane* table) {
  nlohmann::json j = rec::to_json(r, library);
  j["scan"] = scan_json(info);
  nlohmann::json models = nlohmann::json::object();
  auto& objects = j["objects"];
  for (std::size_t o = 0; o < r.objects.size(); ++o) {
    const Model& m = library.models[static_cast<std::size_t>(r.objects[o].model)];
    objects[o]["colour"] = object_colour(o);
    objects[o]["index"] = o;
    if (!models.contains(m.name)) models[m.name] = model_json(m);
  }
  j["models"] = std::move(models);
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity()), hi = -lo;
  std::size_t valid = 0;
  for (const auto& p : cloud.points)
    if (OrganizedCloud::valid(p)) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      ++valid;
    }
  if (valid == 0) lo = hi = Eigen::Vector3f::Zero();
  j["bounds"] = {{"min", {lo.x(), lo.y(), lo.z()}}, {"max", {hi.x(), hi.y(), hi.z()}}};
  j["points_total"] = valid;
  j["viewpoint"] = vec(cloud.viewpoint);
  if (table)
    j["table"] = {{"normal", vec(table->n)}, {"d", table->d}};
  else
    j["table"] = nullptr;
  j["links"] = info.id > 0 ? links_json(info) : nlohmann::json::object();
  return j;
}

nlohmann::json scan_summary_json(const ScanInfo& info, const rec::Recognition& r, const Library& library) {
  nlohmann::json j = scan_json(info);
  nlohmann::json objects = nlohmann::json::array();
  for (std::size_t o = 0; o < r.objects.size(); ++o) {
    const rec::Hypothesis& h = r.objects[o];
    objects.push_back({{"model", library.models[static_cast<std::size_t>(h.model)].name},
                       {"instance", h.instance},
                       {"confidence", h.confidence()},
                       {"ambiguous", h.ambiguous()},
                       {"colour", object_colour(o)}});
  }
  j["objects"] = std::move(objects);
  j["recognition_ms"] = r.stats.total_ms;
  if (!r.note.empty()) j["note"] = r.note;
  j["links"] = links_json(info);
  return j;
}

std::string points_blob(const OrganizedCloud& cloud, const std::vector<std::int32_t>& object_labels,
                        const std::vector<std::int32_t>& region_labels, std::size_t max_points) {
  const std::size_t valid = cloud.valid_count();
  const bool grid = cloud.organized && cloud.height > 1;
  std::size_t stride = 1;
  if (max_points > 0)
    while (valid / (grid ? stride * stride : stride) > max_points) ++stride;
  std::vector<std::uint32_t> keep;
  keep.reserve(std::min(valid, max_points > 0 ? max_points + 1 : valid));
  // The stride above assumes the valid points spread evenly; where they do not, thin further until at most
  // max_points are kept (ends: at a stride of the grid's size one point is left).
  for (;; ++stride) {
    keep.clear();
    if (grid) {
      for (std::uint32_t row = 0; row < cloud.height; row += static_cast<std::uint32_t>(stride))
        for (std::uint32_t col = 0; col < cloud.width; col += static_cast<std::uint32_t>(stride)) {
          const std::size_t i = cloud.index(row, col);
          if (OrganizedCloud::valid(cloud.points[i])) keep.push_back(static_cast<std::uint32_t>(i));
        }
    } else {
      for (std::size_t i = 0; i < cloud.points.size(); i += stride)
        if (OrganizedCloud::valid(cloud.points[i])) keep.push_back(static_cast<std::uint32_t>(i));
    }
    if (max_points == 0 || keep.size() <= max_points) break;
  }
  const std::size_t n = keep.size();
  const bool regions = region_labels.size() == cloud.points.size();
  std::string out;
  out.reserve(kPointsHeader + n * 15 + 2);
  out.append("FSPT", 4);
  put(out, std::uint32_t{1});
  put(out, static_cast<std::uint32_t>(n));
  put(out, std::uint32_t{regions ? 1u : 0u});
  Eigen::Vector3f lo = Eigen::Vector3f::Zero(), hi = lo;
  if (n > 0) {
    lo = hi = cloud.points[keep[0]];
    for (std::uint32_t i : keep) {
      lo = lo.cwiseMin(cloud.points[i]);
      hi = hi.cwiseMax(cloud.points[i]);
    }
  }
  for (int k = 0; k < 3; ++k) put(out, lo[k]);
  for (int k = 0; k < 3; ++k) put(out, hi[k]);
  for (std::uint32_t i : keep)
    for (int k = 0; k < 3; ++k) put(out, cloud.points[i][k]);
  for (std::uint32_t i : keep) {
    const std::int32_t o = i < object_labels.size() ? object_labels[i] : -1;
    out.push_back(static_cast<char>(o >= 0 && o < 255 ? o : 255));
  }
  if (regions) {
    if (out.size() % 2) out.push_back('\0');
    for (std::uint32_t i : keep) {
      const std::int32_t g = region_labels[i];
      put(out, static_cast<std::uint16_t>(g >= 0 && g < 0xffff ? g : 0xffff));
    }
  }
  return out;
}

namespace {

// What a record holds of `info`: its ids, time and the two JSON texts.
void set_info(ScanRecord& out, const ScanInfo& info, const OrganizedCloud& cloud,
              const rec::Recognizer& recognizer, const rec::Recognition& r, const Plane* table) {
  out.id = info.id;
  out.scan_id = info.scan_id;
  out.result_unix_ms = info.result_unix_ms;
  out.summary_json = scan_summary_json(info, r, recognizer.library()).dump();
  out.detail_json = scan_detail_json(info, r, recognizer.library(), cloud, table).dump();
}

}  // namespace

std::shared_ptr<ScanRecord> make_record(const ScanInfo& info, const OrganizedCloud& cloud,
                                        const rec::Recognizer& recognizer, const rec::Recognition& r,
                                        const Plane* table) {
  auto rec = std::make_shared<ScanRecord>();
  set_info(*rec, info, cloud, recognizer, r, table);
  std::vector<std::int32_t> objects;
  recognizer.object_labels(cloud, objects);
  rec->points = points_blob(cloud, objects, recognizer.segmentation().labels);
  return rec;
}

std::shared_ptr<ScanRecord> make_record(const ScanInfo& info, const ScanRecord& base,
                                        const OrganizedCloud& cloud, const rec::Recognizer& recognizer,
                                        const rec::Recognition& r, const Plane* table) {
  auto rec = std::make_shared<ScanRecord>(base);
  set_info(*rec, info, cloud, recognizer, r, table);
  return rec;
}

}  // namespace fs::host::web
