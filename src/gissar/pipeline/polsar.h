// `gissar polsar`: polarimetric decomposition of a quad-pol SLC
// (docs/radiometry.md, "Polarimetric decomposition"): the multilooked
// covariance C3 or coherency T3, the Cloude-Pottier entropy / anisotropy /
// mean alpha and the Pauli RGB, written as rasters on the multilooked radar
// grid (image/polarimetry.h does the maths).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/image/polarimetry.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

struct PolsarRequest {
  // A complex GeoTIFF whose bands are named HH, HV, VH and VV (band
  // descriptions, any order, case-insensitive) ...
  std::string image;
  // ... or a NISAR RSLC product holding the four layers.
  std::string product;
  std::string frequency = "A";  // product band
  // Looks R,A: R range samples (columns) x A azimuth lines (rows) per output
  // pixel, each >= 1 (required: {0, 0} = not given).
  std::vector<int> multilook = {0, 0};
  // C3 or T3 (image::kPolarimetricMatrices; JSON "covariance"/"coherency").
  image::PolarimetricMatrix matrix = image::PolarimetricMatrix::kCovariance;
  // PREFIX_C3.tif (or _T3.tif), PREFIX_HAalpha.tif, PREFIX_pauli.png, PREFIX.json.
  std::string out_prefix;
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();

  // Throws ConfigError naming the flag (one of --image / --product, --out,
  // --multilook R,A with R, A in [1, 1024], --matrix, --frequency, outputs
  // not overwriting inputs).
  void Check() const;
  nlohmann::json ToJson() const;
  void ApplyJson(const nlohmann::json& values, const std::string& source);
};

struct PolsarResult {
  std::vector<std::filesystem::path> outputs;
  nlohmann::json report;  // PREFIX.json
  int width = 0, height = 0;
  double mean_entropy = 0.0, mean_anisotropy = 0.0, mean_alpha_deg = 0.0;
};

// Reads the four channels, multilooks, decomposes and writes the outputs
// (all or nothing). Rasters: float32, NaN no-data, band names and units;
// GISSAR_* metadata of the multilooked grid (a product's radar grid; an
// image's own metadata) and WGS84 GCPs (a product: zero-Doppler rdr2geo on
// the ellipsoid, h = 0; an image: its own GCPs rescaled to the multilooked
// grid). Throws InputError naming the input and the missing channel ("quad
// needs four channels: ...") when a channel is missing, for looks larger
// than the image, or an unreadable input; ConfigError from Check() and for a
// job over the memory budget.
PolsarResult RunPolsar(const PolsarRequest& request, const std::string& command_line,
                       Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
