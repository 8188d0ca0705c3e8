#include "gissar/pipeline/validate_fields.h"

#include "gissar/image/radiometry.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/simulate_fields.h"

namespace gissar::pipeline {
namespace {

using F = Fields<ValidateRequest>;
using R = ValidateRequest;

// Simulate's row `name`, reading and writing the request's simulate member.
RequestField<ValidateRequest> Simulate(const std::string& name) {
  return F::Of(&R::simulate, SimulateFields().at(name));
}

}  // namespace

// Fields in the order of `gissar validate --help` (product_simulate.h states
// what each means; the Sentinel-1 rows also serve the terrain-free check,
// validate_sentinel1.h).
const FieldTable<ValidateRequest>& ValidateFields() {
  static const FieldTable<ValidateRequest> kTable({
      Simulate("product").WithHelp(
          "NISAR-format RSLC product (HDF5) or Sentinel-1 SAFE (directory, manifest.safe or .zip)"),
      Simulate("orbit").WithHelp("Sentinel-1: state vectors (EOF, CSV or JSON) replacing the annotations' orbit"),
      Simulate("swath").WithHelp("Sentinel-1: swath to check (IW1, ..., S3; default: every swath present)"),
      F::Plain("polarization", F::At(&R::polarization),
               "Sentinel-1: polarisation to check (" + material::kPolarizations.List() +
                   "; default: every one present)",
               false),
      Simulate("dem"),
      Simulate("scene"),
      Simulate("fill_nodata"),
      Simulate("dem_oversample"),
      Simulate("vertical_units"),
      Simulate("vertical_datum"),
      F::Plain("reference_geolocation", F::At(&R::reference_geolocation),
               "Directory with a peer's per-pixel x.rdr, y.rdr, z.rdr (lon, lat, height; ISCE topo) and simamp.rdr",
               false),
      F::Integers("looks", F::At(&R::looks), 0, "Multilook sizes k of the k x k correlations, comma-separated",
                  "integer multilook sizes"),
      Simulate("rays_per_cell"),
      Simulate("bounces"),
      Simulate("burst"),
      Simulate("product_window_px"),
      F::Plain("radiometry", F::At(&R::radiometry),
               "Quantity compared: the real image calibrated with a Sentinel-1 product's sigmaNought, betaNought or "
               "gamma LUT, the simulation converted from beta0 with each pixel's ellipsoid incidence: " +
                   image::kRadiometries.Alternatives() + " (a NISAR product: beta0 only, its |s|^2)"),
      F::Plain("noise_removal", F::At(&R::noise_removal),
               "Sentinel-1: subtract the thermal noise power (noiseRangeLut, times noiseAzimuthLut where given) from "
               "the real image's |DN|^2 (negative: no-data)"),
      F::Plain("out_prefix", F::At(&R::out_prefix),
               "Output prefix: PREFIX.json, PREFIX.md, PREFIX_side_by_side.png, PREFIX_histogram.png (Sentinel-1: "
               "PREFIX.json)",
               false),
  });
  return kTable;
}

}  // namespace gissar::pipeline
