#pragma once
// Pictures of a segmentation and its PFRG, for people:
//  * segmentation PNG: one colour per known region, grey shades for unknown regions, black = no data,
//    white = borders between regions;
//  * PFRG SVG: nodes at their regions' image positions (radius ~ sqrt(area)), labelled with id, area (mm^2)
//    and normal; arcs labelled with the border length (mm); the supernode drawn apart;
//  * ENM SVG (extended needle map, thesis ch. 3.4.3): the unit sphere seen from the observer, one needle per
//    face along its normal with length ~ area, great-circle arcs between adjacent faces.
#include <filesystem>
#include <string>

#include "host/pfrg/pfrg.hpp"
#include "host/segment/segmentation.hpp"

namespace fs::host::seg {

void write_segmentation_png(const Segmentation& s, const std::filesystem::path& path);
std::string pfrg_svg(const Pfrg& g, const Segmentation& s);
// view: unit direction from the scene toward the observer (the sphere is drawn as seen along -view).
std::string enm_svg(const Pfrg& g, const Vec3& view);
// Writes segmentation.png, pfrg.svg and enm.svg into dir (created when missing).
void write_pictures(const Segmentation& s, const Pfrg& g, const Vec3& view, const std::filesystem::path& dir);

}  // namespace fs::host::seg
