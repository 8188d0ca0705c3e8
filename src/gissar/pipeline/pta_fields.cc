#include "gissar/pipeline/pta_fields.h"

namespace gissar::pipeline {
namespace {

using F = Fields<PtaRequest>;
using R = PtaRequest;

}  // namespace

// Fields in the order of `gissar pta --help` (pta.h states what each means).
// A null value keeps the default (the Python door's None).
const FieldTable<PtaRequest>& PtaFields() {
  static const FieldTable<PtaRequest> kTable(
      {
          F::Plain("product", F::At(&R::product),
                   "NISAR RSLC product (HDF5) or Sentinel-1 SLC (SAFE directory or .zip): prediction by geo2rdr on "
                   "its orbit",
                   false),
          F::Plain("image", F::At(&R::image),
                   "Or PREFIX_slc.tif of `gissar simulate --coherent` (PREFIX.json beside it): its own geometry",
                   false),
          F::Plain("reflectors", F::At(&R::reflectors),
                   "Reflectors CSV: type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg",
                   false),
          F::Plain("frequency", F::At(&R::frequency), "Product band, A or B (NISAR)"),
          F::Plain("polarization", F::At(&R::polarization),
                   "Channel measured, HH/HV/VH/VV (default: HH; a SAFE: its swath's first; --image: the "
                   "simulation's)",
                   false),
          F::Plain("swath", F::At(&R::swath), "Sentinel-1: swath, e.g. IW2 (default: the product's only one)", false),
          F::Plain("burst", F::At(&R::burst), "Sentinel-1 IW/EW SLC: burst, 1-based per swath (required there)",
                   false),
          F::Plain("orbit", F::At(&R::orbit),
                   "Sentinel-1: state vectors (ESA .EOF, CSV, JSON) replacing the annotation's", false),
          F::Plain("ground_height_m", F::At(&R::ground_height_m),
                   "With --product: ellipsoidal height of the ground under the reflectors, m")
              .WithFlag("--ground-height"),
          F::Plain("upsampling", F::At(&R::upsampling), "Upsampling factor per axis of the target chip"),
          F::Plain("search_px", F::At(&R::search_px), "Search radius around the predicted position, px"),
          F::Plain("chip_half_size_px", F::At(&R::chip_half_size_px),
                   "Half-size of the upsampled chip and of the energy box, px"),
          F::Plain("detection_threshold_db", F::At(&R::detection_threshold_db),
                   "Found: brightest sample at least this far above the background, dB"),
          F::Plain("out_prefix", F::At(&R::out_prefix),
                   "Output prefix: PREFIX.json (measurements), PREFIX_irf.png (cuts)", false),
          F::Plain("max_memory_bytes", F::At(&R::max_memory_bytes), ""),
      },
      /*null_keeps_default=*/true);
  return kTable;
}

// The requests' JSON forms are their tables' (the request headers state the promises).
nlohmann::json PtaRequest::ToJson() const { return PtaFields().ToJson(*this); }

void PtaRequest::ApplyJson(const nlohmann::json& values, const std::string& source) {
  PtaFields().ApplyJson(*this, values, source);
}

}  // namespace gissar::pipeline
