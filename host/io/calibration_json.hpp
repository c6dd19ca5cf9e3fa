#pragma once
// The calibration file (JSON) that `facetscan calibrate` writes and the firmware embeds in ScanBegin.
//
// {"format": "facetscan-calibration", "version": 1, "units": "mm",
//  "camera": {"width": 1280, "height": 1024, "fx": 1600, "fy": 1600, "cx": 639.5, "cy": 511.5,
//             "k1": -0.04, "k2": 0.01, "k3": 0, "p1": 0, "p2": 0,
//             "R_world_cam": [[1,0,0],[0,-1,0],[0,0,-1]], "t_world_cam": [0,0,500]},
//  "laser": {"axis_point": [200,0,500], "axis_dir": [0,1,0], "normal_at_zero": [..], "optical_gain": 2,
//            "mirror_angle_at_step0": -0.1, "rad_per_step": 0.0003},
//  "first_step": 0, "step_count": 500, "table": {"n": [0,0,1], "d": 0}}
// Angles in radians, lengths in millimetres, frames as in common/calibration.hpp. Extra members (e.g. the
// "residuals" report of `facetscan calibrate`) are ignored when reading.
#include <string>

#include <nlohmann/json.hpp>

#include "common/calibration.hpp"

namespace fs::host {

nlohmann::json calibration_to_json(const ScannerCalibration& c);
// Throws fs::Error "<source>: <field>: <what>" for missing / mistyped / non-finite / inconsistent fields.
ScannerCalibration calibration_from_json(const nlohmann::json& j, const std::string& source);

ScannerCalibration read_calibration_file(const std::string& path);
void write_calibration_file(const std::string& path, const ScannerCalibration& c,
                            const nlohmann::json& extra = nlohmann::json::object());

}  // namespace fs::host
