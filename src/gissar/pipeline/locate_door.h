// The door of `gissar locate` and `gissar evaluate`: the one place where a
// request's source picks its path. A request with a product or a track
// (--product: a NISAR RSLC or a Sentinel-1 SAFE; or --orbit with
// --radar-grid) goes to the product path (product_locate.h); a scene or DEM
// terrain (--scene/--dem, an --image with a --prior, simulated trials) goes
// to the terrain path (locate.h). The CLI, the Python module and the tests
// call these functions; neither path calls the other, and each path states
// its own promises, units and failures, which these functions keep.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/pipeline/locate.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

// Any locate request: RunProductLocate when it uses a track
// (LocateRequest::UsesTrack), RunTerrainLocate otherwise. Each path
// Check()s the request first. Returns the fix JSON (written to options.out;
// with a product and an empty `out`, nothing is written).
nlohmann::json RunLocate(const LocateRequest& options, const std::string& command_line,
                         Reporter& reporter = NullReporter());

// Any evaluate request, whole: RunProductEvaluate with a product,
// RunTerrainEvaluate otherwise (each Check()s the request first). Returns the
// summary JSON (also written to PREFIX.json; with a product and no
// out_prefix, nothing is written).
nlohmann::json RunEvaluate(const EvaluateRequest& options, const std::string& command_line,
                           Reporter& reporter = NullReporter());

// Check(), then the per-trial records of trials trial_first .. (see
// EvaluateRequest), nothing written: ProductEvaluateTrials with a product,
// TerrainEvaluateTrials otherwise. Trial k's randomness depends only on
// (seed, k): any split of the trials over processes gives the records of the
// serial run.
std::vector<nlohmann::json> EvaluateTrials(const EvaluateRequest& options, Reporter& reporter = NullReporter());

// The summary statistics of a set of trial records (any order; a repeated
// trial is a ConfigError), identical to the serial run's for the same
// records: ProductSummariseTrials with a product, TerrainSummariseTrials
// otherwise.
nlohmann::json SummariseTrials(const EvaluateRequest& options, const std::vector<nlohmann::json>& records);

// Check(), then writes PREFIX.json, PREFIX_trials.csv (and, on a terrain,
// PREFIX_hist.png) from records, atomically; returns the summary:
// WriteProductEvaluation with a product (`vertical_datum` unused),
// WriteTerrainEvaluation otherwise (`vertical_datum`: the record of the DEM's
// datum; null: the option as given).
nlohmann::json WriteEvaluation(const EvaluateRequest& options, const std::vector<nlohmann::json>& records,
                               const std::string& command_line, double seconds,
                               const nlohmann::json& vertical_datum = nullptr);

}  // namespace gissar::pipeline
