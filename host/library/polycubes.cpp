// Polycube enumeration (grow by one cube + canonical form) and their surfaces.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <set>

#include <fmt/format.h>

#include "common/error.hpp"
#include "host/library/polycubes.hpp"

namespace fs::host {
namespace {

Polycube normalized(Polycube c) {
  Cell lo{INT32_MAX, INT32_MAX, INT32_MAX};
  for (const auto& x : c)
    for (int k = 0; k < 3; ++k)
      lo[static_cast<std::size_t>(k)] =
          std::min(lo[static_cast<std::size_t>(k)], x[static_cast<std::size_t>(k)]);
  for (auto& x : c)
    for (std::size_t k = 0; k < 3; ++k) x[k] -= lo[k];
  std::sort(c.begin(), c.end());
  return c;
}

Polycube rotated(const Polycube& c, const Mat3& R) {
  Polycube out(c.size());
  for (std::size_t i = 0; i < c.size(); ++i)
    for (int r = 0; r < 3; ++r) {
      int v = 0;
      for (int k = 0; k < 3; ++k) v += static_cast<int>(R(r, k)) * c[i][static_cast<std::size_t>(k)];
      out[i][static_cast<std::size_t>(r)] = v;
    }
  return normalized(std::move(out));
}

constexpr std::array<Cell, 6> kDirs{{{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}}};

}  // namespace

const std::array<Mat3, 24>& cube_rotations() {
  static const std::array<Mat3, 24> rots = [] {
    std::array<Mat3, 24> out{};
    std::size_t n = 0;
    std::array<int, 3> perm{0, 1, 2};
    do {
      for (int s = 0; s < 8; ++s) {
        Mat3 R = Mat3::Zero();
        for (int r = 0; r < 3; ++r) R(r, perm[static_cast<std::size_t>(r)]) = (s >> r) & 1 ? -1.0 : 1.0;
        if (R.determinant() > 0) out[n++] = R;
      }
    } while (std::next_permutation(perm.begin(), perm.end()));
    return out;
  }();
  return rots;
}

Polycube canonical_polycube(const Polycube& cells) {
  Polycube best;
  for (const auto& R : cube_rotations()) {
    Polycube c = rotated(cells, R);
    if (best.empty() || c < best) best = std::move(c);
  }
  return best;
}

int polycube_symmetry_order(const Polycube& cells) {
  const Polycube base = normalized(cells);
  int n = 0;
  for (const auto& R : cube_rotations()) n += rotated(cells, R) == base;
  return n;
}

std::vector<std::vector<Polycube>> enumerate_polycubes(int max_volume) {
  if (max_volume < 1 || max_volume > 10)
    throw Error(fmt::format("polycubes: max volume must be in [1, 10] (got {})", max_volume));
  std::vector<std::vector<Polycube>> out;
  out.push_back({Polycube{{0, 0, 0}}});
  for (int v = 2; v <= max_volume; ++v) {
    std::set<Polycube> next;
    for (const auto& p : out.back()) {
      const std::set<Cell> occupied(p.begin(), p.end());
      std::set<Cell> tried;
      for (const auto& c : p)
        for (const auto& d : kDirs) {
          const Cell n{c[0] + d[0], c[1] + d[1], c[2] + d[2]};
          if (occupied.count(n) || !tried.insert(n).second) continue;
          Polycube grown = p;
          grown.push_back(n);
          next.insert(canonical_polycube(grown));
        }
    }
    out.emplace_back(next.begin(), next.end());
  }
  return out;
}

Mesh polycube_mesh(const Polycube& cells, double edge, const std::string& name) {
  Mesh m;
  m.name = name;
  const std::set<Cell> occupied(cells.begin(), cells.end());
  std::map<Cell, std::uint32_t> index;
  auto vertex = [&](const Cell& p) {
    auto [it, fresh] = index.emplace(p, static_cast<std::uint32_t>(m.vertices.size()));
    if (fresh) m.vertices.emplace_back(edge * p[0], edge * p[1], edge * p[2]);
    return it->second;
  };
  for (const auto& c : cells)
    for (std::size_t a = 0; a < 3; ++a)
      for (int s : {1, -1}) {
        Cell n = c;
        n[a] += s;
        if (occupied.count(n)) continue;
        const std::size_t b = (a + 1) % 3, cc = (a + 2) % 3;  // e_b x e_c = e_a
        static constexpr int kCorner[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        std::vector<std::uint32_t> quad;
        for (int k = 0; k < 4; ++k) {
          const int q = s > 0 ? k : 3 - k;  // counter-clockwise about the outward normal s * e_a
          Cell p = c;
          p[a] += s > 0 ? 1 : 0;
          p[b] += kCorner[q][0];
          p[cc] += kCorner[q][1];
          quad.push_back(vertex(p));
        }
        m.faces.push_back(std::move(quad));
      }
  return m;
}

std::string polycube_name(int volume, std::size_t index) {
  return fmt::format("polycube-{}-{:03}", volume, index);
}

Model polycube_model(const Polycube& cells, double edge, const std::string& name) {
  return build_model(polycube_mesh(cells, edge, name));
}

std::vector<Model> polycube_models(const std::vector<std::vector<Polycube>>& all, double edge,
                                   const std::function<void(std::size_t, const std::string&)>& before) {
  std::vector<Model> out;
  for (std::size_t v = 0; v < all.size(); ++v)
    for (std::size_t i = 0; i < all[v].size(); ++i) {
      const std::string name = polycube_name(static_cast<int>(v + 1), i + 1);
      if (before) before(out.size(), name);
      out.push_back(polycube_model(all[v][i], edge, name));
    }
  return out;
}

std::optional<PolycubeId> parse_polycube_name(std::string_view name) {
  constexpr std::string_view kPrefix = "polycube-";
  if (name.substr(0, kPrefix.size()) != kPrefix) return std::nullopt;
  name.remove_prefix(kPrefix.size());
  const std::size_t dash = name.find('-');
  if (dash == std::string_view::npos || dash == 0 || dash + 1 == name.size()) return std::nullopt;
  PolycubeId id;
  const char* vend = name.data() + dash;
  const auto v = std::from_chars(name.data(), vend, id.volume);
  const char* end = name.data() + name.size();
  const auto i = std::from_chars(vend + 1, end, id.index);
  if (v.ec != std::errc() || v.ptr != vend || i.ec != std::errc() || i.ptr != end) return std::nullopt;
  if (id.volume < 1 || id.index < 1) return std::nullopt;
  return id;
}

Mesh polycube_mesh_of(const Model& model, const std::vector<std::vector<Polycube>>& generated,
                      const std::string& source) {
  const auto fail = [&](const std::string& what) {
    return Error(fmt::format("{}: model '{}': {}", source, model.name, what));
  };
  const auto id = parse_polycube_name(model.name);
  if (!id) throw fail("not a polycube (names are polycube-<volume>-<index>)");
  const auto v = static_cast<std::size_t>(id->volume);
  if (v > generated.size() || id->index > generated[v - 1].size())
    throw fail(fmt::format("no such polycube among the generated ones (volume <= {})", generated.size()));
  const Polycube& cells = generated[v - 1][id->index - 1];
  // The edge from the model's bounding box (exact for the generator's coordinates, edge x integer).
  Eigen::AlignedBox3d box_model;
  for (const auto& f : model.faces)
    for (const auto& loop : f.loops)
      for (const auto& p : loop) box_model.extend(p);
  int cells_extent = 0;
  for (const Cell& c : cells)
    for (int k : c) cells_extent = std::max(cells_extent, k + 1);
  const double edge = box_model.isEmpty() ? 0.0 : box_model.sizes().maxCoeff() / cells_extent;
  if (!(edge > 0)) throw fail("no extent");
  Mesh mesh = polycube_mesh(cells, edge, model.name);
  // The model's faces must be the mesh's: the same bounding box, total area and volume (a library of another
  // generator, or an edited name, fails here).
  Eigen::AlignedBox3d box_mesh;
  for (const auto& p : mesh.vertices) box_mesh.extend(p);
  const double area = static_cast<double>(mesh.faces.size()) * edge * edge;  // unit squares
  const double volume = static_cast<double>(v) * edge * edge * edge;
  const double tol = 1e-6 * edge;
  if (std::abs(area - model.total_area) > 1e-6 * area || std::abs(volume - model.volume) > 1e-6 * volume ||
      (box_mesh.min() - box_model.min()).cwiseAbs().maxCoeff() > tol ||
      (box_mesh.max() - box_model.max()).cwiseAbs().maxCoeff() > tol)
    throw fail(fmt::format("its faces are not those of the generator's polycube {}-{}", v, id->index));
  return mesh;
}

}  // namespace fs::host
