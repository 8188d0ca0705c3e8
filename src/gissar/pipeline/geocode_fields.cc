#include "gissar/pipeline/geocode_fields.h"

#include "gissar/pipeline/simulate_fields.h"

namespace gissar::pipeline {

// Fields in the order of `gissar geocode --help` (geocode.h states what each means).
const FieldTable<GeocodeRequest>& GeocodeFields() {
  using F = Fields<GeocodeRequest>;
  using R = GeocodeRequest;
  static const FieldTable<GeocodeRequest> kTable(
      {
          F::Plain("image", F::At(&R::image),
                   "PREFIX.tif of `gissar simulate` (PREFIX.json, PREFIX_mask.tif beside it)", false),
          F::Plain("dem", F::At(&R::dem), "DEM whose heights replace the simulation's terrain (default: the sidecar's)",
                   false),
          F::Plain("vertical_datum", F::At(&R::vertical_datum), SimulateHelp("vertical_datum"), false),
          F::Plain("crs", F::At(&R::crs),
                   "Output CRS, e.g. EPSG:32631 (projected; default: UTM zone of the scene centre)", false),
          F::Plain("pixel_size_m", F::At(&R::pixel_size_m),
                   "Output pixel size, m (default: the image's larger spacing)", false),
          F::Enum("resampling", F::At(&R::resampling), kGeocodeResamplings, kGeocodeResamplings.Alternatives()),
          F::Plain("out_prefix", F::At(&R::out_prefix),
                   "Output prefix: PREFIX.tif (map geometry), PREFIX.json, PREFIX_stac.json", false),
      },
      /*null_keeps_default=*/true);
  return kTable;
}

// The requests' JSON forms are their tables' (the request headers state the promises).
nlohmann::json GeocodeRequest::ToJson() const { return GeocodeFields().ToJson(*this); }

void GeocodeRequest::ApplyJson(const nlohmann::json& values, const std::string& source) {
  GeocodeFields().ApplyJson(*this, values, source);
}

}  // namespace gissar::pipeline
