// `gissar pta` and `gissar polsar` flags (pipeline/pta.h and
// pipeline/polsar.h hold the requests and the work).
#include <cstdio>
#include <memory>
#include <sstream>

#include "gissar/cli/command.h"
#include "gissar/pipeline/polsar.h"
#include "gissar/pipeline/polsar_fields.h"
#include "gissar/pipeline/pta.h"
#include "gissar/pipeline/pta_fields.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions these commands bind

namespace {

// "pta: 1 of 1 reflectors measured; row 1: location error 0.00 / 0.25 px
// (range / azimuth), RCS 104.63 dBsm, expected 25.45 dBsm (offset +79.18 dB)".
std::string PtaHeadline(const nlohmann::json& report) {
  std::ostringstream out;
  out << "pta: " << report.value("measured", 0) << " of " << report.value("total", 0) << " reflectors measured";
  for (const nlohmann::json& r : report.at("reflectors")) {
    if (!r.value("found", false)) continue;
    char text[320];
    std::snprintf(text, sizeof text, "; row %d: location error %.2f / %.2f px (range / azimuth), RCS %.2f dBsm",
                  r.value("id", 0), r["location_error_px"].value("range", 0.0),
                  r["location_error_px"].value("azimuth", 0.0), r.value("rcs_dbsm", 0.0));
    out << text;
    if (r.contains("rcs_expected_dbsm") && r["rcs_expected_dbsm"].is_number()) {
      std::snprintf(text, sizeof text, ", expected %.2f dBsm (offset %+.2f dB)", r["rcs_expected_dbsm"].get<double>(),
                    r["calibration_offset_db"].get<double>());
      out << text;
    }
    if (r.contains("hh_vv_ratio_db") && r["hh_vv_ratio_db"].is_number()) {
      std::snprintf(text, sizeof text, ", HH/VV %.2f dB %.1f deg, isolation %.1f dB", r["hh_vv_ratio_db"].get<double>(),
                    r["hh_vv_phase_deg"].get<double>(), r["cross_pol_isolation_db"].get<double>());
      out << text;
    }
    if (!report.at("calibration").value("calibrated", false)) out << " (uncalibrated)";
  }
  return out.str();
}

// "polsar: 16 x 33 px of 3 x 3 looks (C3); mean entropy 0.665, anisotropy
// 0.609, alpha 52.2 deg".
std::string PolsarHeadline(const PolsarResult& result, int looks_range, int looks_azimuth, const std::string& matrix) {
  char text[256];
  std::snprintf(text, sizeof text,
                "polsar: %d x %d px of %d x %d looks (%s); mean entropy %.3f, anisotropy %.3f, alpha %.1f deg",
                result.width, result.height, looks_range, looks_azimuth, matrix.c_str(), result.mean_entropy,
                result.mean_anisotropy, result.mean_alpha_deg);
  return text;
}


}  // namespace

void AddPolarimetryCommands(CLI::App& root, CommandRegistry& registry) {
  {
    auto o = std::make_shared<PtaRequest>();
    auto max_memory = std::make_shared<std::string>();
    CLI::App* cmd = root.add_subcommand(
        "pta", "Point-target analysis of surveyed reflectors in a complex image: location, resolution, PSLR/ISLR, RCS.");
    // Every field of the request's table that has a help text is a flag
    // (pipeline/pta_fields.cc), in the table's order.
    auto flags = std::make_shared<RequestFlags<PtaRequest>>(cmd, PtaFields(), o.get());
    flags->AddAll({"reflectors", "out_prefix"});
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
    registry.Add(cmd, [=](const CommandContext& context) {
      PtaRequest resolved = *o;
      flags->Apply(resolved);
      resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
      const PtaResult result = RunPta(resolved, context.command_line, context.reporter);
      for (const auto& path : result.outputs) context.out << path.string() << "\n";
      context.out << PtaHeadline(result.report) << "\n";
      if (result.measured == 0) context.no_result = result.report.value("reason", std::string("no reflector found"));
    });
  }
  {
    auto o = std::make_shared<PolsarRequest>();
    auto max_memory = std::make_shared<std::string>();
    CLI::App* cmd = root.add_subcommand(
        "polsar", "Polarimetric decomposition of a quad-pol SLC: C3 or T3, entropy/anisotropy/alpha, Pauli RGB.");
    // Every field of the request's table that has a help text is a flag
    // (pipeline/polsar_fields.cc), in the table's order.
    auto flags = std::make_shared<RequestFlags<PolsarRequest>>(cmd, PolsarFields(), o.get());
    flags->AddAll({"multilook", "out_prefix"});
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
    registry.Add(cmd, [=](const CommandContext& context) {
      PolsarRequest resolved = *o;
      flags->Apply(resolved);
      resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
      const PolsarResult result = RunPolsar(resolved, context.command_line, context.reporter);
      for (const auto& path : result.outputs) context.out << path.string() << "\n";
      context.out << PolsarHeadline(result, resolved.multilook[0], resolved.multilook[1],
                                    resolved.matrix == image::PolarimetricMatrix::kCovariance ? "C3" : "T3")
                  << "\n";
    });
  }
}

}  // namespace gissar::cli
