#include "gissar/pipeline/mvg_fields.h"

#include <optional>

#include "gissar/mvg/registration.h"

namespace gissar::pipeline {
namespace {

// Resect's scene centre, an Eigen::Vector3d: JSON [x, y, z]; CLI "X,Y,Z".
RequestField<ResectRequest> CenterRow(std::string help) {
  RequestField<ResectRequest> f;
  f.name = "center_enu_m";
  f.help = std::move(help);
  f.show_default = false;
  f.ref = [](ResectRequest&) { return FieldRef(); };
  f.from_text = Fields<ResectRequest>::NumbersText(3);
  f.get = [](const ResectRequest& r) {
    return nlohmann::json{r.center_enu_m.x(), r.center_enu_m.y(), r.center_enu_m.z()};
  };
  f.set = [](ResectRequest& r, const nlohmann::json& value, const std::string& key, const std::string& source) {
    std::vector<double> v;
    AssignField(v, value, key, source);
    if (v.size() != 3) throw ConfigError("key '" + key + "' needs 3 numbers", source);
    r.center_enu_m = Eigen::Vector3d(v[0], v[1], v[2]);
  };
  return f;
}

// Resect's measured range, a std::optional<double>: JSON number or null; CLI a number.
RequestField<ResectRequest> SlantRangeRow(std::string help) {
  RequestField<ResectRequest> f;
  f.name = "slant_range_m";
  f.help = std::move(help);
  f.show_default = false;
  f.accepts_null = true;
  f.get = [](const ResectRequest& r) { return r.slant_range_m ? nlohmann::json(*r.slant_range_m) : nlohmann::json(); };
  f.set = [](ResectRequest& r, const nlohmann::json& value, const std::string& key, const std::string& source) {
    if (value.is_null()) {
      r.slant_range_m.reset();
      return;
    }
    double v = 0;
    AssignField(v, value, key, source);
    r.slant_range_m = v;
  };
  f.ref = [](ResectRequest&) { return FieldRef(); };
  f.from_text = [](const std::string& text, const std::string& flag) {
    try {
      size_t used = 0;
      const double v = std::stod(text, &used);
      if (used == text.size()) return nlohmann::json(v);
    } catch (const std::exception&) {
    }
    throw ConfigError("needs a number, got '" + text + "'", flag);
  };
  return f;
}

}  // namespace

// Each table in the order of its command's --help (mvg_commands.h states
// what each field means). Keys are those the JSON outputs record ("out",
// "plot": fmatrix's and resect's outputs).
const FieldTable<FmatrixRequest>& FmatrixFields() {
  using F = Fields<FmatrixRequest>;
  using R = FmatrixRequest;
  static const FieldTable<FmatrixRequest> kTable({
      F::Plain("matches", F::At(&R::matches), "CSV with a header and columns x1,y1,x2,y2 (others ignored)", false),
      F::OptionalPair("range_spacing_m", F::At(&R::range_spacing_m),
                      "Slant-range pixel spacing R1,R2 of images 1 and 2, metres (calibrated F, with "
                      "--azimuth-spacing)",
                      NumberPairText),
      F::OptionalPair("azimuth_spacing_m", F::At(&R::azimuth_spacing_m),
                      "Along-track pixel spacing A1,A2 of images 1 and 2, metres", NumberPairText),
      F::OptionalPair("depressions", F::At(&R::depressions), "Depressions D1,D2 in degrees: gives the heading change",
                      NumberPairText),
      F::Plain("threshold_px", F::At(&R::threshold_px), "RANSAC inlier threshold, pixels"),
      F::Plain("robust", F::At(&R::robust),
               "RANSAC before the Gold Standard fit, or (--no-ransac) one fit to all matches")
          .WithFlag("--ransac"),
      F::Plain("seed", F::At(&R::seed), "RANSAC seed"),
      F::Plain("out", F::At(&R::json_out), "Output prefix: PREFIX.json (the fit)", false),
      F::Plain("plot", F::At(&R::plot_prefix),
               "Pictures: PREFIX_kvd.png (KvD diagram) and, with the images, PREFIX_epipolar.png (matches and "
               "epipolar lines)",
               false),
      F::Plain("image1", F::At(&R::image1), "Image 1 (any GDAL raster) for --plot", false),
      F::Plain("image2", F::At(&R::image2), "Image 2 for --plot", false),
  });
  return kTable;
}

const FieldTable<ResectRequest>& ResectFields() {
  using F = Fields<ResectRequest>;
  using R = ResectRequest;
  static const FieldTable<ResectRequest> kTable({
      F::Plain("points", F::At(&R::points), "CSV with a header and columns X,Y,Z,x,y (ENU m, pixels)", false),
      CenterRow("Scene centre Xc X,Y,Z (ENU m; default 0,0,0)"),
      SlantRangeRow("Measured slant range to Xc, metres: also gives the sensor position"),
      F::Plain("out", F::At(&R::json_out), "Output prefix: PREFIX.json (the camera)", false),
  });
  return kTable;
}

const FieldTable<RegisterRequest>& RegisterFields() {
  using F = Fields<RegisterRequest>;
  using R = RegisterRequest;
  static const FieldTable<RegisterRequest> kTable({
      F::Plain("fixed", F::At(&R::fixed), "Fixed image (any GDAL raster)", false),
      F::Plain("moving", F::At(&R::moving), "Moving image", false),
      F::Plain("points", F::At(&R::points), "CSV x1,y1 (fixed), x2,y2 (moving)", false),
      F::Plain("transform", F::At(&R::transform), mvg::kTransformTypes.Alternatives()),
      F::Plain("threshold_px", F::At(&R::threshold_px), "Robust fit inlier threshold, pixels"),
      F::Plain("robust", F::At(&R::robust), "Robust fit, or (--no-ransac) least squares on all pairs")
          .WithFlag("--ransac"),
      F::Plain("out_prefix", F::At(&R::out_prefix), "Output prefix: PREFIX.tif, PREFIX_composite.png, PREFIX.json",
               false),
  });
  return kTable;
}

const FieldTable<EpipolarRequest>& EpipolarFields() {
  using F = Fields<EpipolarRequest>;
  using R = EpipolarRequest;
  static const FieldTable<EpipolarRequest> kTable({
      F::Plain("matches", F::At(&R::matches), "CSV x1,y1,x2,y2", false),
      F::Plain("image1", F::At(&R::image1), "Image 1", false),
      F::Plain("image2", F::At(&R::image2), "Image 2", false),
      F::Plain("threshold_px", F::At(&R::threshold_px), "RANSAC threshold, pixels"),
      F::Plain("seed", F::At(&R::seed), ""),
      F::Plain("out", F::At(&R::out_png), "Output prefix: PREFIX.png", false),
  });
  return kTable;
}

const FieldTable<CompositeRequest>& CompositeFields() {
  using F = Fields<CompositeRequest>;
  using R = CompositeRequest;
  static const FieldTable<CompositeRequest> kTable({
      F::Plain("green", F::At(&R::green), "First image (e.g. the real one), band 1 linear intensity", false),
      F::Plain("magenta", F::At(&R::magenta), "Second image (e.g. the simulation), same size", false),
      F::Plain("out", F::At(&R::out_png), "Output prefix: PREFIX.png", false),
  });
  return kTable;
}

// The requests' JSON forms are their tables' (the request headers state the promises).
nlohmann::json FmatrixRequest::ToJson() const { return FmatrixFields().ToJson(*this); }

nlohmann::json ResectRequest::ToJson() const { return ResectFields().ToJson(*this); }

nlohmann::json RegisterRequest::ToJson() const { return RegisterFields().ToJson(*this); }

}  // namespace gissar::pipeline
