#include "host/recognize/report.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
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
                     name, h.t.x(), h.t.y(), h.t.z(), axis_angle_text(h.R), h.verify.confidence, h.cost,
                     h.matches.size(), h.faces_visible);
    if (h.alternatives > 0) {
      s += "    fits this view as well:";
      const char* sep = "";
      for (const Hypothesis::Alternative& a : h.listed_alternatives()) {
        s += fmt::format("{} {} ({:.2f})", sep, library.models[static_cast<std::size_t>(a.model)].name,
                         a.confidence);
        sep = ",";
      }
      s += "\n";
    }
  }
  return s;
}

namespace {

std::string colour_hex(std::uint32_t rgb) { return fmt::format("#{:06x}", rgb & 0xffffff); }

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

}  // namespace

void write_report(const std::filesystem::path& dir, const std::string& title, const OrganizedCloud& cloud,
                  const Recognizer& recognizer, const Recognition& r) {
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

  // Top view: height-shaded points, objects' points in their colours, models drawn in their poses.
  const TopView tv = top_view(cloud);
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(tv.w) * tv.h * 3, 255);
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (const auto& p : cloud.points)
    if (OrganizedCloud::valid(p)) {
      zmin = std::min<double>(zmin, p.z());
      zmax = std::max<double>(zmax, p.z());
    }
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const auto& p = cloud.points[i];
    if (!OrganizedCloud::valid(p)) continue;
    const Eigen::Vector2d q = tv.px(p.cast<double>());
    const int x = static_cast<int>(q.x()), y = static_cast<int>(q.y());
    if (x < 0 || y < 0 || x >= tv.w || y >= tv.h) continue;
    std::uint8_t* o = &rgb[(static_cast<std::size_t>(y) * tv.w + x) * 3];
    if (labels[i] >= 0) {
      const std::uint32_t c = label_colour(labels[i] + 1);
      o[0] = static_cast<std::uint8_t>(c >> 16);
      o[1] = static_cast<std::uint8_t>(c >> 8);
      o[2] = static_cast<std::uint8_t>(c);
    } else {
      const double g = zmax > zmin ? (p.z() - zmin) / (zmax - zmin) : 0.5;
      const auto v = static_cast<std::uint8_t>(90 + 140 * g);
      o[0] = o[1] = o[2] = v;
    }
  }
  write_png_rgb8(dir / "scene_top.png", static_cast<std::uint32_t>(tv.w), static_cast<std::uint32_t>(tv.h),
                 rgb);
  std::ostringstream svg;
  svg << fmt::format(R"(<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}">)",
                     tv.w, tv.h, tv.w, tv.h)
      << "\n"
      << fmt::format(R"(<image href="scene_top.png" x="0" y="0" width="{}" height="{}"/>)", tv.w, tv.h)
      << "\n";
  for (std::size_t o = 0; o < r.objects.size(); ++o) {
    const Hypothesis& h = r.objects[o];
    const Model& m = library.models[static_cast<std::size_t>(h.model)];
    const std::string col = colour_hex(label_colour(static_cast<std::int32_t>(o) + 1));
    for (const ModelFace& f : m.faces) {
      const bool up = (h.R * f.normal).z() > 0.05;
      for (const auto& loop : f.loops) {
        svg << "<polygon points=\"";
        for (const Vec3& p : loop) {
          const Eigen::Vector2d q = tv.px(h.R * p + h.t);
          svg << fmt::format("{:.1f},{:.1f} ", q.x(), q.y());
        }
        svg << fmt::format(R"(" fill="{}" fill-opacity="{}" stroke="{}" stroke-width="1.5"/>)", col,
                           up ? 0.18 : 0.0, col)
            << "\n";
      }
    }
    const Eigen::Vector2d c = tv.px(h.R * m.center + h.t);
    svg << fmt::format(
               R"(<text x="{:.0f}" y="{:.0f}" font-family="sans-serif" font-size="14" fill="black" stroke="white" stroke-width="0.6">{}{}</text>)",
               c.x(), c.y(), html_escape(m.name), h.instance > 0 ? fmt::format(" #{}", h.instance + 1) : "")
        << "\n";
  }
  svg << "</svg>\n";
  write_text(dir / "scene.svg", svg.str());

  // The page.
  std::ostringstream html;
  html << "<!doctype html><html><head><meta charset=\"utf-8\"><title>Facetscan: " << html_escape(title)
       << "</"
          "title><style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}td,th{border:"
          "1px "
          "solid #ccc;padding:4px 8px}img{max-width:100%;border:1px solid "
          "#ddd}.g{display:flex;flex-wrap:wrap;gap:"
          "1em}.g figure{margin:0}</style></head><body>\n";
  html << "<h1>Facetscan recognition: " << html_escape(title) << "</h1>\n";
  if (r.objects.empty()) html << "<p><b>No objects recognized.</b> " << html_escape(r.note) << "</p>\n";
  html << "<table><tr><th>#</th><th>model</th><th>position (mm)</th><th>rotation</th><th>confidence</th>"
          "<th>cost</th><th>faces matched / visible</th><th>state</th></tr>\n";
  for (std::size_t o = 0; o < r.objects.size(); ++o) {
    const Hypothesis& h = r.objects[o];
    const Model& m = library.models[static_cast<std::size_t>(h.model)];
    std::string state = m.name;
    for (int k : h.path) state += "." + std::to_string(k);
    html << fmt::format(
        "<tr><td style=\"background:{}\">{}</td><td>{}{}</td><td>({:.1f}, {:.1f}, {:.1f})</td><td>{}</td>"
        "<td>{:.2f}</td><td>{:.4f}</td><td>{} / {}</td><td>{}</td></tr>\n",
        colour_hex(label_colour(static_cast<std::int32_t>(o) + 1)), o + 1, html_escape(m.name),
        h.instance > 0 ? fmt::format(" #{}", h.instance + 1) : "", h.t.x(), h.t.y(), h.t.z(),
        html_escape(axis_angle_text(h.R)), h.verify.confidence, h.cost, h.matches.size(), h.faces_visible,
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

}  // namespace fs::host::rec
