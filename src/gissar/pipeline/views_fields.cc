#include "gissar/pipeline/views_fields.h"

#include "gissar/pipeline/simulate_fields.h"

namespace gissar::pipeline {
namespace {

// Simulate's rows `names`, each reading and writing R::base.
template <class R>
std::vector<RequestField<R>> SimulateRows(std::initializer_list<const char*> names) {
  std::vector<RequestField<R>> rows;
  for (const char* name : names) rows.push_back(Fields<R>::Of(&R::base, SimulateFields().at(name)));
  return rows;
}

// The rows both commands share, before and after the heading.
template <class R>
std::vector<RequestField<R>> TerrainRows() {
  return SimulateRows<R>({"dem", "scene", "fill_nodata", "vertical_datum"});
}
template <class R>
std::vector<RequestField<R>> GeometryAndSensorRows() {
  return SimulateRows<R>({"depression_deg", "look_side", "center_lonlat", "slant_range_m", "range_spacing_m",
                          "azimuth_spacing_m", "rays_per_cell", "range_resolution_m", "azimuth_resolution_m",
                          "psf_window", "speckle_looks", "seed"});
}

template <class R>
void Append(std::vector<RequestField<R>>& rows, std::vector<RequestField<R>> more) {
  for (RequestField<R>& row : more) rows.push_back(std::move(row));
}

}  // namespace

// In the order of `gissar sequence --help`.
const FieldTable<SequenceRequest>& SequenceFields() {
  using R = SequenceRequest;
  using F = Fields<R>;
  static const FieldTable<SequenceRequest> kTable([] {
    std::vector<RequestField<R>> rows = TerrainRows<R>();
    Append(rows, GeometryAndSensorRows<R>());
    Append(rows, SimulateRows<R>({"mode"}));
    rows.push_back(F::Plain("heading_from_deg", F::At(&R::heading_from_deg), "First heading, degrees"));
    rows.push_back(F::Plain("heading_to_deg", F::At(&R::heading_to_deg), "Last heading, degrees"));
    rows.push_back(F::Plain("frames", F::At(&R::frames), "Number of frames (>= 2)"));
    rows.push_back(
        F::Plain("frame_delay_cs", F::At(&R::frame_delay_cs), "GIF frame time, 1/100 s").WithFlag("--frame-delay"));
    rows.push_back(F::Of(&R::base, SimulateFields().at("out_prefix"))
                       .WithHelp("Output prefix: PREFIX_fNN.tif/.png, PREFIX_contact.png, PREFIX.gif, PREFIX.json"));
    return rows;
  }());
  return kTable;
}

// In the order of `gissar ortho --help`.
const FieldTable<OrthoRequest>& OrthoFields() {
  using R = OrthoRequest;
  using F = Fields<R>;
  static const FieldTable<OrthoRequest> kTable([] {
    std::vector<RequestField<R>> rows = TerrainRows<R>();
    Append(rows, SimulateRows<R>({"heading_deg"}));
    Append(rows, GeometryAndSensorRows<R>());
    rows.push_back(
        F::Plain("orthophoto", F::At(&R::orthophoto), "RGB raster draped instead of class colours", false));
    rows.push_back(F::Of(&R::base, SimulateFields().at("out_prefix"))
                       .WithHelp("Output prefix: PREFIX_los.png, PREFIX_sar.png, PREFIX_gperp.png, "
                                 "PREFIX_trio.png, PREFIX.json"));
    return rows;
  }());
  return kTable;
}

}  // namespace gissar::pipeline
