// CSV input of point matches and control points.
//
// Format: comma-separated, first line a header naming the columns; columns
// are found by header name (exact, case-sensitive, surrounding whitespace
// and double quotes ignored), in any order, and other columns are ignored;
// one record per line (LF or CRLF); blank lines are skipped. Values are
// decimal numbers (std::from_chars syntax, surrounding whitespace and
// double quotes allowed).
//
// Failures throw gissar::InputError whose `where` names the file (and
// "file:line" for a bad record): a missing or unreadable file, an empty
// file, a duplicated header name, a required column missing, a record with
// fewer fields than the header, a field that is not a number, or a
// non-finite value (NaN, infinity).
#pragma once

#include <filesystem>
#include <vector>

#include "gissar/mvg/point_match.h"

namespace gissar::mvg {

// Largest magnitude of a CSV coordinate (pixels or metres): larger values are
// an InputError.
constexpr double kMaxPointCoordinate = 1e9;

// Matches from columns x1, y1, x2, y2 (pixels), in file order.
std::vector<PointMatch> ReadMatchesCsv(const std::filesystem::path& path);

// Control points from columns X, Y, Z (ENU metres) and x, y (pixels), in
// file order.
std::vector<ControlPoint> ReadControlPointsCsv(const std::filesystem::path& path);

}  // namespace gissar::mvg
