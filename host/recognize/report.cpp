// The outputs of a recognition that people look at (report.hpp): the result table and the HTML report
// directory. write_report() writes the pictures of seg::write_pictures, objects.ply, the top view
// (draw_top_view -> scene_top.png, write_scene_svg -> scene.svg) and the page (write_index_html ->
// index.html).
#include "host/recognize/report.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>

#include <fmt/format.h>

#include "common/error.hpp"
#include "common/png_write.hpp"
#include "host/io/cloud_writers.hpp"
#include "host/segment/pictures.hpp"

namespace fs::host::rec {

std::string axis_angle_text(const Mat3& R) {
  const Eigen::AngleAxisd aa(R);
  const double deg = aa.angle() * 180.0 / M_PI;
  // Below display precision (0.05°) the axis is noise: show the identity as 0.0° about z.
  const Vec3 ax = deg < 0.05 ? Vec3::UnitZ() : aa.axis();
  return fmt::format("{:6.1f}° about ({:5.2f}, {:5.2f}, {:5.2f})", deg, ax.x(), ax.y(), ax.z());
}

std::string ambiguity_text(const Hypothesis& h, const Library& library) {
  auto candidate = [&](int model, double fit) {
    return fmt::format("{} ({:.2f}, fit {:.2f})", library.models[static_cast<std::size_t>(model)].name,
                       h.candidate_confidence(fit), fit);
  };
  std::string s = "ambiguous: " + candidate(h.model, h.fit());
  for (const Hypothesis::Alternative& a : h.listed_alternatives()) s += " or " + candidate(a.model, a.fit);
  return s + "; they differ only out of view";
}

std::string result_table(const Recognition& r, const Library& library) {
  std::string s;
  if (r.objects.empty()) {
    s += "no objects recognized";
    if (!r.note.empty()) s += ": " + r.note;
    s += "\n";
    return s;
  }
  s += fmt::format("{:<3} {:<24} {:>26}  {:<38} {:>5} {:>7} {:>5}\n", "#", "model", "position (mm)",
                   "rotation (axis-angle)", "conf", "cost", "faces");
  int i = 1;
  for (const Hypothesis& h : r.objects) {
    std::string name = library.models[static_cast<std::size_t>(h.model)].name;
    if (h.instance > 0) name += fmt::format(" #{}", h.instance + 1);
    s += fmt::format("{:<3} {:<24} ({:7.1f}, {:7.1f}, {:7.1f})  {:<38} {:5.2f} {:7.4f} {:>2}/{:<2}\n", i++,
                     name, h.t.x(), h.t.y(), h.t.z(), axis_angle_text(h.R), h.confidence(), h.cost,
                     h.matches.size(), h.faces_visible);
    if (h.ambiguous()) s += "    " + ambiguity_text(h, library) + "\n";
  }
  if (!r.note.empty()) s += "note: " + r.note + "\n";
  return s;
}

std::string base64(const std::string& bytes) {
  static constexpr char k[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const auto v = (std::uint32_t(std::uint8_t(bytes[i])) << 16) |
                   (std::uint32_t(std::uint8_t(bytes[i + 1])) << 8) | std::uint8_t(bytes[i + 2]);
    out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], k[v & 63]};
  }
  if (i + 1 == bytes.size()) {
    const auto v = std::uint32_t(std::uint8_t(bytes[i])) << 16;
    out += {k[v >> 18], k[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == bytes.size()) {
    const auto v =
        (std::uint32_t(std::uint8_t(bytes[i])) << 16) | (std::uint32_t(std::uint8_t(bytes[i + 1])) << 8);
    out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], '='};
  }
  return out;
}

namespace {

std::string colour_hex(std::uint32_t rgb) { return fmt::format("#{:06x}", rgb & 0xffffff); }

// Whole millimetres; a value that rounds to zero is "0", not "-0".
std::string mm_text(double v) {
  std::string t = fmt::format("{:.0f}", v);
  return t == "-0" ? "0" : t;
}

struct TopView {
  double xmin = 0, ymax = 0, scale = 1;
  int w = 0, h = 0;
  Eigen::Vector2d px(const Vec3& p) const { return {(p.x() - xmin) * scale, (ymax - p.y()) * scale}; }
};

TopView top_view(const OrganizedCloud& cloud) {
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin, ymin = xmin, ymax = -xmin;
  for (const auto& p : cloud.points) {
    if (!OrganizedCloud::valid(p)) continue;
    xmin = std::min<double>(xmin, p.x());
    xmax = std::max<double>(xmax, p.x());
    ymin = std::min<double>(ymin, p.y());
    ymax = std::max<double>(ymax, p.y());
  }
  TopView v;
  if (!(xmax > xmin) || !(ymax > ymin)) {
    v.w = v.h = 1;
    return v;
  }
  v.xmin = xmin;
  v.ymax = ymax;
  v.scale = 800.0 / std::max(xmax - xmin, ymax - ymin);
  v.w = std::max(1, static_cast<int>((xmax - xmin) * v.scale) + 1);
  v.h = std::max(1, static_cast<int>((ymax - ymin) * v.scale) + 1);
  return v;
}

void write_text(const std::filesystem::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
  if (!f) throw Error(p.string() + ": cannot write");
}

std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<')
      o += "&lt;";
    else if (c == '>')
      o += "&gt;";
    else if (c == '&')
      o += "&amp;";
    else
      o += c;
  }
  return o;
}

std::string base64_file(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return base64(std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>()));
}

// The top view (scene_top.png): the measured surface seen from above (grid cells drawn as triangles with a
// z-buffer, so no stripe-by-stripe moire and no gaps between stripes), height- and slope-shaded grey, each
// recognized object's points in its colour (labels: cell -> object or -1); no data (laser / camera shadows)
// in a flat blue-grey. Returns the RGB8 pixels, tv.w x tv.h.
std::vector<std::uint8_t> draw_top_view(const OrganizedCloud& cloud, const std::vector<std::int32_t>& labels,
                                        const TopView& tv) {
  const std::size_t npx = static_cast<std::size_t>(tv.w) * tv.h;
  std::vector<std::uint8_t> rgb(npx * 3);
  for (std::size_t i = 0; i < npx; ++i) {
    rgb[3 * i] = 0xc9;
    rgb[3 * i + 1] = 0xd2;
    rgb[3 * i + 2] = 0xdc;
  }
  std::vector<float> zbuf(npx, -std::numeric_limits<float>::infinity());
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (const auto& p : cloud.points)
    if (OrganizedCloud::valid(p)) {
      zmin = std::min<double>(zmin, p.z());
      zmax = std::max<double>(zmax, p.z());
    }
  auto cell_colour = [&](std::size_t i, const Eigen::Vector3f& n, std::uint8_t out[3]) {
    const Eigen::Vector3f light = Eigen::Vector3f(-0.35f, 0.45f, 0.82f).normalized();
    const double shade = 0.55 + 0.45 * std::max(0.0f, std::abs(n.dot(light)));
    if (labels[i] >= 0) {
      const std::uint32_t c = label_colour(labels[i] + 1);
      for (int k = 0; k < 3; ++k)
        out[k] =
            static_cast<std::uint8_t>(std::min(255.0, ((c >> (16 - 8 * k)) & 0xff) * (0.35 + 0.75 * shade)));
    } else {
      const double g = zmax > zmin ? (cloud.points[i].z() - zmin) / (zmax - zmin) : 0.5;
      const auto v = static_cast<std::uint8_t>(std::min(255.0, (70 + 120 * g) * (0.6 + 0.5 * shade)));
      out[0] = out[1] = out[2] = v;
    }
  };
  // Fills the triangle (a, b, c) (image coordinates + height) with one colour where it is the highest.
  auto fill = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                  const std::uint8_t col[3]) {
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(tv.w - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(tv.h - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (std::abs(area) < 1e-12) return;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        const double w0 = ((b.x() - px) * (c.y() - py) - (c.x() - px) * (b.y() - py)) / area;
        const double w1 = ((c.x() - px) * (a.y() - py) - (a.x() - px) * (c.y() - py)) / area;
        const double w2 = 1.0 - w0 - w1;
        constexpr double e = -1e-6;
        if (w0 < e || w1 < e || w2 < e) continue;
        const auto z = static_cast<float>(w0 * a.z() + w1 * b.z() + w2 * c.z());
        const std::size_t k = static_cast<std::size_t>(y) * tv.w + x;
        if (z <= zbuf[k]) continue;
        zbuf[k] = z;
        std::copy(col, col + 3, &rgb[3 * k]);
      }
  };
  // Neighbouring cells farther apart than this are a depth jump (an occlusion edge), not a surface.
  const float max_edge = 6.0f;
  auto img = [&](const Eigen::Vector3f& p) {
    const Eigen::Vector2d q = tv.px(p.cast<double>());
    return Eigen::Vector3d(q.x(), q.y(), p.z());
  };
  if (cloud.organized && cloud.height > 1 && cloud.width > 1) {
    for (std::uint32_t row = 0; row + 1 < cloud.height; ++row)
      for (std::uint32_t col = 0; col + 1 < cloud.width; ++col) {
        const std::size_t i00 = cloud.index(row, col), i01 = cloud.index(row, col + 1),
                          i10 = cloud.index(row + 1, col), i11 = cloud.index(row + 1, col + 1);
        const auto &p00 = cloud.points[i00], &p01 = cloud.points[i01], &p10 = cloud.points[i10],
                   &p11 = cloud.points[i11];
        if (!OrganizedCloud::valid(p00)) continue;
        auto near = [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
          return OrganizedCloud::valid(b) && (a - b).norm() < max_edge;
        };
        std::uint8_t c[3];
        if (near(p00, p01) && near(p00, p10)) {
          cell_colour(i00, (p01 - p00).cross(p10 - p00).normalized(), c);
          fill(img(p00), img(p01), img(p10), c);
        }
        if (near(p11, p01) && near(p11, p10)) {
          cell_colour(labels[i11] >= 0 ? i11 : i00, (p10 - p11).cross(p01 - p11).normalized(), c);
          fill(img(p11), img(p01), img(p10), c);
        }
      }
  }
  // Isolated points (and unorganized clouds) as single pixels.
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const auto& p = cloud.points[i];
    if (!OrganizedCloud::valid(p)) continue;
    const Eigen::Vector2d q = tv.px(p.cast<double>());
    const int x = static_cast<int>(q.x()), y = static_cast<int>(q.y());
    if (x < 0 || y < 0 || x >= tv.w || y >= tv.h) continue;
    const std::size_t k = static_cast<std::size_t>(y) * tv.w + x;
    if (zbuf[k] > -std::numeric_limits<float>::infinity()) continue;
    zbuf[k] = p.z();
    std::uint8_t c[3];
    cell_colour(i, Eigen::Vector3f::UnitZ(), c);
    std::copy(c, c + 3, &rgb[3 * k]);
  }
  return rgb;
}

// scene.svg: the top view picture (inline), each model's outline in its pose, and a legend below the picture.
void write_scene_svg(const std::filesystem::path& dir, const Library& library, const Recognition& r,
                     const TopView& tv) {
  const int legend_rows = static_cast<int>(r.objects.size()) + 2;
  const int svg_h = tv.h + 12 + 24 * legend_rows;
  std::ostringstream svg;
  svg << fmt::format(R"(<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}">)",
                     tv.w, svg_h, tv.w, svg_h)
      << "\n"
      << fmt::format(R"(<rect x="0" y="0" width="{}" height="{}" fill="white"/>)", tv.w, svg_h)
      << "\n"
      // The picture inline (data: URI): an SVG shown with <img> loads no external file.
      << fmt::format(R"(<image href="data:image/png;base64,{}" x="0" y="0" width="{}" height="{}"/>)",
                     base64_file(dir / "scene_top.png"), tv.w, tv.h)
      << "\n";
  for (std::size_t o = 0; o < r.objects.size(); ++o) {
    const Hypothesis& h = r.objects[o];
    const Model& m = library.models[static_cast<std::size_t>(h.model)];
    const std::string col = colour_hex(label_colour(static_cast<std::int32_t>(o) + 1));
    for (const ModelFace& f : m.faces) {
      if ((h.R * f.normal).z() <= 0.05) continue;  // the outline seen from above: upward faces
      for (const auto& loop : f.loops) {
        svg << "<polygon points=\"";
        for (const Vec3& p : loop) {
          const Eigen::Vector2d q = tv.px(h.R * p + h.t);
          svg << fmt::format("{:.1f},{:.1f} ", q.x(), q.y());
        }
        svg << R"(" fill="none" stroke="black" stroke-opacity="0.55" stroke-width="1"/>)"
            << "\n";
      }
    }
    const Eigen::Vector2d c = tv.px(h.R * m.center + h.t);
    svg << fmt::format(
               R"(<text x="{:.0f}" y="{:.0f}" text-anchor="middle" font-family="sans-serif" font-size="15" font-weight="bold" fill="black" stroke="white" stroke-width="3" paint-order="stroke">{}{}</text>)",
               c.x(), c.y(), html_escape(m.name), h.instance > 0 ? fmt::format(" #{}", h.instance + 1) : "")
        << "\n";
  }
  auto legend_row = [&](int k, const std::string& fill, const std::string& text) {
    const int y = tv.h + 10 + 24 * k;
    svg << fmt::format(
               R"(<rect x="10" y="{}" width="18" height="18" fill="{}" stroke="#555"/><text x="36" y="{}" font-family="sans-serif" font-size="14" fill="black">{}</text>)",
               y, fill, y + 14, html_escape(text))
        << "\n";
  };
  for (std::size_t o = 0; o < r.objects.size(); ++o) {
    const Hypothesis& h = r.objects[o];
    const Model& m = library.models[static_cast<std::size_t>(h.model)];
    legend_row(static_cast<int>(o), colour_hex(label_colour(static_cast<std::int32_t>(o) + 1)),
               fmt::format("{}{}: confidence {:.2f}{}, at ({}, {}, {}) mm", m.name,
                           h.instance > 0 ? fmt::format(" #{}", h.instance + 1) : "", h.confidence(),
                           h.ambiguous() ? " (ambiguous)" : "", mm_text(h.t.x()), mm_text(h.t.y()),
                           mm_text(h.t.z())));
  }
  // The swatch: a level surface at the lowest height (the table) as draw_top_view shades it.
  legend_row(static_cast<int>(r.objects.size()), "#4a4a4a",
             "table and unrecognized surfaces (grey by height: the table this dark, lighter = higher)");
  legend_row(static_cast<int>(r.objects.size()) + 1, "#c9d2dc", "no data (laser or camera shadow)");
  svg << "</svg>\n";
  write_text(dir / "scene.svg", svg.str());
}

// index.html: the title, `view_html`, the object table, the statistics and the pictures.
void write_index_html(const std::filesystem::path& dir, const std::string& title, const Library& library,
                      const Recognition& r, const std::string& view_html) {
  std::ostringstream html;
  html << "<!doctype html><html><head><meta charset=\"utf-8\"><title>Facetscan: " << html_escape(title)
       << "</"
          "title><style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}td,th{border:"
          "1px "
          "solid #ccc;padding:4px 8px}img{max-width:100%;border:1px solid "
          "#ddd}.g{display:flex;flex-wrap:wrap;gap:"
          "1em}.g figure{margin:0}</style></head><body>\n";
  html << "<h1>Facetscan recognition: " << html_escape(title) << "</h1>\n";
  html << view_html;
  if (r.objects.empty()) html << "<p><b>No objects recognized.</b> " << html_escape(r.note) << "</p>\n";
  html << "<table><tr><th>#</th><th>model</th><th>position (mm)</th><th>rotation</th><th>confidence</th>"
          "<th>cost</th><th>faces matched / visible</th><th>state</th></tr>\n";
  for (std::size_t o = 0; o < r.objects.size(); ++o) {
    const Hypothesis& h = r.objects[o];
    const Model& m = library.models[static_cast<std::size_t>(h.model)];
    std::string state = m.name;
    for (int k : h.path) state += "." + std::to_string(k);
    const std::string ambiguity =
        h.ambiguous() ? "<br><b>" + html_escape(ambiguity_text(h, library)) + "</b>" : std::string();
    html << fmt::format(
        "<tr><td style=\"background:{}\">{}</td><td>{}{}{}</td><td>({:.1f}, {:.1f}, {:.1f})</td><td>{}</td>"
        "<td>{:.2f}{}</td><td>{:.4f}</td><td>{} / {}</td><td>{}</td></tr>\n",
        colour_hex(label_colour(static_cast<std::int32_t>(o) + 1)), o + 1, html_escape(m.name),
        h.instance > 0 ? fmt::format(" #{}", h.instance + 1) : "", ambiguity, h.t.x(), h.t.y(), h.t.z(),
        html_escape(axis_angle_text(h.R)), h.confidence(),
        h.ambiguous() ? fmt::format(" (fit {:.2f})", h.fit()) : "", h.cost, h.matches.size(), h.faces_visible,
        state);
  }
  html << "</table>\n";
  const RecognizeStats& s = r.stats;
  html << fmt::format(
      "<p>Segmentation {:.1f} ms ({} regions, {} known), PFRG {:.1f} ms ({} nodes, {} arcs{}), matching "
      "{:.1f} ms "
      "against {} references ({} states), verification {:.1f} ms ({} hypotheses, {} rejected); total {:.1f} "
      "ms."
      "</p>\n",
      s.segment_ms, s.regions, s.known_regions, s.pfrg_ms, s.scene_nodes, s.scene_arcs,
      s.table_removed ? ", table removed" : "", s.match_ms, s.references, s.states, s.verify_ms, s.hypotheses,
      s.rejected, s.total_ms);
  html << "<div class=\"g\"><figure><img src=\"scene.svg\"><figcaption>Top view: recognized models in their "
          "poses</figcaption></figure><figure><img "
          "src=\"segmentation.png\"><figcaption>Segmentation</figcaption>"
          "</figure><figure><img src=\"pfrg.svg\"><figcaption>Scene PFRG</figcaption></figure><figure><img "
          "src=\"enm.svg\"><figcaption>Extended needle map</figcaption></figure></div>\n";
  html << "<p><a href=\"objects.ply\">objects.ply</a>: the cloud coloured by object.</p></body></html>\n";
  write_text(dir / "index.html", html.str());
}

}  // namespace

void write_report(const std::filesystem::path& dir, const std::string& title, const OrganizedCloud& cloud,
                  const Recognizer& recognizer, const Recognition& r, const std::string& view_html) {
  std::filesystem::create_directories(dir);
  const Library& library = recognizer.library();
  // Segmentation, PFRG, ENM pictures.
  Vec3 view = Vec3::UnitZ();
  {
    Vec3 c = Vec3::Zero();
    std::size_t n = 0;
    for (const auto& p : cloud.points)
      if (OrganizedCloud::valid(p)) {
        c += p.cast<double>();
        ++n;
      }
    if (n > 0) view = (cloud.viewpoint - c / static_cast<double>(n)).normalized();
  }
  if (recognizer.segmentation().width > 0)
    seg::write_pictures(recognizer.segmentation(), recognizer.scene_graph(), view, dir);

  // Cloud coloured by object.
  std::vector<std::int32_t> labels;
  recognizer.object_labels(cloud, labels);
  OrganizedCloud coloured = cloud;
  coloured.labels.resize(labels.size());
  for (std::size_t i = 0; i < labels.size(); ++i) coloured.labels[i] = labels[i] >= 0 ? labels[i] + 1 : 0;
  CloudWriteOptions wo;
  wo.colours_from_labels = true;
  write_cloud((dir / "objects.ply").string(), coloured, wo);

  // Top view, its SVG, the page.
  const TopView tv = top_view(cloud);
  write_png_rgb8(dir / "scene_top.png", static_cast<std::uint32_t>(tv.w), static_cast<std::uint32_t>(tv.h),
                 draw_top_view(cloud, labels, tv));
  write_scene_svg(dir, library, r, tv);
  write_index_html(dir, title, library, r, view_html);
}

}  // namespace fs::host::rec
