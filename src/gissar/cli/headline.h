// The one-line result ("headline") each command that computes something
// prints on stdout after its file names, so a user sees the answer without
// opening the JSON: the heading change of fmatrix, the camera of resect, the
// fix of locate, the success of evaluate, the agreement of validate, the
// output grid of geocode. Each reads the result JSON the command wrote (the
// same keys as the file); a key the result lacks is left out of the line.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace gissar::cli {

// "fmatrix: heading change 29.97 deg (candidates 29.97, 150.03), 812 of 900 matches inliers, Gold Standard rms
// 0.41 px; KvD s 1.0021, theta 1.20 deg, phi 88.10 deg"
std::string FmatrixHeadline(const nlohmann::json& result);
// "resect: heading 30.01 +- 0.02 deg, depression 39.98 +- 0.03 deg, spacings 10.00 x 10.00 m, rms 0.12 px"
std::string ResectHeadline(const nlohmann::json& result);
// "locate: fix heading 30.00 deg, depression 40.00 deg, sensor lon/lat/h ...; moved 212.3 m from the prior;
// converged" or "...; not converged: <reason>"; with a product: the error against the annotated track.
std::string LocateHeadline(const nlohmann::json& report);
// "evaluate: 99 of 100 trials succeeded (<= 2 cells), median error 0.62 cells (9.4 m), p95 1.9 cells; bias
// along -17.0 m, cross 2.1 m"
std::string EvaluateHeadline(const nlohmann::json& summary);
// "validate: ..." from the validate report.
std::string ValidateHeadline(const nlohmann::json& report);
// "geocode: 1204 x 980 px of 30 m in EPSG:32631"
std::string GeocodeHeadline(const nlohmann::json& sidecar);

}  // namespace gissar::cli
