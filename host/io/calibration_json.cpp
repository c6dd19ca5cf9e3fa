#include "host/io/calibration_json.hpp"

#include <cmath>
#include <fstream>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "common/json_text.hpp"

namespace fs::host {
namespace {

using nlohmann::json;

json vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

struct Reader {
  const std::string& source;
  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw Error(source + ": " + field + ": " + what);
  }
  const json& member(const json& obj, const std::string& parent, const char* key) const {
    if (!obj.is_object()) fail(parent, "is not an object");
    const auto it = obj.find(key);
    if (it == obj.end()) fail(parent.empty() ? key : parent + "." + key, "missing");
    return *it;
  }
  double num(const json& obj, const std::string& parent, const char* key) const {
    const json& v = member(obj, parent, key);
    const std::string f = parent.empty() ? key : parent + "." + key;
    if (!v.is_number()) fail(f, "is not a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(f, "is not finite");
    return d;
  }
  std::uint64_t uint(const json& obj, const std::string& parent, const char* key, std::uint64_t max) const {
    const json& v = member(obj, parent, key);
    const std::string f = parent.empty() ? key : parent + "." + key;
    if (!v.is_number_integer() || (v.is_number_integer() && v.get<std::int64_t>() < 0))
      fail(f, "is not a non-negative integer");
    const auto u = v.get<std::uint64_t>();
    if (u > max) fail(f, std::to_string(u) + " exceeds " + std::to_string(max));
    return u;
  }
  Vec3 vec3(const json& obj, const std::string& parent, const char* key) const {
    const json& v = member(obj, parent, key);
    const std::string f = parent + "." + key;
    if (!v.is_array() || v.size() != 3) fail(f, "must be an array of 3 numbers");
    Vec3 out;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>()))
        fail(f, "must be an array of 3 finite numbers");
      out[i] = v[i].get<double>();
    }
    return out;
  }
  Vec3 unit3(const json& obj, const std::string& parent, const char* key) const {
    const Vec3 v = vec3(obj, parent, key);
    if (v.norm() < 1e-9) fail(parent + "." + key, "must not be the zero vector");
    return std::abs(v.norm() - 1.0) < 1e-12 ? v : v.normalized();  // keep written unit vectors bit-exact
  }
};

}  // namespace

nlohmann::json calibration_to_json(const ScannerCalibration& c) {
  const auto& cam = c.camera;
  json R = json::array();
  for (int r = 0; r < 3; ++r)
    R.push_back(json::array({cam.R_world_cam(r, 0), cam.R_world_cam(r, 1), cam.R_world_cam(r, 2)}));
  return json{{"format", "facetscan-calibration"},
              {"version", 1},
              {"units", "mm"},
              {"camera",
               {{"width", cam.width},
                {"height", cam.height},
                {"fx", cam.fx},
                {"fy", cam.fy},
                {"cx", cam.cx},
                {"cy", cam.cy},
                {"k1", cam.k1},
                {"k2", cam.k2},
                {"k3", cam.k3},
                {"p1", cam.p1},
                {"p2", cam.p2},
                {"R_world_cam", R},
                {"t_world_cam", vec(cam.t_world_cam)}}},
              {"laser",
               {{"axis_point", vec(c.laser.axis_point)},
                {"axis_dir", vec(c.laser.axis_dir)},
                {"normal_at_zero", vec(c.laser.normal_at_zero)},
                {"optical_gain", c.laser.optical_gain},
                {"mirror_angle_at_step0", c.laser.mirror_angle_at_step0},
                {"rad_per_step", c.laser.rad_per_step}}},
              {"first_step", c.first_step},
              {"step_count", c.step_count},
              {"table", {{"n", vec(c.table.n)}, {"d", c.table.d}}}};
}

ScannerCalibration calibration_from_json(const nlohmann::json& j, const std::string& source) {
  Reader r{source};
  if (!j.is_object()) r.fail("(top level)", "is not a JSON object");
  if (j.contains("format") && j["format"] != "facetscan-calibration")
    r.fail("format", "is not \"facetscan-calibration\"");
  if (j.contains("version") && (!j["version"].is_number_integer() || j["version"].get<int>() != 1))
    r.fail("version", "unsupported (expected 1)");
  if (j.contains("units") && j["units"] != "mm") r.fail("units", "must be \"mm\"");
  ScannerCalibration c;
  const json& cam = r.member(j, "", "camera");
  c.camera.width = static_cast<std::uint32_t>(r.uint(cam, "camera", "width", 16384));
  c.camera.height = static_cast<std::uint32_t>(r.uint(cam, "camera", "height", 16384));
  if (c.camera.width == 0 || c.camera.height == 0) r.fail("camera.width/height", "must be positive");
  c.camera.fx = r.num(cam, "camera", "fx");
  c.camera.fy = r.num(cam, "camera", "fy");
  if (c.camera.fx <= 0 || c.camera.fy <= 0) r.fail("camera.fx/fy", "must be positive");
  c.camera.cx = r.num(cam, "camera", "cx");
  c.camera.cy = r.num(cam, "camera", "cy");
  for (const char* k : {"k1", "k2", "k3", "p1", "p2"}) {
    double& dst = k[0] == 'k' ? (k[1] == '1'   ? c.camera.k1
                                 : k[1] == '2' ? c.camera.k2
                                               : c.camera.k3)
                              : (k[1] == '1' ? c.camera.p1 : c.camera.p2);
    dst = cam.contains(k) ? r.num(cam, "camera", k) : 0.0;
  }
  const json& R = r.member(cam, "camera", "R_world_cam");
  if (!R.is_array() || R.size() != 3) r.fail("camera.R_world_cam", "must be a 3x3 array");
  for (int i = 0; i < 3; ++i) {
    if (!R[i].is_array() || R[i].size() != 3) r.fail("camera.R_world_cam", "must be a 3x3 array");
    for (int k = 0; k < 3; ++k) {
      if (!R[i][k].is_number() || !std::isfinite(R[i][k].get<double>()))
        r.fail("camera.R_world_cam", "must hold finite numbers");
      c.camera.R_world_cam(i, k) = R[i][k].get<double>();
    }
  }
  if ((c.camera.R_world_cam.transpose() * c.camera.R_world_cam - Mat3::Identity()).norm() > 1e-6 ||
      c.camera.R_world_cam.determinant() < 0)
    r.fail("camera.R_world_cam", "is not a rotation matrix");
  c.camera.t_world_cam = r.vec3(cam, "camera", "t_world_cam");
  const json& las = r.member(j, "", "laser");
  c.laser.axis_point = r.vec3(las, "laser", "axis_point");
  c.laser.axis_dir = r.unit3(las, "laser", "axis_dir");
  c.laser.normal_at_zero = r.unit3(las, "laser", "normal_at_zero");
  if (std::abs(c.laser.axis_dir.dot(c.laser.normal_at_zero)) > 1e-3)
    r.fail("laser.normal_at_zero", "must be perpendicular to laser.axis_dir");
  c.laser.optical_gain = las.contains("optical_gain") ? r.num(las, "laser", "optical_gain") : 2.0;
  c.laser.mirror_angle_at_step0 = r.num(las, "laser", "mirror_angle_at_step0");
  c.laser.rad_per_step = r.num(las, "laser", "rad_per_step");
  const json& fs = r.member(j, "", "first_step");
  if (!fs.is_number_integer() || std::abs(fs.get<std::int64_t>()) > (1 << 30))
    r.fail("first_step", "is not an integer in range");
  c.first_step = static_cast<std::int32_t>(fs.get<std::int64_t>());
  c.step_count = static_cast<std::uint32_t>(r.uint(j, "", "step_count", 65536));
  if (c.step_count == 0) r.fail("step_count", "must be positive");
  if (j.contains("table")) {
    c.table.n = r.unit3(j["table"], "table", "n");
    c.table.d = r.num(j["table"], "table", "d");
  }
  return c;
}

ScannerCalibration read_calibration_file(const std::string& path) {
  return calibration_from_json(
      parse_json_text(read_input_file(path, kMaxConfigFileBytes, "calibration file"), path), path);
}

void write_calibration_file(const std::string& path, const ScannerCalibration& c,
                            const nlohmann::json& extra) {
  nlohmann::json j = calibration_to_json(c);
  for (auto it = extra.begin(); it != extra.end(); ++it) j[it.key()] = it.value();
  std::ofstream f(path, std::ios::trunc);
  if (!f) throw Error(path + ": cannot open for writing");
  f << j.dump(2) << "\n";
  if (!f) throw Error(path + ": write error");
}

}  // namespace fs::host
