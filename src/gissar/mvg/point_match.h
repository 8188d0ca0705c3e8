// Point correspondences shared by the mvg module: image-to-image matches and
// ground control points (3D scene point with its image position).
//
// Error policy of the whole module (every header repeats what applies):
//  - invalid input values (NaN or infinite coordinates, too few points,
//    a matrix that is not of the required form) throw gissar::InputError;
//  - well-formed input whose geometry does not determine the answer
//    (degenerate or collinear configurations, RANSAC finding no model)
//    gives std::nullopt;
//  - a failed GISSAR_CHECK is a bug in gissar, never a property of the data.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace gissar::mvg {

// One correspondence between image 1 and image 2, in pixels (x = column =
// slant range, y = row = azimuth; pixel centres at integer coordinates).
// For registration image 1 is the fixed image and image 2 the moving one.
struct PointMatch {
  Eigen::Vector2d p1 = Eigen::Vector2d::Zero();  // (x1, y1) in image 1
  Eigen::Vector2d p2 = Eigen::Vector2d::Zero();  // (x2, y2) in image 2
};

// A scene point with known position and its measured image position.
struct ControlPoint {
  Eigen::Vector3d world = Eigen::Vector3d::Zero();  // (X, Y, Z): ENU metres
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // (x, y): pixels
};

// Throws InputError naming `what` and the 0-based index of the first match
// with a non-finite coordinate; does nothing when all are finite.
void CheckFinite(const std::vector<PointMatch>& matches, const std::string& what);
void CheckFinite(const std::vector<ControlPoint>& points, const std::string& what);

}  // namespace gissar::mvg
