// PFRG JSON reading/writing with validation (contract: DESIGN.md "PFRG JSON").
#include "host/pfrg/pfrg.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <unordered_set>
#include <utility>

#include <nlohmann/json.hpp>

#include "common/error.hpp"
#include "common/input_file.hpp"
#include "common/json_text.hpp"

namespace fs::host {

namespace {

using nlohmann::json;

[[noreturn]] void fail(const std::string& source, const std::string& field, const std::string& what) {
  throw Error(source + ": " + field + ": " + what);
}

double get_number(const json& obj, const char* key, const std::string& source, const std::string& where,
                  bool required, double fallback) {
  auto it = obj.find(key);
  if (it == obj.end()) {
    if (required) fail(source, where + "." + key, "missing");
    return fallback;
  }
  if (!it->is_number())
    fail(source, where + "." + key, "expected a number, got " + std::string(it->type_name()));
  double v = it->get<double>();
  if (!std::isfinite(v)) fail(source, where + "." + key, "not finite");
  return v;
}

int get_int(const json& obj, const char* key, const std::string& source, const std::string& where) {
  auto it = obj.find(key);
  if (it == obj.end()) fail(source, where + "." + key, "missing");
  if (!it->is_number_integer()) fail(source, where + "." + key, "expected an integer");
  auto v = it->get<std::int64_t>();
  if (v < -1'000'000'000 || v > 1'000'000'000) fail(source, where + "." + key, "out of range");
  return static_cast<int>(v);
}

Vec3 get_vec3(const json& v, const std::string& source, const std::string& field) {
  if (!v.is_array() || v.size() != 3) fail(source, field, "expected an array of 3 numbers");
  Vec3 out;
  for (int i = 0; i < 3; ++i) {
    if (!v[static_cast<std::size_t>(i)].is_number()) fail(source, field, "expected an array of 3 numbers");
    out[i] = v[static_cast<std::size_t>(i)].get<double>();
    if (!std::isfinite(out[i])) fail(source, field, "not finite");
  }
  return out;
}

json vec_json(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

}  // namespace

const PfrgNode* Pfrg::find(int id) const {
  for (const auto& n : nodes)
    if (n.id == id) return &n;
  return nullptr;
}

json to_json(const Pfrg& g) {
  json j = json::object();
  if (!g.name.empty()) j["name"] = g.name;
  json nodes = json::array();
  for (const auto& n : g.nodes) {
    json o = json::object();
    o["id"] = n.id;
    if (n.supernode) {
      o["supernode"] = true;
    } else {
      o["area"] = n.area;
      o["normal"] = vec_json(n.normal);
      if (n.has_plane) {
        o["offset"] = n.offset;
        o["centroid"] = vec_json(n.centroid);
      }
    }
    nodes.push_back(std::move(o));
  }
  j["nodes"] = std::move(nodes);
  json arcs = json::array();
  for (const auto& a : g.arcs) arcs.push_back(json{{"a", a.a}, {"b", a.b}, {"border", a.border}});
  j["arcs"] = std::move(arcs);
  if (g.has_observer) j["observer"] = vec_json(g.observer);
  return j;
}

Pfrg pfrg_from_json(const json& j, const std::string& source) {
  if (!j.is_object()) fail(source, "(top level)", "expected an object");
  Pfrg g;
  if (auto it = j.find("name"); it != j.end()) {
    if (!it->is_string()) fail(source, "name", "expected a string");
    g.name = it->get<std::string>();
  }
  auto nit = j.find("nodes");
  if (nit == j.end()) fail(source, "nodes", "missing");
  if (!nit->is_array()) fail(source, "nodes", "expected an array");
  std::unordered_set<int> ids;
  g.nodes.reserve(nit->size());
  for (std::size_t i = 0; i < nit->size(); ++i) {
    const json& o = (*nit)[i];
    const std::string where = "nodes[" + std::to_string(i) + "]";
    if (!o.is_object()) fail(source, where, "expected an object");
    PfrgNode n;
    n.id = get_int(o, "id", source, where);
    if (!ids.insert(n.id).second) fail(source, where + ".id", "duplicate node id " + std::to_string(n.id));
    if (auto s = o.find("supernode"); s != o.end()) {
      if (!s->is_boolean()) fail(source, where + ".supernode", "expected true or false");
      n.supernode = s->get<bool>();
    }
    if (!n.supernode) {
      n.area = get_number(o, "area", source, where, true, 0.0);
      if (n.area < 0) fail(source, where + ".area", "negative");
      auto nn = o.find("normal");
      if (nn == o.end()) fail(source, where + ".normal", "missing");
      n.normal = get_vec3(*nn, source, where + ".normal");
      const double len = n.normal.norm();
      if (!(len > 1e-12)) fail(source, where + ".normal", "zero length");
      n.normal /= len;
      auto off = o.find("offset");
      auto cen = o.find("centroid");
      if (off != o.end() || cen != o.end()) {
        n.offset = get_number(o, "offset", source, where, true, 0.0);
        if (cen == o.end()) fail(source, where + ".centroid", "missing (offset given)");
        n.centroid = get_vec3(*cen, source, where + ".centroid");
        n.has_plane = true;
      }
    }
    g.nodes.push_back(n);
  }
  auto ait = j.find("arcs");
  if (ait != j.end()) {
    if (!ait->is_array()) fail(source, "arcs", "expected an array");
    std::set<std::pair<int, int>> seen;
    g.arcs.reserve(ait->size());
    for (std::size_t i = 0; i < ait->size(); ++i) {
      const json& o = (*ait)[i];
      const std::string where = "arcs[" + std::to_string(i) + "]";
      if (!o.is_object()) fail(source, where, "expected an object");
      PfrgArc a;
      a.a = get_int(o, "a", source, where);
      a.b = get_int(o, "b", source, where);
      a.border = get_number(o, "border", source, where, false, 0.0);
      if (a.border < 0) fail(source, where + ".border", "negative");
      if (!ids.count(a.a)) fail(source, where + ".a", "unknown node id " + std::to_string(a.a));
      if (!ids.count(a.b)) fail(source, where + ".b", "unknown node id " + std::to_string(a.b));
      if (a.a == a.b) fail(source, where, "arc from node " + std::to_string(a.a) + " to itself");
      if (!seen.insert({std::min(a.a, a.b), std::max(a.a, a.b)}).second)
        fail(source, where, "duplicate arc " + std::to_string(a.a) + "-" + std::to_string(a.b));
      g.arcs.push_back(a);
    }
  }
  if (auto o = j.find("observer"); o != j.end()) {
    g.observer = get_vec3(*o, source, "observer");
    const double len = g.observer.norm();
    if (!(len > 1e-12)) fail(source, "observer", "zero length");
    g.observer /= len;
    g.has_observer = true;
  }
  return g;
}

Pfrg read_pfrg_json(const std::filesystem::path& path) {
  const json j = parse_json_text(read_input_file(path, kMaxGraphFileBytes, "PFRG JSON file"), path.string());
  Pfrg g = pfrg_from_json(j, path.string());
  if (g.name.empty()) g.name = path.stem().string();
  return g;
}

void write_pfrg_json(const Pfrg& g, const std::filesystem::path& path) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error(path.string() + ": cannot open for writing");
  out << to_json(g).dump(1) << "\n";
  if (!out) throw Error(path.string() + ": write failed");
}

}  // namespace fs::host
