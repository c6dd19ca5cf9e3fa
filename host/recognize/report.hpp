#pragma once
// Outputs people look at: the result table (terminal), an HTML report directory (segmentation image, PFRG,
// ENM, a top view of the scene with every recognized model drawn in its pose, the object table, statistics)
// and the cloud coloured by object (PLY).
#include <filesystem>
#include <string>

#include "host/io/organized_cloud.hpp"
#include "host/recognize/recognizer.hpp"

namespace fs::host::rec {

// Rotation as axis-angle: "123.4° about (0.00, 0.00, 1.00)".
std::string axis_angle_text(const Mat3& R);

// A fixed-width table: model, instance, position (mm), rotation (axis-angle), confidence, cost, faces; an
// ambiguous object is followed by its ambiguity_text().
std::string result_table(const Recognition& r, const Library& library);

// The candidates of an ambiguous object (Hypothesis::ambiguous()) with their confidence and fit:
// "ambiguous: cube (0.50, fit 1.00) or box (0.49, fit 0.99); they differ only out of view".
std::string ambiguity_text(const Hypothesis& h, const Library& library);

// `bytes` in base64 (RFC 4648, with '=' padding): the data: URIs and scene-data.js of the reports.
std::string base64(const std::string& bytes);

// Writes DIR/index.html, segmentation.png, pfrg.svg, enm.svg, scene.svg (+ scene_top.png: the top view with
// every recognized object coloured over its points; scene.svg adds the outlines and a legend) and
// objects.ply. `title` names the input. `view_html` is placed above the table (host/web/report_view.hpp: the
// 3D view).
void write_report(const std::filesystem::path& dir, const std::string& title, const OrganizedCloud& cloud,
                  const Recognizer& recognizer, const Recognition& r, const std::string& view_html = {});

}  // namespace fs::host::rec
