#include "host/segment/pictures.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <vector>

#include <fmt/format.h>

#include "common/error.hpp"
#include "common/png_write.hpp"

namespace fs::host::seg {
namespace {

// Well-separated colours: golden-angle hue walk.
void region_colour(std::int32_t id, std::uint8_t rgb[3]) {
  const double h = std::fmod(double(id) * 137.508, 360.0) / 60.0;
  const double s = 0.75, v = (id % 2) ? 0.95 : 0.8;
  const double c = v * s, x = c * (1 - std::abs(std::fmod(h, 2.0) - 1)), m = v - c;
  double r = 0, g = 0, b = 0;
  switch (int(h)) {
    case 0:
      r = c;
      g = x;
      break;
    case 1:
      r = x;
      g = c;
      break;
    case 2:
      g = c;
      b = x;
      break;
    case 3:
      g = x;
      b = c;
      break;
    case 4:
      r = x;
      b = c;
      break;
    default:
      r = c;
      b = x;
      break;
  }
  rgb[0] = std::uint8_t((r + m) * 255);
  rgb[1] = std::uint8_t((g + m) * 255);
  rgb[2] = std::uint8_t((b + m) * 255);
}

std::string colour_hex(std::int32_t id) {
  std::uint8_t c[3];
  region_colour(id, c);
  return fmt::format("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  if (!f) throw Error(path.string() + ": cannot open for writing");
  f << text;
  if (!f) throw Error(path.string() + ": write failed");
}

}  // namespace

void write_segmentation_png(const Segmentation& s, const std::filesystem::path& path) {
  const std::uint32_t w = s.width, h = s.height;
  if (w == 0 || h == 0 || s.labels.size() < std::size_t(w) * h)
    throw Error(path.string() + ": empty segmentation");
  std::vector<std::uint8_t> rgb(std::size_t(w) * h * 3, 0);
  for (std::uint32_t r = 0; r < h; ++r) {
    for (std::uint32_t c = 0; c < w; ++c) {
      const std::size_t i = std::size_t(r) * w + c;
      const std::int32_t l = s.labels[i];
      std::uint8_t* px = &rgb[i * 3];
      if (l < 0) continue;
      const bool border = (c + 1 < w && s.labels[i + 1] != l) || (r + 1 < h && s.labels[i + w] != l);
      if (border) {
        px[0] = px[1] = px[2] = 255;
      } else if (s.regions[std::size_t(l)].known) {
        region_colour(l, px);
      } else {
        px[0] = px[1] = px[2] = std::uint8_t(70 + (l * 37) % 60);
      }
    }
  }
  write_png_rgb8(path, w, h, rgb);
}

std::string pfrg_svg(const Pfrg& g, const Segmentation& s) {
  const double W = 900.0, H = 700.0, margin = 80.0;
  const double sx = (W - 2 * margin) / std::max(1u, s.width), sy = (H - 2 * margin) / std::max(1u, s.height);
  const double scale = std::min(sx, sy);
  double max_area = 1.0;
  for (const auto& n : g.nodes) max_area = std::max(max_area, n.area);
  std::map<int, std::pair<double, double>> pos;
  for (const auto& n : g.nodes) {
    if (n.supernode) {
      pos[n.id] = {margin * 0.5, margin * 0.5};
    } else {
      const int r = n.id - 1;
      if (r >= 0 && std::size_t(r) < s.regions.size()) {
        const auto& px = s.regions[std::size_t(r)].pixel;
        pos[n.id] = {margin + px.x() * scale, margin + px.y() * scale};
      } else {
        pos[n.id] = {W / 2, H / 2};
      }
    }
  }
  std::string out = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\" "
      "font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      "<text x=\"{}\" y=\"20\" font-size=\"14\">PFRG: {} nodes, {} arcs (area mm², border mm)</text>\n",
      W, H, W, H, margin, g.nodes.size(), g.arcs.size());
  for (const auto& a : g.arcs) {
    auto pa = pos[a.a], pb = pos[a.b];
    const bool sn = a.a == 0 || a.b == 0;
    out += fmt::format(
        "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" "
        "stroke-width=\"1.5\"{}/>\n",
        pa.first, pa.second, pb.first, pb.second, sn ? "#999" : "#333",
        sn ? " stroke-dasharray=\"4,3\"" : "");
    out += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" fill=\"#a00\" text-anchor=\"middle\">{:.1f}</text>\n",
                       (pa.first + pb.first) / 2, (pa.second + pb.second) / 2 - 3, a.border);
  }
  for (const auto& n : g.nodes) {
    auto p = pos[n.id];
    if (n.supernode) {
      out += fmt::format(
          "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"24\" height=\"24\" fill=\"#ddd\" stroke=\"#333\"/>"
          "<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">SN</text>\n",
          p.first - 12, p.second - 12, p.first, p.second + 4);
      continue;
    }
    const double rad = 6.0 + 22.0 * std::sqrt(n.area / max_area);
    out += fmt::format(
        "<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"{:.1f}\" fill=\"{}\" fill-opacity=\"0.8\" "
        "stroke=\"#333\"/>\n",
        p.first, p.second, rad, colour_hex(n.id - 1));
    out +=
        fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" font-weight=\"bold\">{}</text>\n",
                    p.first, p.second + 4, n.id);
    out += fmt::format(
        "<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">{:.0f} mm² n=({:.2f},{:.2f},{:.2f})"
        "</text>\n",
        p.first, p.second + rad + 12, n.area, n.normal.x(), n.normal.y(), n.normal.z());
  }
  out += "</svg>\n";
  return out;
}

std::string enm_svg(const Pfrg& g, const Vec3& view_in) {
  const double W = 600.0, C = 300.0, R = 240.0;
  const Vec3 view = view_in.norm() > 0 ? view_in.normalized() : Vec3::UnitZ();
  // screen basis: e1 right, e2 up, view toward the observer
  Vec3 e1 = (std::abs(view.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(view).normalized();
  e1 = view.cross(e1).cross(view).normalized();
  if (e1.norm() < 0.5) e1 = Vec3::UnitX();
  const Vec3 e2 = view.cross(e1).normalized();
  auto proj = [&](const Vec3& v) { return std::pair<double, double>{C + R * v.dot(e1), C - R * v.dot(e2)}; };
  double max_area = 1.0;
  for (const auto& n : g.nodes) max_area = std::max(max_area, n.area);
  std::string out = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" viewBox=\"0 0 {} {}\" "
      "font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      "<text x=\"10\" y=\"18\" font-size=\"14\">Extended needle map: needle = normal, length ~ area</text>\n"
      "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"#f4f4fa\" stroke=\"#888\"/>\n",
      W, W, W, W, C, C, R);
  std::map<int, Vec3> nrm;
  for (const auto& n : g.nodes)
    if (!n.supernode) nrm[n.id] = n.normal.normalized();
  for (const auto& a : g.arcs) {
    if (!nrm.count(a.a) || !nrm.count(a.b)) continue;
    const Vec3 p = nrm[a.a], q = nrm[a.b];
    const double om = std::acos(std::clamp(p.dot(q), -1.0, 1.0));
    std::string pts;
    for (int k = 0; k <= 24; ++k) {
      const double t = k / 24.0;
      Vec3 v = om < 1e-6 ? p : Vec3((std::sin((1 - t) * om) * p + std::sin(t * om) * q) / std::sin(om));
      auto s = proj(v);
      pts += fmt::format("{:.1f},{:.1f} ", s.first, s.second);
    }
    out += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"#c55\" stroke-width=\"1\"/>\n", pts);
  }
  for (const auto& n : g.nodes) {
    if (n.supernode) continue;
    const Vec3 v = n.normal.normalized();
    const double len = 0.25 + 0.75 * std::sqrt(n.area / max_area);
    auto tip = proj(v), base = proj(Vec3::Zero()), end = proj(v * (1.0 + 0.35 * len));
    const bool back = v.dot(view) < 0;
    out += fmt::format(
        "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"#bbb\" "
        "stroke-dasharray=\"2,2\"/>\n",
        base.first, base.second, tip.first, tip.second);
    out += fmt::format(
        "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" "
        "stroke-width=\"{:.1f}\"{}/>\n",
        tip.first, tip.second, end.first, end.second, colour_hex(n.id - 1), 2.0 + 4.0 * len,
        back ? " stroke-opacity=\"0.4\"" : "");
    out += fmt::format(
        "<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"3\" fill=\"#333\"/>"
        "<text x=\"{:.1f}\" y=\"{:.1f}\">{} ({:.0f} mm²)</text>\n",
        tip.first, tip.second, end.first + 4, end.second - 4, n.id, n.area);
  }
  out += "</svg>\n";
  return out;
}

void write_pictures(const Segmentation& s, const Pfrg& g, const Vec3& view,
                    const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot create directory: " + ec.message());
  write_segmentation_png(s, dir / "segmentation.png");
  write_text(dir / "pfrg.svg", pfrg_svg(g, s));
  write_text(dir / "enm.svg", enm_svg(g, view));
}

}  // namespace fs::host::seg
