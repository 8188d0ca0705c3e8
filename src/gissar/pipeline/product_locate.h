// `gissar locate --product` and `gissar evaluate --product`: pose fixes of a
// real zero-Doppler product against references simulated in its own
// range-Doppler geometry (issue 23). The algorithm is nav::LocateProduct;
// these functions load the product and the terrain, build the prior from the
// product's annotated track (the truth) and write the results. Errors: the
// gissar::Error family; no fix is a result (converged false, a reason).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/pipeline/locate.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

// LocateRequest with `product` (or `orbit`) set (RunLocate, locate_door.h,
// sends it here): writes options.out (the fix JSON: fix, correction,
// covariance, error against the annotated track, matches, time) and the
// composite picture when asked; with an empty `out` (Python) nothing is
// written. Returns the JSON.
nlohmann::json RunProductLocate(const LocateRequest& options, const std::string& command_line,
                                Reporter& reporter = NullReporter());

// EvaluateRequest with `product` set: `trials` seeded prior offsets (uniform
// +- the prior errors; trial k depends only on (seed, k), so any split of the
// trials over processes gives the serial run's records), one fix each.
// RunProductEvaluate = ProductEvaluateTrials, then WriteProductEvaluation
// (PREFIX.json: success_rate, position_error_m, position_error_cells, ...,
// every record; PREFIX_trials.csv), or only ProductSummariseTrials without
// an out_prefix (Python). The door (locate_door.h: RunLocate, RunEvaluate,
// EvaluateTrials, SummariseTrials, WriteEvaluation) sends a product here.
std::vector<nlohmann::json> ProductEvaluateTrials(const EvaluateRequest& options, Reporter& reporter = NullReporter());
// The summary of records in any order (a repeated trial: ConfigError).
nlohmann::json ProductSummariseTrials(const EvaluateRequest& options, std::vector<nlohmann::json> records);
nlohmann::json WriteProductEvaluation(const EvaluateRequest& options, const std::vector<nlohmann::json>& records,
                                      const std::string& command_line, double seconds);
nlohmann::json RunProductEvaluate(const EvaluateRequest& options, const std::string& command_line,
                                  Reporter& reporter = NullReporter());

// Default prior errors of `evaluate --product` (uniform +- bounds) for a
// product whose multilooked footprint is along_m x range_m (metres on the
// ground along track, slant range): horizontal = min(along, range) / 8,
// vertical = horizontal / 8, heading = 0.05 deg.
struct PriorErrors {
  double horizontal_m, vertical_m, heading_deg;
};
PriorErrors FootprintPriorErrors(double along_m, double range_m);

}  // namespace gissar::pipeline
