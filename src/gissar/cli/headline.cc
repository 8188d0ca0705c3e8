#include "gissar/cli/headline.h"

#include <cmath>
#include <cstdio>
#include <string>

namespace gissar::cli {
namespace {

using nlohmann::json;

// `value` with `decimals` after the point; "n/a" for null or non-numbers.
std::string Fixed(const json& value, int decimals) {
  if (!value.is_number()) return "n/a";
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", decimals, value.get<double>());
  return text;
}

// The value at `path` ("a/b/c", array indices as numbers), or null.
const json& At(const json& root, std::initializer_list<const char*> path) {
  static const json kNull;
  const json* node = &root;
  for (const char* key : path) {
    if (node->is_object() && node->contains(key)) {
      node = &(*node)[key];
    } else if (node->is_array() && std::isdigit(static_cast<unsigned char>(key[0]))) {
      const size_t index = std::stoul(key);
      if (index >= node->size()) return kNull;
      node = &(*node)[index];
    } else {
      return kNull;
    }
  }
  return *node;
}

}  // namespace

std::string FmatrixHeadline(const json& r) {
  std::string line = "fmatrix: ";
  if (r.contains("heading_change_deg")) {
    line += "heading change " + Fixed(r["heading_change_deg"], 2) + " deg";
    const json& candidates = At(r, {"heading_change_candidates"});
    if (candidates.is_array() && candidates.size() > 1) {
      line += " (candidates";
      for (size_t i = 0; i < candidates.size(); ++i) line += (i ? ", " : " ") + Fixed(candidates[i], 2);
      line += ")";
    }
    line += ", ";
  } else {
    line += "heading change not determined (give --depressions and the spacings), ";
  }
  const json& inliers = At(r, {"inliers"});  // the inlier indices
  line += (inliers.is_array() ? std::to_string(inliers.size()) : Fixed(inliers, 0)) + " of " +
          Fixed(At(r, {"num_matches"}), 0) + " matches inliers, " +
          "Gold Standard rms " + Fixed(At(r, {"rms_gs_px"}), 3) + " px; KvD s " + Fixed(At(r, {"kvd", "s"}), 4) +
          ", theta " + Fixed(At(r, {"kvd", "theta_deg"}), 2) + " deg, phi " + Fixed(At(r, {"kvd", "phi_deg"}), 2) +
          " deg";
  return line;
}

std::string ResectHeadline(const json& r) {
  std::string line = "resect: heading " + Fixed(At(r, {"heading_deg"}), 3) + " +- " +
                     Fixed(At(r, {"sigma", "heading_deg"}), 3) + " deg, depression " +
                     Fixed(At(r, {"depression_deg"}), 3) + " +- " + Fixed(At(r, {"sigma", "depression_deg"}), 3) +
                     " deg, spacings " + Fixed(At(r, {"range_spacing_m"}), 3) + " x " +
                     Fixed(At(r, {"azimuth_spacing_m"}), 3) + " m (range x azimuth), rms " +
                     Fixed(At(r, {"rms_px"}), 3) + " px";
  const json& sensor = At(r, {"sensor_enu_m"});
  if (sensor.is_array() && sensor.size() == 3) {
    line += ", sensor ENU " + Fixed(sensor[0], 1) + ", " + Fixed(sensor[1], 1) + ", " + Fixed(sensor[2], 1) + " m";
  }
  if (At(r, {"converged"}).is_boolean() && !r["converged"].get<bool>()) line += "; not converged";
  return line;
}

std::string LocateHeadline(const json& r) {
  std::string line = "locate: ";
  const bool converged = At(r, {"converged"}).is_boolean() && r["converged"].get<bool>();
  if (r.contains("fix")) {  // a product: its own track fixed
    const json& fix = r["fix"];
    const json& position = At(fix, {"frame", "sensor_lon_lat_height"});
    if (position.is_array() && position.size() == 3) {
      line += "fix sensor lon " + Fixed(position[0], 6) + ", lat " + Fixed(position[1], 6) + ", h " +
              Fixed(position[2], 1) + " m";
    } else {
      line += "fix";
    }
    if (At(fix, {"time_utc"}).is_string()) line += " at " + fix["time_utc"].get<std::string>();
    const json& correction = At(fix, {"correction"});
    if (correction.is_object()) {
      line += ", correction along " + Fixed(correction["along_m"], 1) + " m, cross " +
              Fixed(correction["cross_m"], 1) + " m, up " + Fixed(correction["up_m"], 1) + " m";
    }
    const json& error = At(fix, {"error_against_annotated_track"});
    if (error.is_object()) {
      line += "; error against the annotated track " + Fixed(error["position_error_m"], 1) + " m (prior " +
              Fixed(error["prior_position_error_m"], 1) + " m)";
      if (At(r, {"cell_m"}).is_number() && r["cell_m"].get<double>() > 0) {
        line += ", " + Fixed(error["position_error_m"].get<double>() / r["cell_m"].get<double>(), 2) + " cells";
      }
    }
  } else {
    const json& pose = At(r, {"pose"});
    const json& sensor = At(pose, {"sensor_lon_lat_h"});
    line += "fix heading " + Fixed(At(pose, {"heading_deg"}), 3) + " deg, depression " +
            Fixed(At(pose, {"depression_deg"}), 3) + " deg";
    if (sensor.is_array() && sensor.size() == 3) {
      line += ", sensor lon " + Fixed(sensor[0], 6) + ", lat " + Fixed(sensor[1], 6) + ", h " + Fixed(sensor[2], 1) +
              " m";
    }
    const json& a = At(pose, {"sensor_enu_m"});
    const json& b = At(r, {"prior", "sensor_enu_m"});
    if (a.is_array() && b.is_array() && a.size() == 3 && b.size() == 3) {
      const double d = std::hypot(std::hypot(a[0].get<double>() - b[0].get<double>(),
                                             a[1].get<double>() - b[1].get<double>()),
                                  a[2].get<double>() - b[2].get<double>());
      line += "; " + Fixed(d, 1) + " m from the prior";
    }
    if (At(r, {"inliers"}).is_number()) line += ", " + Fixed(r["inliers"], 0) + " inliers";
  }
  line += converged ? "; converged" : "; not converged: " + (At(r, {"reason"}).is_string()
                                                                 ? r["reason"].get<std::string>()
                                                                 : std::string("no reason given"));
  return line;
}

std::string EvaluateHeadline(const json& s) {
  const json& trials = At(s, {"trials"});
  const json& rate = At(s, {"success_rate"});
  std::string line = "evaluate: ";
  if (trials.is_number() && rate.is_number()) {
    const double n = trials.get<double>();
    line += Fixed(json(std::round(rate.get<double>() * n)), 0) + " of " + Fixed(trials, 0) +
            " trials succeeded (" + Fixed(json(100.0 * rate.get<double>()), 1) + " %, <= " +
            Fixed(At(s, {"success_cells"}), 3) + " cells)";
  }
  line += ", median error " + Fixed(At(s, {"position_error_cells", "median"}), 2) + " cells (" +
          Fixed(At(s, {"position_error_m", "median"}), 1) + " m), p95 " +
          Fixed(At(s, {"position_error_cells", "p95"}), 2) + " cells";
  if (At(s, {"heading_error_deg", "median"}).is_number()) {
    line += ", heading error median " + Fixed(s["heading_error_deg"]["median"], 3) + " deg";
  }
  const json& check = At(s, {"covariance_check"});
  if (check.is_object() && At(check, {"along_m"}).is_object() && At(check, {"cross_m"}).is_object()) {
    line += "; bias along " + Fixed(check["along_m"]["error_mean"], 1) + " m (sd " +
            Fixed(check["along_m"]["error_sd"], 1) + "), cross " + Fixed(check["cross_m"]["error_mean"], 1) +
            " m (sd " + Fixed(check["cross_m"]["error_sd"], 1) + ")";
    if (At(check, {"inside_95_region", "along_cross_rate"}).is_number()) {
      line += ", " + Fixed(json(100.0 * check["inside_95_region"]["along_cross_rate"].get<double>()), 0) +
              " % inside the stated 95 % ellipse";
    }
  }
  line += "; " + Fixed(At(s, {"seconds_per_fix", "median"}), 2) + " s per fix";
  return line;
}

std::string ValidateHeadline(const json& r) {
  std::string line = "validate:";
  const json& corr = At(r, {"correlation"});
  if (corr.is_array() && !corr.empty()) {
    line += " simulated vs real dB correlation";
    for (size_t i = 0; i < corr.size(); ++i) {
      line += std::string(i ? "," : "") + " r " + Fixed(corr[i]["r_db"], 3) + " at " + Fixed(corr[i]["looks"], 0) +
              "x" + Fixed(corr[i]["looks"], 0) + " looks";
    }
  }
  const json& geo = At(r, {"geolocation"});
  if (geo.is_object()) {
    line += "; geolocation against the reference: range " + Fixed(geo["range_px_rms"], 3) + " px rms, azimuth " +
            Fixed(geo["azimuth_px_rms"], 3) + " px rms, ground " + Fixed(geo["ground_m_rms"], 2) + " m rms";
  }
  if (At(r, {"pixels_geolocated"}).is_number()) line += "; " + Fixed(r["pixels_geolocated"], 0) + " pixels geolocated";
  return line;
}

std::string GeocodeHeadline(const json& g) {
  return "geocode: " + Fixed(At(g, {"width"}), 0) + " x " + Fixed(At(g, {"height"}), 0) + " px of " +
         Fixed(At(g, {"pixel_size_m"}), 3) + " m in " + (At(g, {"crs"}).is_string() ? g["crs"].get<std::string>() : "?") +
         ", " + Fixed(At(g, {"valid_pixels"}), 0) + " pixels with a value";
}

}  // namespace gissar::cli
