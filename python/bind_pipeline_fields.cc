// Binds the pipeline's request field tables and defaults: simulate_request_defaults/_help/_fields,
// request_fields (docs/options.md is made from them), flag_of_field, unknown_key_message, and the
// defaults of the locate, evaluate, pta and polsar requests.
#include "bindings.h"

#include "gissar/pipeline/evaluate_fields.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/pipeline/geocode_fields.h"
#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/locate_fields.h"
#include "gissar/pipeline/mvg_fields.h"
#include "gissar/pipeline/polsar.h"
#include "gissar/pipeline/polsar_fields.h"
#include "gissar/pipeline/pta.h"
#include "gissar/pipeline/pta_fields.h"
#include "gissar/pipeline/scene_build_fields.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/simulate_fields.h"
#include "gissar/pipeline/validate_fields.h"
#include "gissar/pipeline/views_fields.h"

namespace gissar::python {

namespace {

// The rows of a request's field table (pipeline/request_fields.h), in its
// order: {name, flag, aliases, help, default, show_default} per field, the default
// that of a request R().
template <class R>
py::list FieldRows(const pipeline::FieldTable<R>& table) {
  py::list fields;
  const R defaults;
  for (const auto& field : table.fields()) {
    py::dict d;
    d["name"] = field.name;
    d["flag"] = field.Flag();
    d["aliases"] = field.aliases;
    d["help"] = field.help;
    d["default"] = JsonToPython(field.get(defaults));
    d["show_default"] = field.show_default;
    fields.append(d);
  }
  return fields;
}

// The request tables by command name, in docs/options.md's order.
const char* const kTableCommands =
    "simulate, evaluate, locate, geocode, scene_build, sequence, ortho, matchpair, pta, polsar, validate, fmatrix, "
    "resect, register, epipolar or composite";

// The field table of `command` as FieldRows (one of kTableCommands);
// ConfigError naming the argument for another name.
py::list RequestFieldRows(const std::string& command) {
  if (command == "simulate") return FieldRows(pipeline::SimulateFields());
  if (command == "evaluate") return FieldRows(pipeline::EvaluateFields());
  if (command == "locate") return FieldRows(pipeline::LocateFields());
  if (command == "geocode") return FieldRows(pipeline::GeocodeFields());
  if (command == "scene_build") return FieldRows(pipeline::SceneBuildFields());
  if (command == "pta") return FieldRows(pipeline::PtaFields());
  if (command == "sequence") return FieldRows(pipeline::SequenceFields());
  if (command == "ortho") return FieldRows(pipeline::OrthoFields());
  if (command == "matchpair") return FieldRows(pipeline::MatchPairFields());
  if (command == "polsar") return FieldRows(pipeline::PolsarFields());
  if (command == "validate") return FieldRows(pipeline::ValidateFields());
  if (command == "fmatrix") return FieldRows(pipeline::FmatrixFields());
  if (command == "resect") return FieldRows(pipeline::ResectFields());
  if (command == "register") return FieldRows(pipeline::RegisterFields());
  if (command == "epipolar") return FieldRows(pipeline::EpipolarFields());
  if (command == "composite") return FieldRows(pipeline::CompositeFields());
  throw ConfigError("unknown request '" + command + "': must be " + kTableCommands, "gissar.request_fields: command");
}

}  // namespace

void BindPipelineFields(py::module_& m) {
  m.def("simulate_request_defaults", [] { return JsonToPython(pipeline::SimulateRequest().ToJson()); },
        "The keywords of simulate with their defaults (the request fields, docs/conventions.md).");
  m.def("simulate_request_help", [] { return pipeline::SimulateFieldHelp(); },
        "{field: one-line help} of the simulate request fields the doors offer as flags or keywords (the text "
        "of `gissar simulate --help`, without defaults; simulate_request_defaults() gives those).");
  m.def("simulate_request_fields", [] { return RequestFieldRows("simulate"); },
        "The simulate request's field table (pipeline/simulate_fields.cc), in its order: one dict per field with "
        "name (the keyword and options-file key), flag (the CLI's), help (one line; empty: no flag), default and "
        "show_default. The corridor's flags and docs/options.md are made from it. Same as "
        "request_fields('simulate').");
  m.def("request_fields", &RequestFieldRows, py::arg("command"),
        "The field table of a command's request, in its order, as simulate_request_fields() gives simulate's: "
        "command 'simulate', 'evaluate', 'locate', 'geocode', 'scene_build', 'sequence', 'ortho', 'matchpair', 'pta', "
        "'polsar', 'validate', 'fmatrix', 'resect', 'register', 'epipolar' or 'composite' "
        "(pipeline/<command>_fields.cc; sequence and ortho: views_fields.cc, matchpair: locate_fields.cc, the "
        "affine-camera commands: mvg_fields.cc). docs/options.md is made from them.");
  m.def("flag_of_field", &pipeline::FlagOfField, py::arg("field"),
        "The CLI flag of a request field: kebab case without the unit suffix (heading_deg -> --heading; "
        "out_prefix -> --out, center_lonlat -> --center, look_side -> --look).");
  m.def("unknown_key_message", &pipeline::UnknownKeyMessage, py::arg("key"), py::arg("known"),
        "\"unknown key 'KEY'\" with \"; did you mean K?\" when a key of `known` is close (the same case, '-' for "
        "'_', the flag name without its unit suffix, or at most 2 edits): the message of every request's "
        "unknown keyword.");
  m.def("locate_request_defaults", [] { return JsonToPython(pipeline::LocateRequest().ToJson()); },
        "The locate request's fields and their defaults (the keywords of gissar.locate_product; "
        "pipeline/locate_fields.cc).");
  m.def("evaluate_request_defaults", [] { return JsonToPython(pipeline::EvaluateRequest().ToJson()); },
        "The evaluate request's fields and their defaults (the keywords of gissar.evaluate).");
  m.def("pta_request_defaults", [] { return JsonToPython(pipeline::PtaRequest().ToJson()); },
        "The pta request's fields and their defaults (the keywords of gissar.pta).");
  m.def("polsar_request_defaults", [] { return JsonToPython(pipeline::PolsarRequest().ToJson()); },
        "The polsar request's fields and their defaults (the keywords of gissar.polsar).");
}

}  // namespace gissar::python
