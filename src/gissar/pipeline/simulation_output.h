// The writing step of `gissar simulate`: the files a simulation writes
// (reserved before any work), the writers shared with a product simulation
// (complex bands, Pauli quicklook, mask categories and counts), and
// WriteSimulation / CommitSimulation, which write and commit them together.
// simulate.h includes this header; the request, the simulated image and the
// result are declared there.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/geo/raster_io.h"
#include "gissar/material/material.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {

struct SimulateRequest;
struct SimulatedImage;
struct SimulateResult;

// Band names of the bounce layers (render::SarImage::bounce_layers), the
// suffixes of a channel's bounce bands (HH_single, ...).
inline constexpr const char* kBounceLayerNames[render::kBounceLayers] = {"single", "double", "triple",
                                                                         "four_or_more"};

// How many bounce layers the outputs of `images` hold: bounce counts 1 up to
// the highest one the render filled in any of them (a plane of the image's
// pixels; of its complex parts when `complex`), at least 1. A run cannot
// return at counts above that (more bounces than traced, and no reflector of
// that order), so PREFIX.tif, PREFIX_slc.tif and Python's bands stop there; a
// count below it the render left empty is written as NoReturnPlane.
int HeldBounceLayers(std::span<const render::SarImage* const> images, bool complex = false);
// The same for a first channel's `image` and the `others`.
int HeldBounceLayers(const render::SarImage& image, const std::vector<render::SarImage>& others,
                     bool complex = false);

// The names of the image bands of PREFIX.tif and PREFIX_slc.tif (and
// Python's band_names) for `images` channels holding `held` bounce layers:
// one channel: "total", then kBounceLayerNames[0, held); several: each
// channel's name (`channels`, "VV" past its end), then each channel's
// "<channel>_<layer>" bounce bands.
std::vector<std::string> ImageBandNames(const std::vector<material::Polarization>& channels, size_t images,
                                        int held);

// "1 name, 2 name, ..." (GISSAR_BANDS).
std::string NumberedBands(const std::vector<std::string>& names);

// The pixels of a bounce layer the render left empty (no return of that
// order, render::SarImage::bounce_layers), as the writers and Python give
// it: 0 inside the footprint (NaN when `db`: the dB of no power, as
// image::ToDecibels writes it), NaN outside it (image.footprint; every pixel
// is inside when the footprint is empty). Also the real and the imaginary
// part of an empty complex layer (db false).
std::vector<float> NoReturnPlane(const render::SarImage& image, bool db);

// Whether the request's channels give a Pauli vector (HH, VV and HV or VH):
// a coherent run then writes PREFIX_pauli.png.
bool HasPauliChannels(const SimulateRequest& options);

// The complex bands of PREFIX_slc.tif (channels[k] is images[k]): one
// channel: the complex total, then one band per bounce count; several: each
// channel's complex total (named by its channel), then each channel's
// bounce bands (HH_single, ...). A layer the render left empty points to
// `no_return` (NoReturnPlane of images[0], filled here). Sets
// GISSAR_BANDS (and GISSAR_POLARIZATIONS for several) in `metadata`.
std::vector<geo::ComplexBand> SlcBands(const std::vector<render::SarImage*>& images,
                                       const std::vector<material::Polarization>& channels,
                                       std::vector<float>& no_return, geo::Metadata& metadata);

// Writes the Pauli RGB (image::PauliRgb: R = |HH - VV|, G = |HV + VH|, B =
// |HH + VV|, each / sqrt 2, one common dB stretch from the 2nd to the 98th
// percentile) of the multilooked coherency (at least 2 x 2 looks, more to
// keep the longer side <= kQuicklookMaxSidePx) of the complex channels
// `images` (channels[k] is images[k]; HH, VV and HV or VH among them), and
// records the looks and the stretch. A missing cross-polarised channel is
// taken from the other (reciprocity).
void WritePauliQuicklook(const std::filesystem::path& path, const std::vector<material::Polarization>& channels,
                         const std::vector<const render::SarImage*>& images, nlohmann::json* record);

// The files a simulation writes, reserved (AtomicOutputs::Add) before any
// work so that a missing or read-only directory fails first.
struct SimulationOutputs {
  AtomicOutputs files;
  std::filesystem::path tif, png, annotated_png, mask_tif, json, stac_json, contributions_csv, slc_tif, layers_tif,
      pauli_png;
  // The provenance's record of the terrain input (DEM or scene), its
  // checksum computed while the job runs.
  PendingInputRecord terrain_input;
};
// Reserves PREFIX.tif, .png, _quicklook.png, _mask.tif, .json, _stac.json (STAC Item, stac.h), _slc.tif in
// coherent mode (and _pauli.png for a coherent run with HH, VV and a cross-polarised channel), _layers.tif with `layers` and the contributions CSV when asked,
// and starts the terrain input's record. Throws IoError for a missing or read-only
// directory.
void ReserveSimulationOutputs(const SimulateRequest& options, SimulationOutputs& outputs);

// The writing step: the GeoTIFF (total + per-bounce bands, geometry
// metadata), quicklooks, mask, contributions and the provenance sidecar of
// `simulated`, committed together (nothing is left on failure). `total`
// started with the job (for the recorded timings).
SimulateResult WriteSimulation(const SimulateRequest& options, SimulatedImage& simulated,
                               const std::string& command_line, SimulationOutputs& reserved,
                               const Stopwatch& total);

// Pixel counts of a layover/shadow mask by code, for provenance:
// {"none", "layover", "shadow", "layover_and_shadow", "outside"} (outside:
// render::kMaskOutside, no-data).
nlohmann::json MaskPixelCounts(const std::vector<uint8_t>& mask);

// Text of the mask codes (GISSAR_MASK_CODES metadata) and the mask GeoTIFF's
// categories: names and colours of codes 0-3, no-data render::kMaskOutside.
inline constexpr const char* kMaskCodesText =
    "0 none, 1 layover, 2 shadow, 3 layover and shadow, 255 outside the imaged footprint (no-data)";
geo::ByteCategories MaskCategories();

// Finishes a simulation's outputs: records their absolute final paths in
// provenance["outputs"], writes `provenance` to `json` (one of the reserved
// outputs), commits them all (renames) and returns the result for `image`.
// Throws IoError when writing or renaming fails (nothing is left behind).
SimulateResult CommitSimulation(AtomicOutputs& outputs, nlohmann::json& provenance,
                                const std::filesystem::path& json, const render::SarImage& image,
                                double total_seconds);

}  // namespace gissar::pipeline
