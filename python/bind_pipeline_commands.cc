// Binds the pipeline's commands that take a request as a dict of its fields: geocode, locate_product,
// evaluate_trials, summarise_trials, write_evaluation (the pieces of evaluate that distributed_evaluate.py
// spreads over Dask), pta and polsar.
#include "bindings.h"

#include "gissar/pipeline/geocode.h"
#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/locate_door.h"
#include "gissar/pipeline/polsar.h"
#include "gissar/pipeline/pta.h"

namespace gissar::python {

namespace {

// An EvaluateRequest from a dict of its fields (EvaluateRequest::ToJson keys).
pipeline::EvaluateRequest EvaluateOptionsFrom(const py::dict& values, const std::string& where) {
  pipeline::EvaluateRequest o;
  o.ApplyJson(JsonOfFields(values), where);
  if (o.out_prefix.empty() && o.product.empty()) o.out_prefix = "(python)";
  return o;
}

// Trial records from Python (dicts, as evaluate_trials returns them).
std::vector<nlohmann::json> RecordsFrom(const py::iterable& records) {
  std::vector<nlohmann::json> out;
  const py::object dumps = py::module_::import("json").attr("dumps");
  for (const py::handle r : records) out.push_back(nlohmann::json::parse(dumps(r).cast<std::string>()));
  return out;
}

}  // namespace

void BindPipelineCommands(py::module_& m) {
  m.def("geocode", [](const py::dict& options) {
        pipeline::GeocodeRequest o;
        o.ApplyJson(JsonOfFields(options), "gissar.geocode keyword");
        pipeline::GeocodeResult r;
        PyReporter reporter{py::none()};
        {
          py::gil_scoped_release release;
          o.Check();
          r = pipeline::RunGeocode(o, "python: gissar.geocode", reporter);
        }
        std::vector<std::string> paths;
        for (const auto& p : r.outputs) paths.push_back(p.string());
        return py::dict(py::arg("outputs") = paths, py::arg("width") = r.width, py::arg("height") = r.height,
                        py::arg("geotransform") = r.geotransform, py::arg("crs") = r.crs,
                        py::arg("valid_pixels") = r.valid_pixels);
      }, py::arg("options"),
      "`gissar geocode` (docs/georeferencing.md): a simulation's PREFIX.tif (with its sidecar and mask beside "
      "it) to map geometry: out_prefix.tif (the image's bands, local_incidence, layover_shadow), .json, "
      "_stac.json. options: the geocode request's fields as a dict (image, out_prefix, dem, vertical_datum, crs, "
      "pixel_size_m, resampling; pipeline/geocode_fields.cc; None keeps a default). Returns {'outputs', 'width', "
      "'height', 'geotransform', 'crs', 'valid_pixels'}.");
  m.def("evaluate_trials", [](const py::dict& options) {
          const pipeline::EvaluateRequest o = EvaluateOptionsFrom(options, "gissar.evaluate_trials");
          std::vector<nlohmann::json> records;
          {
            py::gil_scoped_release release;
            records = pipeline::EvaluateTrials(o);
          }
          py::list out;
          for (const nlohmann::json& r : records) out.append(JsonToPython(r));
          return out;
        }, py::arg("options"),
        "Run trials trial_first .. trial_first + trial_count - 1 (trial_count -1: the rest) of an evaluate request "
        "(a dict of its fields) and return their records (list of dicts); trial k depends only on (seed, k).");
  m.def("locate_product", [](const py::dict& options) {
          pipeline::LocateRequest o;
          o.ApplyJson(JsonOfFields(options), "gissar.locate_product keyword");
          if (!o.UsesTrack()) throw ConfigError("give product, or orbit with radar_grid and image", "gissar.locate_product");
          nlohmann::json report;
          {
            py::gil_scoped_release release;
            report = pipeline::RunLocate(o, "gissar.locate_product (python)");
          }
          return JsonToPython(report);
        }, py::arg("options"),
        "Pose fix of a real product (or an orbit, radar grid and image) from a displaced prior: the locate "
        "request's fields as a dict (docs/navigation.md, 'Real images'). Returns the fix dict; no fix is "
        "converged=False with a reason.");
  m.def("pta", [](const py::dict& options) {
          pipeline::PtaRequest o;
          o.ApplyJson(JsonOfFields(options), "gissar.pta keyword");
          pipeline::PtaResult result;
          {
            py::gil_scoped_release release;
            o.Check();
            result = pipeline::RunPta(o, "gissar.pta (python)");
          }
          nlohmann::json out = result.report;
          out["outputs"] = nlohmann::json::array();
          for (const auto& p : result.outputs) out["outputs"].push_back(p.string());
          return JsonToPython(out);
        }, py::arg("options"),
        "`gissar pta` (docs/radiometry.md, point targets): the pta request's fields as a dict (product or image, "
        "reflectors, out_prefix, ...). Writes PREFIX.json and PREFIX_irf.png and returns PREFIX.json's dict "
        "(plus 'outputs'); no reflector found is converged=False with a reason.");
  m.def("polsar", [](const py::dict& options) {
          pipeline::PolsarRequest o;
          o.ApplyJson(JsonOfFields(options), "gissar.polsar keyword");
          pipeline::PolsarResult result;
          {
            py::gil_scoped_release release;
            o.Check();
            result = pipeline::RunPolsar(o, "gissar.polsar (python)");
          }
          nlohmann::json out = result.report;
          out["outputs"] = nlohmann::json::array();
          for (const auto& p : result.outputs) out["outputs"].push_back(p.string());
          return JsonToPython(out);
        }, py::arg("options"),
        "`gissar polsar` (docs/radiometry.md, polarimetric decomposition): the polsar request's fields as a dict "
        "(image or product, looks, matrix, out_prefix). Writes the C3/T3 and H/A/alpha rasters and the Pauli "
        "quicklook and returns PREFIX.json's dict (plus 'outputs').");
  m.def("summarise_trials", [](const py::dict& options, const py::iterable& records) {
          const pipeline::EvaluateRequest o = EvaluateOptionsFrom(options, "gissar.summarise_trials");
          return JsonToPython(pipeline::SummariseTrials(o, RecordsFrom(records)));
        }, py::arg("options"), py::arg("records"),
        "Summary statistics (success_rate, position_error_m median/p95, ...) of trial records in any order: "
        "the serial evaluate's table.");
  m.def("write_evaluation", [](const py::dict& options, const py::iterable& records, double seconds) {
          const pipeline::EvaluateRequest o = EvaluateOptionsFrom(options, "gissar.write_evaluation");
          return JsonToPython(pipeline::WriteEvaluation(o, RecordsFrom(records), "gissar (python)", seconds));
        }, py::arg("options"), py::arg("records"), py::arg("seconds") = 0.0,
        "Write PREFIX.json, PREFIX_trials.csv and PREFIX_hist.png of trial records (options['out_prefix']).");
}

}  // namespace gissar::python
