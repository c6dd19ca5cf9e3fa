// Library container and the .fslib binary file (layout in library.hpp).
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string_view>
#include <unordered_set>

#include <fmt/format.h>

#include "common/byte_io.hpp"
#include "common/crc32_ieee.hpp"
#include "common/error.hpp"
#include "common/input_file.hpp"
#include "host/library/library.hpp"

namespace fs::host {
namespace {

constexpr std::array<std::uint8_t, 8> kMagic{'F', 'S', 'L', 'I', 'B', '\r', '\n', 0x1a};
constexpr std::size_t kHeaderSize = 8 + 4 + 4 + 8 + 4;

struct Writer {
  std::vector<std::uint8_t> out;
  void u8(std::uint8_t v) { out.push_back(v); }
  void u32(std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void u64(std::uint64_t v) {
    for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void f64(double v) { u64(std::bit_cast<std::uint64_t>(v)); }
  void f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }
  void vec(const Vec3& v) {
    f64(v.x());
    f64(v.y());
    f64(v.z());
  }
  void str(const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size()));
    out.insert(out.end(), s.begin(), s.end());
  }
};

struct Reader {
  std::span<const std::uint8_t> b;
  std::size_t pos;
  const std::string& src;

  Error fail(const std::string& what) const { return error_at_offset(src, pos, what); }
  void need(std::size_t n, const char* what) const {
    if (b.size() - pos < n)
      throw fail(fmt::format("truncated: {} needs {} bytes, {} left", what, n, b.size() - pos));
  }
  std::uint8_t u8(const char* what) {
    need(1, what);
    return b[pos++];
  }
  std::uint32_t u32(const char* what) {
    need(4, what);
    pos += 4;
    return load_le<std::uint32_t>(b.data() + pos - 4);
  }
  std::uint64_t u64(const char* what) {
    need(8, what);
    pos += 8;
    return load_le<std::uint64_t>(b.data() + pos - 8);
  }
  double f64(const char* what) {
    const std::size_t at = pos;
    const double v = std::bit_cast<double>(u64(what));
    if (!std::isfinite(v)) throw error_at_offset(src, at, fmt::format("{} is not a finite number", what));
    return v;
  }
  float f32(const char* what) {
    const std::size_t at = pos;
    const float v = std::bit_cast<float>(u32(what));
    if (!std::isfinite(v)) throw error_at_offset(src, at, fmt::format("{} is not a finite number", what));
    return v;
  }
  Vec3 vec(const char* what) {
    need(24, what);
    Vec3 v;
    for (int i = 0; i < 3; ++i) {
      v[i] = load_le<double>(b.data() + pos + 8 * static_cast<std::size_t>(i));
      if (!std::isfinite(v[i]))
        throw error_at_offset(src, pos + 8 * static_cast<std::size_t>(i),
                              fmt::format("{} is not a finite number", what));
    }
    pos += 24;
    return v;
  }
  // A count of items of at least min_bytes each that must fit in what is left.
  std::uint32_t count(const char* what, std::size_t min_bytes) {
    const std::size_t at = pos;
    const std::uint32_t n = u32(what);
    if (static_cast<std::uint64_t>(n) * min_bytes > b.size() - pos)
      throw error_at_offset(
          src, at, fmt::format("{} {} does not fit in the remaining {} bytes", what, n, b.size() - pos));
    return n;
  }
};

}  // namespace

const Model* Library::find(const std::string& name) const {
  for (const auto& m : models)
    if (m.name == name) return &m;
  return nullptr;
}

namespace {

std::vector<const Pfrg*> graphs_of(const std::vector<Model>& models) {
  std::vector<const Pfrg*> graphs;
  graphs.reserve(models.size());
  for (const Model& m : models) graphs.push_back(&m.graph);
  return graphs;
}

void write_index(Writer& p, const match::ArcIndex& index) {
  p.u32(static_cast<std::uint32_t>(index.entry_array().size()));
  for (const auto& e : index.entry_array()) {
    p.f32(e.angle);
    p.f32(e.a0);
    p.f32(e.a1);
    p.u32(e.ref);
  }
  p.u32(static_cast<std::uint32_t>(index.path_array().size()));
  for (const auto& g : index.path_array())
    for (float v : {g.xy, g.yz, g.xz, g.ax, g.ay, g.az}) p.f32(v);
  for (std::uint32_t v : index.path_starts()) p.u32(v);
  for (float v : index.flattest_array()) p.f32(v);
  for (std::uint32_t v : index.fingerprints()) p.u32(v);
}

match::ArcIndex read_index(Reader& r, std::size_t references) {
  const std::size_t at = r.pos;
  std::vector<match::ArcIndex::Entry> entries(r.count("arc index entry count", 16));
  for (auto& e : entries) {
    e.angle = r.f32("arc index entry angle");
    e.a0 = r.f32("arc index entry area");
    e.a1 = r.f32("arc index entry area");
    e.ref = r.u32("arc index entry reference");
  }
  std::vector<match::ArcIndex::PathSig> paths(r.count("arc index path count", 24));
  for (auto& g : paths)
    for (float* v : {&g.xy, &g.yz, &g.xz, &g.ax, &g.ay, &g.az}) *v = r.f32("arc index path value");
  r.need((references + 1) * 4 + references * 8, "arc index per-reference arrays");
  std::vector<std::uint32_t> path_start(references + 1), fingerprints(references);
  std::vector<float> flattest(references);
  for (auto& v : path_start) v = r.u32("arc index path start");
  for (auto& v : flattest) v = r.f32("arc index flattest angle");
  for (auto& v : fingerprints) v = r.u32("arc index fingerprint");
  try {
    return match::ArcIndex::from_arrays(references, std::move(entries), std::move(paths),
                                        std::move(path_start), std::move(flattest), std::move(fingerprints));
  } catch (const Error& e) {
    throw error_at_offset(r.src, at, e.what());
  }
}

}  // namespace

match::ArcIndex Library::index_of_models() const { return match::ArcIndex(graphs_of(models)); }

void Library::build_index() { index = index_of_models(); }

bool Library::index_describes_models() const { return index.describes(graphs_of(models)); }

void Library::add(Model model) {
  if (find(model.name)) throw Error(fmt::format("library: duplicate model name '{}'", model.name));
  models.push_back(std::move(model));
}

std::vector<std::uint8_t> Library::to_bytes() const {
  Writer p;
  for (const auto& m : models) {
    p.str(m.name);
    p.u8(m.open ? 1 : 0);
    p.u32(static_cast<std::uint32_t>(m.faces.size()));
    for (const auto& f : m.faces) {
      p.vec(f.normal);
      p.f64(f.offset);
      p.f64(f.area);
      p.vec(f.centroid);
      p.u32(static_cast<std::uint32_t>(f.loops.size()));
      for (const auto& loop : f.loops) {
        p.u32(static_cast<std::uint32_t>(loop.size()));
        for (const auto& v : loop) p.vec(v);
      }
    }
    p.u32(static_cast<std::uint32_t>(m.graph.arcs.size()));
    for (const auto& a : m.graph.arcs) {
      p.u32(static_cast<std::uint32_t>(a.a));
      p.u32(static_cast<std::uint32_t>(a.b));
      p.f64(a.border);
    }
    p.u32(static_cast<std::uint32_t>(m.symmetries.size()));
    for (const auto& S : m.symmetries)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) p.f64(S(r, c));
  }
  if (index_describes_models()) {
    write_index(p, index);
  } else {
    write_index(p, index_of_models());
  }
  Writer h;
  h.out.assign(kMagic.begin(), kMagic.end());
  h.u32(kFslibVersion);
  h.u32(static_cast<std::uint32_t>(models.size()));
  h.u64(p.out.size());
  h.u32(crc32_ieee(p.out));
  h.out.insert(h.out.end(), p.out.begin(), p.out.end());
  return h.out;
}

void Library::save(const std::filesystem::path& path) const {
  const auto bytes = to_bytes();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error(fmt::format("{}: cannot open for writing", path.string()));
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw Error(fmt::format("{}: write failed", path.string()));
}

Library Library::from_bytes(std::span<const std::uint8_t> bytes, const std::string& source) {
  Reader r{bytes, 0, source};
  r.need(kHeaderSize, "header");
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin()))
    throw r.fail("not a facetscan library (.fslib): bad magic");
  r.pos = 8;
  const std::size_t vpos = r.pos;
  const std::uint32_t version = r.u32("version");
  if (version < 1 || version > kFslibVersion)
    throw error_at_offset(
        source, vpos,
        fmt::format("unsupported .fslib version {} (this build reads 1 to {})", version, kFslibVersion));
  const std::uint32_t nmodels = r.u32("model count");
  const std::size_t spos = r.pos;
  const std::uint64_t size = r.u64("payload size");
  const std::uint32_t crc = r.u32("payload CRC");
  if (size != bytes.size() - kHeaderSize)
    throw error_at_offset(
        source, spos,
        fmt::format("payload size {} but {} bytes follow the header", size, bytes.size() - kHeaderSize));
  if (crc32_ieee(bytes.subspan(kHeaderSize)) != crc)
    throw error_at_offset(source, kHeaderSize, "payload CRC mismatch (file corrupt)");
  if (static_cast<std::uint64_t>(nmodels) * 17 > size)
    throw error_at_offset(source, 12, fmt::format("model count {} does not fit in the payload", nmodels));

  Library lib;
  lib.models.reserve(nmodels);  // never reallocated below: the names' views stay valid
  std::unordered_set<std::string_view> names;
  names.reserve(nmodels);
  std::unordered_set<std::uint64_t> arc_keys;  // one model's arcs (faces a < b), reused
  for (std::uint32_t mi = 0; mi < nmodels; ++mi) {
    Model m;
    const std::size_t name_pos = r.pos;
    const std::uint32_t len = r.count("model name length", 1);
    m.name.assign(reinterpret_cast<const char*>(bytes.data() + r.pos), len);
    r.pos += len;
    if (names.count(m.name))
      throw error_at_offset(source, name_pos, fmt::format("duplicate model name '{}'", m.name));
    const std::uint8_t open = r.u8("open flag");
    if (open > 1) throw error_at_offset(source, r.pos - 1, fmt::format("open flag {} is not 0 or 1", open));
    m.open = open == 1;
    const std::uint32_t nf = r.count("face count", 68);
    m.faces.resize(nf);
    for (auto& f : m.faces) {
      const std::size_t npos = r.pos;
      f.normal = r.vec("face normal");
      if (std::abs(f.normal.norm() - 1.0) > 1e-6)
        throw error_at_offset(source, npos, "face normal is not a unit vector");
      f.offset = r.f64("face offset");
      const std::size_t apos = r.pos;
      f.area = r.f64("face area");
      if (f.area < 0) throw error_at_offset(source, apos, "negative face area");
      f.centroid = r.vec("face centroid");
      const std::uint32_t nl = r.count("loop count", 4);
      f.loops.resize(nl);
      for (auto& loop : f.loops) {
        const std::size_t lpos = r.pos;
        const std::uint32_t nv = r.count("loop vertex count", 24);
        if (nv < 3) throw error_at_offset(source, lpos, fmt::format("a face loop has {} vertices (< 3)", nv));
        loop.resize(nv);
        for (auto& v : loop) v = r.vec("loop vertex");
        for (std::size_t i = 0; i < loop.size(); ++i)
          f.perimeter += (loop[(i + 1) % loop.size()] - loop[i]).norm();
      }
    }
    const std::uint32_t na = r.count("arc count", 16);
    std::vector<PfrgArc> arcs(na);
    arc_keys.clear();
    for (auto& a : arcs) {
      const std::size_t apos = r.pos;
      const std::uint32_t x = r.u32("arc node"), y = r.u32("arc node");
      a.border = r.f64("arc border");
      if (x >= nf || y >= nf || x == y)
        throw error_at_offset(source, apos,
                              fmt::format("arc ({}, {}) does not join two faces of {}", x, y, nf));
      if (a.border < 0) throw error_at_offset(source, apos + 8, "negative arc border");
      a.a = static_cast<int>(x);
      a.b = static_cast<int>(y);
      if (!arc_keys.insert(std::uint64_t{std::min(x, y)} << 32 | std::max(x, y)).second)
        throw error_at_offset(source, apos, fmt::format("duplicate arc ({}, {})", x, y));
    }
    const std::size_t sympos = r.pos;
    const std::uint32_t ns = r.count("symmetry count", 72);
    if (ns == 0) throw error_at_offset(source, sympos, "symmetry group is empty (needs the identity)");
    m.symmetries.resize(ns);
    for (auto& S : m.symmetries) {
      const std::size_t at = r.pos;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) S(i, j) = r.f64("symmetry matrix entry");
      if ((S * S.transpose() - Mat3::Identity()).norm() > 1e-6 || S.determinant() < 0)
        throw error_at_offset(source, at, "symmetry is not a rotation matrix");
    }
    finish_model(m, std::move(arcs), BuildOptions{}, false);
    lib.models.push_back(std::move(m));
    names.insert(lib.models.back().name);
  }
  if (version >= 2) {
    const std::size_t at = r.pos;
    lib.index = read_index(r, nmodels);
    if (!lib.index_describes_models())
      throw error_at_offset(source, at, "the arc index does not describe the models (fingerprints differ)");
    if (version == 2) lib.index = match::ArcIndex{};  // its areas lack the shallow folds: built again
  }
  if (r.pos != bytes.size())
    throw r.fail(fmt::format("{} unexpected bytes after the {}", bytes.size() - r.pos,
                             version >= 2 ? "arc index" : "last model"));
  return lib;
}

Library Library::load(const std::filesystem::path& path) {
  const ByteBuffer bytes = read_input_bytes(path, kMaxLibraryFileBytes, "model library");
  return from_bytes(std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()),
                    path.string());
}

}  // namespace fs::host
