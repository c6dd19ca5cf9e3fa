#include "hw-sim/scene/scene.hpp"

#include <cmath>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "common/json_text.hpp"
#include "common/mesh_io.hpp"

namespace fs::sim {
namespace {

using nlohmann::json;

class Fields {
 public:
  explicit Fields(const std::string& source) : source_(source) {}
  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw Error(source_ + ": " + field + ": " + what);
  }
  double number(const json& j, const std::string& field) const {
    if (!j.is_number()) fail(field, "expected a number");
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(field, "not finite");
    return v;
  }
  Vec3 vec3(const json& j, const std::string& field) const {
    if (!j.is_array() || j.size() != 3) fail(field, "expected an array of 3 numbers");
    return {number(j[0], field + "[0]"), number(j[1], field + "[1]"), number(j[2], field + "[2]")};
  }
  Vec3 unit3(const json& j, const std::string& field) const {
    const Vec3 v = vec3(j, field);
    if (v.norm() < 1e-12) fail(field, "zero-length direction");
    return v.normalized();
  }
  Mat3 rotation(const json& j, const std::string& field) const {
    if (!j.is_array() || j.size() != 3) fail(field, "expected a 3x3 array of numbers (3 rows)");
    Mat3 r;
    for (int i = 0; i < 3; ++i) {
      const std::string fi = field + "[" + std::to_string(i) + "]";
      if (!j[static_cast<std::size_t>(i)].is_array() || j[static_cast<std::size_t>(i)].size() != 3)
        fail(fi, "expected a row of 3 numbers");
      for (int k = 0; k < 3; ++k)
        r(i, k) = number(j[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)],
                         fi + "[" + std::to_string(k) + "]");
    }
    if ((r.transpose() * r - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-6 || r.determinant() < 0)
      fail(field, "not a rotation (needs orthonormal rows and determinant +1, within 1e-6)");
    return r;
  }
  Mat3 quaternion(const json& j, const std::string& field) const {
    if (!j.is_array() || j.size() != 4) fail(field, "expected [w, x, y, z]");
    Eigen::Quaterniond q(number(j[0], field + "[0]"), number(j[1], field + "[1]"),
                         number(j[2], field + "[2]"), number(j[3], field + "[3]"));
    if (q.norm() < 1e-9) fail(field, "zero quaternion");
    return q.normalized().toRotationMatrix();
  }
  std::uint32_t count(const json& j, const std::string& field, std::uint32_t min, std::uint32_t max) const {
    if (!j.is_number_integer()) fail(field, "expected an integer");
    const auto v = j.get<long long>();
    if (v < min || v > max)
      fail(field, "must be in [" + std::to_string(min) + ", " + std::to_string(max) + "]");
    return static_cast<std::uint32_t>(v);
  }
  void only_keys(const json& j, const std::string& field, std::initializer_list<const char*> keys) const {
    if (!j.is_object()) fail(field, "expected an object");
    for (auto it = j.begin(); it != j.end(); ++it) {
      bool known = false;
      for (const char* k : keys) known = known || it.key() == k;
      if (!known) fail(field.empty() ? it.key() : field + "." + it.key(), "unknown field");
    }
  }

 private:
  const std::string& source_;
};

void parse_camera(const json& j, CameraModel& cam, const Fields& f) {
  const std::string F = "scanner.camera";
  f.only_keys(
      j, F,
      {"width", "height", "fx", "fy", "cx", "cy", "k1", "k2", "k3", "p1", "p2", "rotation", "position"});
  if (j.contains("width")) cam.width = f.count(j["width"], F + ".width", 16, 16384);
  if (j.contains("height")) cam.height = f.count(j["height"], F + ".height", 16, 16384);
  for (auto [key, ptr] : {std::pair{"fx", &cam.fx},
                          {"fy", &cam.fy},
                          {"cx", &cam.cx},
                          {"cy", &cam.cy},
                          {"k1", &cam.k1},
                          {"k2", &cam.k2},
                          {"k3", &cam.k3},
                          {"p1", &cam.p1},
                          {"p2", &cam.p2}})
    if (j.contains(key)) *ptr = f.number(j[key], F + "." + key);
  if (cam.fx <= 0) f.fail(F + ".fx", "must be positive");
  if (cam.fy <= 0) f.fail(F + ".fy", "must be positive");
  if (j.contains("rotation")) cam.R_world_cam = f.rotation(j["rotation"], F + ".rotation");
  if (j.contains("position")) cam.t_world_cam = f.vec3(j["position"], F + ".position");
}

void parse_laser(const json& j, LaserModel& laser, const Fields& f) {
  const std::string F = "scanner.laser";
  f.only_keys(
      j, F,
      {"axis_point", "axis_dir", "normal_at_zero", "optical_gain", "mirror_angle_at_step0", "rad_per_step"});
  if (j.contains("axis_point")) laser.axis_point = f.vec3(j["axis_point"], F + ".axis_point");
  if (j.contains("axis_dir")) laser.axis_dir = f.unit3(j["axis_dir"], F + ".axis_dir");
  if (j.contains("normal_at_zero"))
    laser.normal_at_zero = f.unit3(j["normal_at_zero"], F + ".normal_at_zero");
  if (std::abs(laser.normal_at_zero.dot(laser.axis_dir)) > 1e-6)
    f.fail(F + ".normal_at_zero", "must be perpendicular to axis_dir (the plane contains the mirror axis)");
  if (j.contains("optical_gain")) laser.optical_gain = f.number(j["optical_gain"], F + ".optical_gain");
  if (j.contains("mirror_angle_at_step0"))
    laser.mirror_angle_at_step0 = f.number(j["mirror_angle_at_step0"], F + ".mirror_angle_at_step0");
  if (j.contains("rad_per_step")) laser.rad_per_step = f.number(j["rad_per_step"], F + ".rad_per_step");
}

}  // namespace

void add_object(Scene& scene, Mesh mesh, const Mat3& rotation, const Vec3& translation, double scale) {
  SceneObject o;
  o.name = mesh.name;
  o.rotation = rotation;
  o.translation = translation;
  o.scale = scale;
  // Outward normals: a mesh with negative signed volume has inward-wound faces.
  const bool flip = mesh_signed_volume(mesh) < 0.0;
  o.bounds.setEmpty();
  o.faces.reserve(mesh.faces.size());
  for (std::size_t fi = 0; fi < mesh.faces.size(); ++fi) {
    const auto& face = mesh.faces[fi];
    WorldFace wf;
    wf.polygon.reserve(face.size());
    for (auto idx : face) {
      const Vec3 x = rotation * (scale * mesh.vertices.at(idx)) + translation;
      if (!x.allFinite() || x.cwiseAbs().maxCoeff() > 1e9)
        throw Error(scene.source + ": mesh '" + mesh.name + "': the pose puts vertex " + std::to_string(idx) +
                    " out of range (|coordinate| > 1e9 mm)");
      wf.polygon.push_back(x);
      o.bounds.extend(x);
    }
    if (flip) std::reverse(wf.polygon.begin(), wf.polygon.end());
    // Newell's method: robust normal of a planar polygon, length = 2 * area.
    Vec3 n = Vec3::Zero();
    Vec3 centroid = Vec3::Zero();
    for (std::size_t k = 0; k < wf.polygon.size(); ++k) {
      const Vec3& a = wf.polygon[k];
      const Vec3& b = wf.polygon[(k + 1) % wf.polygon.size()];
      n += a.cross(b);
      centroid += a;
    }
    centroid /= static_cast<double>(wf.polygon.size());
    wf.area = 0.5 * n.norm();
    if (!(wf.area >= 1e-9))
      throw Error(scene.source + ": mesh '" + mesh.name + "' face " + std::to_string(fi) + " has no area");
    wf.plane.n = n.normalized();
    wf.plane.d = wf.plane.n.dot(centroid);
    o.faces.push_back(std::move(wf));
  }
  o.mesh = std::move(mesh);
  scene.objects.push_back(std::move(o));
}

void resample_sweep(ScannerCalibration& c, std::uint32_t steps) {
  if (steps == 0) throw Error("resample_sweep: zero steps");
  const double first = c.laser.mirror_angle(c.first_step);
  const double last =
      c.laser.mirror_angle(static_cast<double>(c.first_step) + (c.step_count > 0 ? c.step_count - 1 : 0));
  c.step_count = steps;
  c.laser.rad_per_step = steps > 1 ? (last - first) / static_cast<double>(steps - 1) : 0.0;
  c.laser.mirror_angle_at_step0 = first - static_cast<double>(c.first_step) * c.laser.rad_per_step;
}

Scene parse_scene(const json& doc, const std::filesystem::path& base_dir, const std::string& source) {
  Scene scene;
  scene.source = source;
  const Fields f(scene.source);
  f.only_keys(doc, "", {"objects", "table", "scanner", "name", "description", "comment"});

  if (doc.contains("scanner")) {
    const json& s = doc["scanner"];
    f.only_keys(s, "scanner", {"steps", "first_step", "camera", "laser"});
    const std::uint32_t steps = s.contains("steps") ? f.count(s["steps"], "scanner.steps", 1, 100000) : 500;
    scene.calibration = ScannerCalibration::bench_default(steps);
    if (s.contains("first_step")) {
      if (!s["first_step"].is_number_integer()) f.fail("scanner.first_step", "expected an integer");
      scene.calibration.first_step = s["first_step"].get<std::int32_t>();
    }
    if (s.contains("camera")) parse_camera(s["camera"], scene.calibration.camera, f);
    if (s.contains("laser")) parse_laser(s["laser"], scene.calibration.laser, f);
  }

  if (doc.contains("table")) {
    const json& t = doc["table"];
    if (t.is_boolean()) {
      scene.has_table = t.get<bool>();
    } else {
      f.only_keys(t, "table", {"normal", "d"});
      if (t.contains("normal")) scene.calibration.table.n = f.unit3(t["normal"], "table.normal");
      if (t.contains("d")) scene.calibration.table.d = f.number(t["d"], "table.d");
    }
  }

  if (!doc.contains("objects")) f.fail("objects", "missing (an array of objects, may be empty)");
  const json& objs = doc["objects"];
  if (!objs.is_array()) f.fail("objects", "expected an array");
  for (std::size_t i = 0; i < objs.size(); ++i) {
    const std::string F = "objects[" + std::to_string(i) + "]";
    const json& o = objs[i];
    f.only_keys(o, F, {"model", "rotation", "quaternion", "translation", "scale", "name"});
    if (!o.contains("model") || !o["model"].is_string())
      f.fail(F + ".model", "expected a mesh path (string)");
    std::filesystem::path model = o["model"].get<std::string>();
    if (model.empty()) f.fail(F + ".model", "empty path");
    if (!model.has_extension() && !model.has_parent_path())
      model = std::filesystem::path("meshes") / (model.string() + ".off");
    const std::filesystem::path resolved = model.is_absolute() ? model : base_dir / model;
    if (o.contains("rotation") && o.contains("quaternion"))
      f.fail(F, "give either rotation or quaternion, not both");
    Mat3 r = Mat3::Identity();
    if (o.contains("rotation")) r = f.rotation(o["rotation"], F + ".rotation");
    if (o.contains("quaternion")) r = f.quaternion(o["quaternion"], F + ".quaternion");
    const Vec3 t = o.contains("translation") ? f.vec3(o["translation"], F + ".translation") : Vec3::Zero();
    const double scale = o.contains("scale") ? f.number(o["scale"], F + ".scale") : 1.0;
    if (scale <= 0) f.fail(F + ".scale", "must be positive");
    Mesh mesh;
    try {
      mesh = read_mesh(resolved);
    } catch (const Error& e) {
      f.fail(F + ".model", e.what());
    }
    if (o.contains("name")) {
      if (!o["name"].is_string()) f.fail(F + ".name", "expected a string");
      mesh.name = o["name"].get<std::string>();
    }
    try {
      add_object(scene, std::move(mesh), r, t, scale);
    } catch (const Error& e) {
      f.fail(F + ".model", e.what());
    }
    scene.objects.back().model = resolved;
  }
  return scene;
}

Scene load_scene(const std::filesystem::path& path) {
  return parse_scene(parse_json_text(read_input_file(path, kMaxConfigFileBytes, "scene file"), path.string()),
                     path.parent_path(), path.string());
}

}  // namespace fs::sim
