#include "gissar/pipeline/validate_sentinel1.h"

#include <algorithm>
#include <cmath>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/orbit_file.h"
#include "gissar/sensor/range_doppler.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;

namespace {

// Running sums of squared, absolute and signed differences.
struct Moments {
  int n = 0;
  double sum = 0.0, sum_sq = 0.0, max_abs = 0.0;
  void Add(double v) {
    ++n;
    sum += v;
    sum_sq += v * v;
    max_abs = std::max(max_abs, std::abs(v));
  }
  void Merge(const Moments& o) {
    n += o.n;
    sum += o.sum;
    sum_sq += o.sum_sq;
    max_abs = std::max(max_abs, o.max_abs);
  }
  double Rms() const { return n > 0 ? std::sqrt(sum_sq / n) : 0.0; }
  double Mean() const { return n > 0 ? sum / n : 0.0; }
};

struct GridMoments {
  Moments range, azimuth, ground;
  Moments line, pixel;  // against the grid's line and pixel numbers
  int failures = 0;
};

GridMoments Measure(const geo::Sentinel1Annotation& a) {
  const sensor::Orbit orbit(a.orbit.time_s, a.orbit.position_m, a.orbit.velocity_mps);
  const sensor::LookSide side = a.look_left ? sensor::LookSide::kLeft : sensor::LookSide::kRight;
  GridMoments m;
  for (const geo::Sentinel1GridPoint& g : a.geolocation_grid) {
    const double grid_range_m = a.SlantRangeOfTime(g.slant_range_time_s);
    const Eigen::Vector3d target = geo::LocalFrame::EcefFromGeodetic(g.longitude_deg, g.latitude_deg, g.height_m);
    const std::optional<sensor::RadarCoordinate> rc = sensor::Geo2Rdr(orbit, target, g.azimuth_time_s);
    const double height_m = g.height_m;
    sensor::Rdr2GeoOptions options;
    options.initial_height_m = height_m;
    const std::optional<Eigen::Vector3d> llh = sensor::Rdr2Geo(
        orbit, g.azimuth_time_s, grid_range_m, side,
        [height_m](double, double) -> std::optional<double> { return height_m; }, options);
    if (!rc || !llh) {
      ++m.failures;
      continue;
    }
    m.azimuth.Add((rc->time_s - g.azimuth_time_s) / a.azimuth_time_interval_s);
    if (a.is_grd()) {
      const double gissar_g = a.GroundRangeOfSlantRange(rc->range_m, rc->time_s);
      const double grid_g = a.GroundRangeOfSlantRange(grid_range_m, g.azimuth_time_s);
      m.range.Add((gissar_g - grid_g) / a.range_pixel_spacing_m);
    } else {
      m.range.Add((rc->range_m - grid_range_m) / a.slant_range_spacing_m());
    }
    // gissar's image position of the point against the grid's line/pixel:
    // IW/EW SLC lines through the timing of the burst holding the grid line,
    // otherwise from the first line; pixels from the first sample (GRD:
    // ground range / spacing).
    double line = 0.0;
    if (!a.bursts.empty()) {
      const int b = std::clamp(g.line / a.lines_per_burst, 0, static_cast<int>(a.bursts.size()) - 1);
      line = a.bursts[size_t(b)].first_line +
             (rc->time_s - a.bursts[size_t(b)].azimuth_time_s) / a.azimuth_time_interval_s;
    } else {
      line = (rc->time_s - a.first_line_time_s) / a.azimuth_time_interval_s;
    }
    const double pixel = a.is_grd() ? a.GroundRangeOfSlantRange(rc->range_m, rc->time_s) / a.range_pixel_spacing_m
                                    : (rc->range_m - a.SlantRangeOfTime(a.slant_range_time_s)) / a.slant_range_spacing_m();
    m.line.Add(line - g.line);
    m.pixel.Add(pixel - g.pixel);
    const geo::LocalFrame frame(g.longitude_deg, g.latitude_deg, g.height_m);
    const Eigen::Vector3d enu = frame.EnuFromGeodetic((*llh)[0], (*llh)[1], (*llh)[2]);
    m.ground.Add(std::hypot(enu.x(), enu.y()));
  }
  return m;
}

GeolocationGridAgreement Summarise(const GridMoments& m) {
  GeolocationGridAgreement r;
  r.points = m.azimuth.n;
  r.failures = m.failures;
  r.range_rms_px = m.range.Rms();
  r.range_max_px = m.range.max_abs;
  r.range_mean_px = m.range.Mean();
  r.azimuth_rms_px = m.azimuth.Rms();
  r.azimuth_max_px = m.azimuth.max_abs;
  r.azimuth_mean_px = m.azimuth.Mean();
  r.ground_rms_m = m.ground.Rms();
  r.ground_max_m = m.ground.max_abs;
  r.line_rms_px = m.line.Rms();
  r.line_max_px = m.line.max_abs;
  r.pixel_rms_px = m.pixel.Rms();
  r.pixel_max_px = m.pixel.max_abs;
  return r;
}

bool Passes(const GeolocationGridAgreement& r) {
  return r.points > 0 && r.failures == 0 && r.range_rms_px <= kGridRmsMaxPx && r.azimuth_rms_px <= kGridRmsMaxPx &&
         r.range_max_px <= kGridMaxMaxPx && r.azimuth_max_px <= kGridMaxMaxPx && r.ground_max_m <= kGridGroundMaxM;
}

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

nlohmann::json GeolocationGridAgreement::ToJson() const {
  return {{"points", points},
          {"failures", failures},
          {"range_px", {{"rms", range_rms_px}, {"max", range_max_px}, {"mean", range_mean_px}}},
          {"azimuth_px", {{"rms", azimuth_rms_px}, {"max", azimuth_max_px}, {"mean", azimuth_mean_px}}},
          {"ground_m", {{"rms", ground_rms_m}, {"max", ground_max_m}}},
          {"image_px", {{"line", {{"rms", line_rms_px}, {"max", line_max_px}}},
                        {"pixel", {{"rms", pixel_rms_px}, {"max", pixel_max_px}}}}}};
}

GeolocationGridAgreement CheckGeolocationGrid(const geo::Sentinel1Annotation& annotation,
                                              const std::string& orbit_source) {
  GeolocationGridAgreement r = Summarise(Measure(annotation));
  r.swath = annotation.swath;
  r.polarization = annotation.polarization;
  r.product_type = annotation.product_type;
  r.orbit_source = orbit_source;
  return r;
}

void Sentinel1ValidateRequest::Check() const {
  if (product.empty()) throw ConfigError("a product is required", "--product");
  if (out_prefix.empty()) throw ConfigError("a report prefix is required", "--out");
  CheckOutputsAreNotInputs({fs::path(out_prefix + ".json")}, {product, orbit});
}

nlohmann::json Sentinel1ValidateRequest::ToJson() const {
  return {{"product", product},
          {"orbit", orbit},
          {"swath", swath},
          {"polarization", polarization},
          {"out_prefix", out_prefix}};
}

Sentinel1ValidateResult RunSentinel1Validate(const Sentinel1ValidateRequest& request, const std::string& command_line,
                                             Reporter& reporter) {
  request.Check();
  AtomicOutputs outputs;
  const fs::path json_path = outputs.Add(request.out_prefix + ".json");

  const geo::Sentinel1Product product = geo::OpenSentinel1(request.product);
  std::optional<geo::StateVectors> vectors;
  if (!request.orbit.empty()) vectors = geo::ReadStateVectors(request.orbit);

  // Selection: explicit swath and polarisation go through Entry() (errors
  // name --swath / --polarization); otherwise every matching entry.
  std::vector<const geo::Sentinel1Entry*> selected;
  const std::string swath = Upper(request.swath), pol = Upper(request.polarization);
  if (!swath.empty() || !pol.empty()) product.Entry(swath, pol);  // throws for a swath/polarisation it lacks
  for (const geo::Sentinel1Entry& e : product.entries) {
    if ((swath.empty() || e.swath == swath) && (pol.empty() || e.polarization == pol)) selected.push_back(&e);
  }
  const bool explicit_pair = !swath.empty() && !pol.empty();
  nlohmann::json absent = nlohmann::json::array();
  nlohmann::json swaths = nlohmann::json::array();
  GridMoments pooled;
  bool passed = true;
  for (const geo::Sentinel1Entry* e : selected) {
    if (!e->annotation_present && !explicit_pair) {
      absent.push_back(e->annotation_file);
      reporter.Warn("the manifest lists " + e->annotation_file + " but the SAFE lacks it: " + e->swath + "/" +
                    e->polarization + " not checked");
      continue;
    }
    geo::Sentinel1Annotation a = geo::ReadSentinel1Annotation(product, *e);
    std::string source = "annotation";
    if (vectors) {
      geo::ReplaceSentinel1Orbit(a, product, *vectors, request.orbit);
      source = request.orbit;
    }
    reporter.Info("geolocation grid of " + e->swath + "/" + e->polarization + ": " +
                  std::to_string(a.geolocation_grid.size()) + " points");
    const GridMoments m = Measure(a);
    GeolocationGridAgreement r = Summarise(m);
    r.swath = a.swath;
    r.polarization = a.polarization;
    r.product_type = a.product_type;
    r.orbit_source = source;
    passed = passed && Passes(r);
    pooled.range.Merge(m.range);
    pooled.azimuth.Merge(m.azimuth);
    pooled.ground.Merge(m.ground);
    pooled.line.Merge(m.line);
    pooled.pixel.Merge(m.pixel);
    pooled.failures += m.failures;
    swaths.push_back({{"swath", r.swath},
                      {"polarization", r.polarization},
                      {"product_type", r.product_type},
                      {"annotation", a.file},
                      {"bursts", a.bursts.size()},
                      {"geolocation_grid", r.ToJson()},
                      {"passed", Passes(r)}});
  }
  if (swaths.empty()) {
    throw InputError("the SAFE holds none of the annotations its manifest lists for the selection",
                     product.name + "/annotation");
  }
  nlohmann::json report = ProvenanceHeader("validate", command_line, request.ToJson());
  report["inputs"] = {{"product", product.path}};
  if (!request.orbit.empty()) report["inputs"]["orbit"] = InputFileRecord(request.orbit);
  report["product"] = product.name;
  report["mission"] = product.mission;
  report["mode"] = product.mode;
  report["product_type"] = product.product_type;
  report["epoch_utc"] = product.epoch_utc;
  report["orbit"] = request.orbit.empty() ? "annotation" : request.orbit;
  report["checks"] = {"geolocation_grid"};
  report["geolocation_grid"] = Summarise(pooled).ToJson();
  report["swaths"] = swaths;
  report["absent_annotations"] = absent;
  report["thresholds"] = {{"rms_px", kGridRmsMaxPx}, {"max_px", kGridMaxMaxPx}, {"ground_max_m", kGridGroundMaxM}};
  report["passed"] = passed;
  WriteJsonFile(report, json_path);
  outputs.Commit();
  return {outputs.final_paths(), report};
}

}  // namespace gissar::pipeline
