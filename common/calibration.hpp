#pragma once
// Scanner geometry and calibration, shared by the simulator (rendering), the firmware (ScanBegin) and the
// host (triangulation).
//
// Frames (all lengths in millimetres):
//  * world: the table plane is z = 0, z points up toward the scanner, x to the right of the bench, y away.
//  * camera: OpenCV convention, x right, y down, z along the optical axis. x_world = R_world_cam x_cam + t.
//  * pixels: (u, v) = (column, row), the centre of pixel (0, 0) is at (0, 0).
//  * laser: a light plane that contains the galvo mirror's rotation axis. Its normal at mirror angle 0 is
//    normal_at_zero; rotating the mirror by a turns the plane by optical_gain * a about the axis (a mirror
//    doubles the angle). The mirror angle of galvo step k is mirror_angle_at_step0 + k * rad_per_step.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace fs {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// The plane { x : n . x = d } with |n| = 1.
struct Plane {
  Vec3 n = Vec3::UnitZ();
  double d = 0.0;
  double signed_distance(const Vec3& x) const { return n.dot(x) - d; }
};

struct CameraModel {
  std::uint32_t width = 1280;
  std::uint32_t height = 1024;
  double fx = 1600.0, fy = 1600.0, cx = 639.5, cy = 511.5;
  // Brown-Conrady distortion, OpenCV's meaning and names.
  double k1 = 0.0, k2 = 0.0, k3 = 0.0, p1 = 0.0, p2 = 0.0;
  Mat3 R_world_cam = Mat3::Identity();
  Vec3 t_world_cam = Vec3::Zero();

  // Normalized image coordinates (x/z, y/z) -> distorted normalized coordinates.
  Vec2 distort(const Vec2& xn) const;
  // Distorted pixel -> undistorted normalized coordinates (fixed-point iteration, converges for |k| < ~0.5).
  Vec2 undistort_pixel(const Vec2& px) const;
  // World point -> pixel. Returns false when the point is behind the camera.
  bool project(const Vec3& x_world, Vec2& px) const;
  // Unit viewing ray (world frame) through a distorted pixel; origin is center().
  Vec3 ray_world(const Vec2& px) const;
  Vec3 center() const { return t_world_cam; }
};

struct LaserModel {
  Vec3 axis_point = Vec3::Zero();
  Vec3 axis_dir = Vec3::UnitY();
  Vec3 normal_at_zero = Vec3::UnitX();
  double optical_gain = 2.0;
  double mirror_angle_at_step0 = 0.0;  // rad
  double rad_per_step = 1e-4;          // mirror rad per galvo step

  double mirror_angle(double step) const { return mirror_angle_at_step0 + step * rad_per_step; }
  Plane plane_at_mirror_angle(double mirror_angle_rad) const;
  Plane plane_at_step(double step) const { return plane_at_mirror_angle(mirror_angle(step)); }
  // The (fractional) galvo step whose light plane passes through x: the inverse of plane_at_step. A plane
  // through the axis is the same plane half a turn on, so of the steps whose plane contains x this is the one
  // whose plane angle lies within a quarter turn of near_step's (pass the middle of the sweep: steps are
  // absolute, and a sweep may start far from step 0). NaN for a point on the axis or a zero step size.
  double step_through(const Vec3& x, double near_step = 0.0) const;
  // Aims the sweep (axis_point, axis_dir and optical_gain set): the plane at mirror angle 0 through the world
  // origin, step 0's plane through `first` and step steps - 1's through `last`.
  void aim(const Vec3& first, const Vec3& last, std::uint32_t steps);
};

struct ScannerCalibration {
  CameraModel camera;
  LaserModel laser;
  std::int32_t first_step = 0;
  std::uint32_t step_count = 500;
  Plane table{};  // the table plane (world z = 0 by default)

  // The bench-top default: 1280x1024 mono camera 500 mm above the table looking straight down, galvo mirror
  // 200 mm to its side (+x) at the same height, axis along y, sweeping the stripe over x in [-150, 150] mm on
  // the table in step_count steps.
  static ScannerCalibration bench_default(std::uint32_t step_count = 500);
  // Whether the scan can measure x at all: it projects into the camera image and the sweep's steps reach it
  // (first_step .. first_step + step_count - 1). Shadows are not tested.
  bool covers(const Vec3& x) const;
};

// Intersection of the ray origin + s * dir (s > 0) with a plane. Returns false when the ray is parallel to
// the plane within cos_min (grazing) or the hit is behind the origin.
bool intersect_ray_plane(const Vec3& origin, const Vec3& dir, const Plane& plane, double cos_min, Vec3& hit);

}  // namespace fs
