#pragma once
// Planar Face Representation Graph (thesis ch. 3.4, 7.1): nodes = planar faces (area mm^2, unit outward
// normal), arcs = adjacencies (border length mm). One supernode stands for all unknown / NIL / image-border
// regions and is never matched. JSON contract: see DESIGN.md and docs/formats.md.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "common/calibration.hpp"

namespace fs::host {

struct PfrgNode {
  int id = 0;
  bool supernode = false;
  double area = 0.0;           // mm^2
  Vec3 normal = Vec3::Zero();  // unit, out of the object (toward the observer for scene faces)
  // Optional (not part of the minimal JSON contract, written when known):
  double offset = 0.0;           // plane: normal . x = offset (mm)
  Vec3 centroid = Vec3::Zero();  // mm
  bool has_plane = false;        // offset/centroid valid
};

struct PfrgArc {
  int a = 0, b = 0;     // node ids
  double border = 0.0;  // mm
};

struct Pfrg {
  std::string name;
  std::vector<PfrgNode> nodes;
  std::vector<PfrgArc> arcs;
  // Optional (JSON "observer"): unit vector from the object toward the sensor, in the frame of the normals.
  // Used by the visibility condition of the matcher; when absent the matcher takes the area-weighted mean of
  // the scene normals.
  Vec3 observer = Vec3::Zero();
  bool has_observer = false;

  const PfrgNode* find(int id) const;
};

// JSON: {"name":..., "nodes":[{"id","area","normal",["supernode"],["offset","centroid"]}],
//        "arcs":[{"a","b","border"}], ["observer":[x,y,z]]}. Validation: unique integer ids, finite
// non-negative areas/borders, non-zero finite normals (normalized on read), arcs between two different
// existing nodes, no duplicate arcs. Errors name the source and the field (e.g. "s.json: nodes[2].normal:
// ...").
nlohmann::json to_json(const Pfrg& g);
Pfrg pfrg_from_json(const nlohmann::json& j,
                    const std::string& source);  // throws fs::Error naming source/field
Pfrg read_pfrg_json(const std::filesystem::path& path);
void write_pfrg_json(const Pfrg& g, const std::filesystem::path& path);

}  // namespace fs::host
