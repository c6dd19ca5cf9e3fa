// Ideal partial views of a model (convex visibility: a face is seen when it faces the sensor).
#include <map>

#include "host/library/views.hpp"

namespace fs::host {

std::vector<int> visible_faces(const Model& model, const Mat3& R, const Vec3& view_dir, double min_cos) {
  std::vector<int> out;
  const Vec3 toward_sensor = -view_dir.normalized();
  for (std::size_t i = 0; i < model.faces.size(); ++i)
    if ((R * model.faces[i].normal).dot(toward_sensor) > min_cos) out.push_back(static_cast<int>(i));
  return out;
}

Pfrg partial_view(const Model& model, const Mat3& R, const Vec3& view_dir, const ViewOptions& options) {
  Pfrg g;
  g.name = model.name;
  g.observer = -view_dir.normalized();
  g.has_observer = true;
  const std::vector<int> vis = visible_faces(model, R, view_dir, options.min_cos);
  std::vector<bool> seen(model.faces.size(), false);
  for (int i : vis) {
    seen[static_cast<std::size_t>(i)] = true;
    const ModelFace& f = model.faces[static_cast<std::size_t>(i)];
    PfrgNode n;
    n.id = i;
    n.area = f.area;
    n.normal = R * f.normal;
    n.centroid = R * f.centroid + options.translation;
    n.offset = n.normal.dot(n.centroid);
    n.has_plane = true;
    g.nodes.push_back(n);
  }
  std::map<int, double> to_super;  // visible face -> border with invisible faces
  for (const auto& a : model.graph.arcs) {
    const bool sa = seen[static_cast<std::size_t>(a.a)], sb = seen[static_cast<std::size_t>(a.b)];
    if (sa && sb)
      g.arcs.push_back(a);
    else if (sa)
      to_super[a.a] += a.border;
    else if (sb)
      to_super[a.b] += a.border;
  }
  if (options.supernode && !to_super.empty()) {
    PfrgNode s;
    s.id = options.supernode_id >= 0 ? options.supernode_id : static_cast<int>(model.faces.size());
    s.supernode = true;
    g.nodes.push_back(s);
    for (const auto& [face, len] : to_super) g.arcs.push_back({face, s.id, len});
  }
  return g;
}

}  // namespace fs::host
