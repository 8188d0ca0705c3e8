#include "gissar/pipeline/polsar_fields.h"

#include "gissar/material/material.h"

namespace gissar::pipeline {
namespace {

using F = Fields<PolsarRequest>;
using R = PolsarRequest;

}  // namespace

// Fields in the order of `gissar polsar --help` (polsar.h states what each
// means). A null value keeps the default (the Python door's None).
const FieldTable<PolsarRequest>& PolsarFields() {
  static const FieldTable<PolsarRequest> kTable(
      {
          F::Plain("image", F::At(&R::image),
                   "Complex GeoTIFF with bands named " + material::kPolarizations.List(), false),
          F::Plain("product", F::At(&R::product), "Or a NISAR RSLC product (HDF5) holding the four layers", false),
          F::Plain("frequency", F::At(&R::frequency), "Product band, A or B"),
          F::Integers("multilook", F::At(&R::multilook), 2, "R,A: range x azimuth looks averaged per output pixel",
                      "two integers R,A (range and azimuth looks)", /*show_default=*/false)
              .WithAliases("--looks"),
          F::Enum("matrix", F::At(&R::matrix), image::kPolarimetricMatrices,
                  std::string(image::kPolarimetricMatrices.Name(image::PolarimetricMatrix::kCovariance)) +
                      " (C3) or " +
                      std::string(image::kPolarimetricMatrices.Name(image::PolarimetricMatrix::kCoherency)) +
                      " (T3)"),
          F::Plain("out_prefix", F::At(&R::out_prefix),
                   "Output prefix: PREFIX_C3.tif (or _T3.tif), PREFIX_HAalpha.tif, PREFIX_pauli.png, PREFIX.json",
                   false),
          F::Plain("max_memory_bytes", F::At(&R::max_memory_bytes), ""),
      },
      /*null_keeps_default=*/true);
  return kTable;
}

// The requests' JSON forms are their tables' (the request headers state the promises).
nlohmann::json PolsarRequest::ToJson() const { return PolsarFields().ToJson(*this); }

void PolsarRequest::ApplyJson(const nlohmann::json& values, const std::string& source) {
  PolsarFields().ApplyJson(*this, values, source);
}

}  // namespace gissar::pipeline
