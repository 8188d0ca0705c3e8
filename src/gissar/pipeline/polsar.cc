#include "gissar/pipeline/polsar.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <map>

#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/geo/sentinel1_safe.h"
#include "gissar/image/polarimetry.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/sensor/range_doppler.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::string Upper(std::string text) {
  for (char& c : text) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return text;
}

std::string Joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out.empty() ? "none" : out;
}

std::string Num(double value, const char* format = "%.12g") {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, format, value);
  return buffer;
}

// The four channels with what the outputs need to know of their grid.
struct QuadInput {
  image::QuadPolImage image;
  std::string unit;  // of |S|^2
  geo::Metadata metadata;
  geo::Georeference georeference;  // of the multilooked grid
  json description;
  json inputs = json::array();
};

QuadInput FromProduct(const PolsarRequest& request, int looks_range, int looks_azimuth) {
  if (geo::IsSentinel1Path(request.product)) {
    // Sentinel-1 transmits one polarisation (single or dual-pol products):
    // no scattering matrix to decompose.
    std::string channels;
    for (const geo::Sentinel1Entry& e : geo::OpenSentinel1(request.product).entries) {
      if (channels.find(e.polarization) == std::string::npos) channels += (channels.empty() ? "" : ", ") + e.polarization;
    }
    throw InputError("a Sentinel-1 product holds " + channels +
                         " only: a quad-pol decomposition needs HH, HV, VH and VV (a NISAR or ALOS quad-pol RSLC, or "
                         "`simulate --polarization quad --coherent`)",
                     "--product (" + request.product + ")");
  }
  QuadInput q;
  geo::RslcReadOptions options;
  options.frequency = request.frequency;
  options.polarization = "HH";
  options.read_amplitude = false;
  options.read_complex = false;  // metadata and the stored layers first
  options.read_calibration = true;
  options.max_bytes = request.max_memory_bytes;
  options.bytes_per_pixel = 4 * 8.0 + 12.0 * 4.0 / double(looks_range * looks_azimuth);
  // The first stored layer gives the grid (HH may be the one missing).
  geo::RslcProduct p;
  {
    geo::RslcReadOptions probe = options;
    probe.max_bytes = 0;
    try {
      p = geo::ReadRslcProduct(request.product, probe);
    } catch (const InputError& e) {
      if (std::string(e.what()).find("(polarisations stored:") == std::string::npos) throw;
      // HH is not stored: read the metadata through any stored layer.
      for (const char* c : {"HV", "VH", "VV"}) {
        probe.polarization = c;
        try {
          p = geo::ReadRslcProduct(request.product, probe);
          break;
        } catch (const InputError&) {
        }
      }
      if (p.zero_doppler_time_s.empty()) throw;
    }
  }
  std::vector<std::string> missing;
  for (const char* c : material::kQuadChannelNames) {
    if (std::find(p.stored_polarizations.begin(), p.stored_polarizations.end(), c) == p.stored_polarizations.end()) {
      missing.push_back(c);
    }
  }
  if (!missing.empty()) {
    throw InputError("quad needs four channels: frequency " + request.frequency + " has no " + Joined(missing) +
                         " layer (stored: " + Joined(p.stored_polarizations) +
                         "; listOfPolarizations: " + Joined(p.polarizations) + ")",
                     request.product);
  }
  for (const char* c : material::kQuadChannelNames) {
    geo::RslcReadOptions read = options;
    read.polarization = c;
    read.read_complex = true;
    read.read_calibration = false;
    geo::RslcProduct layer = geo::ReadRslcProduct(request.product, read);
    std::vector<std::complex<float>>& target = c == std::string("HH")   ? q.image.hh
                                               : c == std::string("HV") ? q.image.hv
                                               : c == std::string("VH") ? q.image.vh
                                                                        : q.image.vv;
    target = std::move(layer.slc);
  }
  q.image.width = p.cols();
  q.image.height = p.rows();
  q.unit = "|DN|^2 (the product's SLC samples squared)";
  if (p.beta0_lut) {
    const auto [lo, hi] = std::minmax_element(p.beta0_lut->values.begin(), p.beta0_lut->values.end());
    if (*lo == 1.0 && *hi == 1.0) q.unit = "beta0 (linear; the product's beta0 LUT is 1)";
  }
  q.inputs.push_back(InputFileRecord(request.product));
  const double dt = p.azimuth_spacing_s(), dr = p.range_spacing_m();
  const int lr = looks_range, la = looks_azimuth;
  const double t0 = p.zero_doppler_time_s.front() + 0.5 * (la - 1) * dt;
  const double r0 = p.slant_range_m.front() + 0.5 * (lr - 1) * dr;
  q.metadata["GISSAR_GEOMETRY"] =
      "product radar grid multilooked " + std::to_string(lr) + " x " + std::to_string(la) +
      " (range x azimuth): row = zero-Doppler azimuth line, column = slant-range bin";
  q.metadata["GISSAR_PRODUCT"] = fs::absolute(request.product).string();
  q.metadata["GISSAR_FREQUENCY"] = request.frequency;
  q.metadata["GISSAR_EPOCH_UTC"] = p.epoch_utc;
  q.metadata["GISSAR_FIRST_TIME_S"] = Num(t0, "%.9f");
  q.metadata["GISSAR_TIME_SPACING_S"] = Num(la * dt);
  q.metadata["GISSAR_FIRST_RANGE_M"] = Num(r0, "%.6f");
  q.metadata["GISSAR_RANGE_SPACING_M"] = Num(lr * dr, "%.9g");
  q.metadata["GISSAR_LOOK_SIDE"] = sensor::ToString(sensor::LookSideOf(p.look_left));
  q.metadata["GISSAR_WAVELENGTH_M"] = Num(p.wavelength_m);
  q.metadata["GISSAR_GCPS"] = "WGS84, zero-Doppler rdr2geo on the ellipsoid (height 0 m, no DEM)";
  // GCPs: a lattice of up to 6 x 6 output pixel centres on the ellipsoid.
  const int out_w = p.cols() / lr, out_h = p.rows() / la;
  const sensor::Orbit orbit(p.orbit.time_s, p.orbit.position_m, p.orbit.velocity_mps);
  const sensor::LookSide side = p.look_left ? sensor::LookSide::kLeft : sensor::LookSide::kRight;
  const int nx = std::min(out_w, 6), ny = std::min(out_h, 6);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double c = nx > 1 ? double(i) * (out_w - 1) / (nx - 1) : 0.0;
      const double r = ny > 1 ? double(j) * (out_h - 1) / (ny - 1) : 0.0;
      const auto ground = sensor::Rdr2Geo(orbit, t0 + r * la * dt, r0 + c * lr * dr, side,
                                          [](double, double) { return std::optional<double>(0.0); });
      if (!ground) continue;
      q.georeference.gcps.push_back({c + 0.5, r + 0.5, ground->x(), ground->y(), ground->z()});
    }
  }
  q.description = {{"kind", "NISAR RSLC product"},
                   {"file", p.path},
                   {"mission", p.mission},
                   {"frequency", request.frequency},
                   {"epoch_utc", p.epoch_utc},
                   {"rows", p.rows()},
                   {"cols", p.cols()},
                   {"zero_doppler_time_spacing_s", dt},
                   {"slant_range_spacing_m", dr},
                   {"wavelength_m", p.wavelength_m},
                   {"look_side", sensor::ToString(sensor::LookSideOf(p.look_left))},
                   {"beta0_lut", p.beta0_lut ? json(p.beta0_lut->dataset) : json(nullptr)}};
  return q;
}

QuadInput FromImage(const PolsarRequest& request, int looks_range, int looks_azimuth) {
  QuadInput q;
  const geo::ComplexRaster raster = geo::ReadComplexRaster(request.image);
  std::map<std::string, size_t> named;
  for (size_t b = 0; b < raster.band_names.size(); ++b) {
    const std::string name = Upper(raster.band_names[b]);
    if (!named.count(name)) named[name] = b;
  }
  std::vector<std::string> missing, names;
  for (const char* c : material::kQuadChannelNames) {
    if (!named.count(c)) missing.push_back(c);
  }
  for (const std::string& name : raster.band_names) names.push_back(name.empty() ? "(unnamed)" : name);
  if (!missing.empty()) {
    throw InputError("quad needs four channels: no band named " + Joined(missing) + " (bands: " + Joined(names) + ")",
                     request.image);
  }
  CheckMemoryBudget(double(raster.width) * raster.height * (4 * 8.0 + 8.0 * raster.bands.size()),
                    request.max_memory_bytes, "the four channels of " + request.image, "crop the image");
  q.image.width = raster.width;
  q.image.height = raster.height;
  for (const char* c : material::kQuadChannelNames) {
    const std::vector<float>& interleaved = raster.bands[named.at(c)];
    std::vector<std::complex<float>> plane(size_t(raster.width) * raster.height);
    for (size_t k = 0; k < plane.size(); ++k) plane[k] = {interleaved[2 * k], interleaved[2 * k + 1]};
    (c == std::string("HH")   ? q.image.hh
     : c == std::string("HV") ? q.image.hv
     : c == std::string("VH") ? q.image.vh
                              : q.image.vv) = std::move(plane);
  }
  const std::string band_unit =
      raster.band_units.empty() ? std::string() : raster.band_units[named.at("HH")];
  q.unit = band_unit.empty()           ? "|s|^2 (the image's samples squared)"
           : band_unit == "sqrt(m2/m2)" ? std::string("m2/m2")
                                        : "(" + band_unit + ")^2";
  // Metadata other than the input's own grid description; GCPs rescaled.
  for (const auto& [key, value] : raster.metadata) {
    if (key.rfind("GISSAR_", 0) != 0) q.metadata[key] = value;
  }
  q.metadata["GISSAR_GEOMETRY"] = "the input's grid multilooked " + std::to_string(looks_range) + " x " +
                                  std::to_string(looks_azimuth) + " (range = columns x azimuth = rows)";
  q.metadata["GISSAR_SOURCE"] = fs::absolute(request.image).string();
  try {
    const geo::Georeference in = geo::ReadGeoreference(request.image);
    const double out_w = raster.width / looks_range, out_h = raster.height / looks_azimuth;
    for (geo::GroundControlPoint g : in.gcps) {
      g.pixel /= looks_range;
      g.line /= looks_azimuth;
      if (g.pixel >= 0.0 && g.line >= 0.0 && g.pixel <= out_w && g.line <= out_h) q.georeference.gcps.push_back(g);
    }
    if (!q.georeference.gcps.empty()) q.metadata["GISSAR_GCPS"] = "the input's GCPs, rescaled to the multilooked grid";
  } catch (const InputError&) {
    // No georeferencing: the grid is described by the metadata only.
  }
  q.inputs.push_back(InputFileRecord(request.image));
  q.description = {{"kind", "complex GeoTIFF"},
                   {"file", fs::absolute(request.image).string()},
                   {"width", raster.width},
                   {"height", raster.height},
                   {"bands", names}};
  return q;
}

float Mean(const std::vector<float>& plane, int64_t* count) {
  double sum = 0.0;
  int64_t n = 0;
  for (float v : plane) {
    if (std::isfinite(v)) sum += v, ++n;
  }
  if (count) *count = n;
  return n > 0 ? float(sum / double(n)) : std::numeric_limits<float>::quiet_NaN();
}

}  // namespace

void PolsarRequest::Check() const {
  if (product.empty() == image.empty()) throw ConfigError("give one of --image or --product", "--image/--product");
  if (out_prefix.empty()) throw ConfigError("an output prefix is required", "--out");
  if (frequency != "A" && frequency != "B") throw ConfigError("must be A or B, got '" + frequency + "'", "--frequency");
  if (multilook.size() != 2) throw ConfigError("needs R,A (range and azimuth looks)", "--multilook");
  for (int looks : multilook) {
    if (looks < 1 || looks > 1024) {
      throw ConfigError("looks must be integers in [1, 1024] (R,A), got " + std::to_string(multilook[0]) + "," +
                            std::to_string(multilook[1]),
                        "--multilook");
    }
  }
  const std::string kind = matrix == image::PolarimetricMatrix::kCovariance ? "_C3.tif" : "_T3.tif";
  CheckOutputsAreNotInputs({out_prefix + kind, out_prefix + "_HAalpha.tif", out_prefix + "_pauli.png",
                            out_prefix + ".json"},
                           {image, product});
}

PolsarResult RunPolsar(const PolsarRequest& request, const std::string& command_line, Reporter& reporter) {
  request.Check();
  Stopwatch total;
  const image::PolarimetricMatrix kind = request.matrix;
  const std::string matrix_name = kind == image::PolarimetricMatrix::kCovariance ? "C3" : "T3";
  AtomicOutputs outputs;
  const fs::path out_matrix = outputs.Add(request.out_prefix + "_" + matrix_name + ".tif");
  const fs::path out_haalpha = outputs.Add(request.out_prefix + "_HAalpha.tif");
  const fs::path out_pauli = outputs.Add(request.out_prefix + "_pauli.png");
  const fs::path out_json = outputs.Add(request.out_prefix + ".json");
  const int lr = request.multilook[0], la = request.multilook[1];

  QuadInput input = request.product.empty() ? FromImage(request, lr, la) : FromProduct(request, lr, la);
  ThrowIfCancelled(reporter, "polsar");
  const std::string source = request.product.empty() ? request.image : request.product;
  if (lr > input.image.width || la > input.image.height) {
    throw InputError("looks " + std::to_string(lr) + "," + std::to_string(la) + " exceed the " +
                         std::to_string(input.image.width) + " x " + std::to_string(input.image.height) +
                         " image (range x azimuth)",
                     source);
  }
  const image::PolarimetricMatrixImage matrix = image::MultilookPolarimetricMatrix(input.image, kind, lr, la);
  input.image = {};  // the SLC is no longer needed
  ThrowIfCancelled(reporter, "polsar");
  const image::CloudePottierImage hal = image::CloudePottierPlanes(matrix);
  image::PauliStretch stretch;
  const image::RgbImage pauli = image::PauliRgb(matrix, &stretch);

  geo::Metadata metadata = input.metadata;
  metadata["GISSAR_MULTILOOK"] = std::to_string(lr) + "," + std::to_string(la);
  metadata["GISSAR_VERSION"] = VersionString();
  {
    geo::FloatRaster raster;
    raster.width = matrix.width;
    raster.height = matrix.height;
    raster.bands.assign(matrix.bands.begin(), matrix.bands.end());
    raster.band_names = image::PolarimetricBandNames(kind);
    raster.band_units.assign(raster.bands.size(), input.unit);
    raster.metadata = metadata;
    raster.metadata["GISSAR_MATRIX"] =
        kind == image::PolarimetricMatrix::kCovariance
            ? "covariance C3 = <k_L k_L^H>, k_L = (S_HH, sqrt2 (S_HV + S_VH)/2, S_VV); 11, 22, 33, then 12, 13, 23 "
              "as real and imaginary parts"
            : "coherency T3 = <k k^H>, k = (S_HH + S_VV, S_HH - S_VV, S_HV + S_VH) / sqrt2; 11, 22, 33, then 12, "
              "13, 23 as real and imaginary parts";
    raster.metadata["GISSAR_UNITS"] = input.unit;
    raster.nodata_nan = true;
    raster.georeference = input.georeference;
    geo::WriteFloatGeoTiff(out_matrix, raster);
  }
  {
    geo::FloatRaster raster;
    raster.width = hal.width;
    raster.height = hal.height;
    raster.bands = {hal.entropy, hal.anisotropy, hal.alpha_deg};
    raster.band_names = image::CloudePottierBandNames();
    raster.band_units = {"1", "1", "deg"};
    raster.metadata = metadata;
    raster.metadata["GISSAR_DECOMPOSITION"] =
        "Cloude-Pottier of T3: entropy H in [0, 1] (log base 3), anisotropy A in [0, 1], mean alpha in degrees";
    raster.nodata_nan = true;
    raster.georeference = input.georeference;
    geo::WriteFloatGeoTiff(out_haalpha, raster);
  }
  geo::WritePng(out_pauli, pauli.rgb, pauli.width, pauli.height, 3);

  PolsarResult result;
  int64_t valid = 0;
  result.mean_entropy = Mean(hal.entropy, &valid);
  result.mean_anisotropy = Mean(hal.anisotropy, nullptr);
  result.mean_alpha_deg = Mean(hal.alpha_deg, nullptr);
  result.width = matrix.width;
  result.height = matrix.height;
  auto number = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  json report = ProvenanceHeader("polsar", command_line, request.ToJson());
  report["inputs"] = input.inputs;
  report["source"] = input.description;
  report["looks"] = {{"range", lr}, {"azimuth", la}};
  report["matrix"] = matrix_name;
  report["grid"] = {{"width", matrix.width},
                    {"height", matrix.height},
                    {"pixel_centre", "output (row r, column c) = input (row r A + (A - 1)/2, column c R + (R - 1)/2)"},
                    {"gcps", input.georeference.gcps.size()}};
  report["bands"] = {{matrix_name, image::PolarimetricBandNames(kind)}, {"HAalpha", image::CloudePottierBandNames()}};
  report["units"] = {{matrix_name, input.unit}, {"entropy", "1"}, {"anisotropy", "1"}, {"alpha_deg", "deg"}};
  report["nodata"] = "NaN";
  report["stretch"] = {{"low_db", stretch.low_db},
                       {"high_db", stretch.high_db},
                       {"percentiles", {2, 98}},
                       {"mapping", "grey 1 + 254 (10 log10 P - low_db) / (high_db - low_db), clipped; one scale for "
                                   "the three channels"},
                       {"channels", "R = T22 (|S_HH - S_VV|^2 / 2), G = T33 (|S_HV + S_VH|^2 / 2), B = T11 "
                                    "(|S_HH + S_VV|^2 / 2), multilooked"}};
  report["mean"] = {{"entropy", number(result.mean_entropy)},
                    {"anisotropy", number(result.mean_anisotropy)},
                    {"alpha_deg", number(result.mean_alpha_deg)}};
  report["valid_pixels"] = valid;
  report["timings_s"] = {{"total", total.ElapsedSeconds()}};
  std::vector<std::string> finals;
  for (const fs::path& path : outputs.final_paths()) finals.push_back(fs::absolute(path).string());
  report["outputs"] = finals;
  WriteJsonFile(report, out_json);
  outputs.Commit();
  result.outputs = outputs.final_paths();
  result.report = report;
  return result;
}

}  // namespace gissar::pipeline
