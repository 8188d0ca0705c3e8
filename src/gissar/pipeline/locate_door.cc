#include "gissar/pipeline/locate_door.h"

#include "gissar/pipeline/product_locate.h"

namespace gissar::pipeline {

nlohmann::json RunLocate(const LocateRequest& options, const std::string& command_line, Reporter& reporter) {
  // Each path Check()s the request first.
  if (options.UsesTrack()) return RunProductLocate(options, command_line, reporter);
  return RunTerrainLocate(options, command_line, reporter);
}

nlohmann::json RunEvaluate(const EvaluateRequest& options, const std::string& command_line, Reporter& reporter) {
  // Each path Check()s the request first.
  if (!options.product.empty()) return RunProductEvaluate(options, command_line, reporter);
  return RunTerrainEvaluate(options, command_line, reporter);
}

std::vector<nlohmann::json> EvaluateTrials(const EvaluateRequest& options, Reporter& reporter) {
  // Each path Check()s the request first.
  if (!options.product.empty()) return ProductEvaluateTrials(options, reporter);
  return TerrainEvaluateTrials(options, reporter);
}

nlohmann::json SummariseTrials(const EvaluateRequest& options, const std::vector<nlohmann::json>& records) {
  if (!options.product.empty()) return ProductSummariseTrials(options, records);
  return TerrainSummariseTrials(options, records);
}

nlohmann::json WriteEvaluation(const EvaluateRequest& options, const std::vector<nlohmann::json>& records,
                               const std::string& command_line, double seconds, const nlohmann::json& vertical_datum) {
  // Each path Check()s the request first.
  if (!options.product.empty()) return WriteProductEvaluation(options, records, command_line, seconds);
  return WriteTerrainEvaluation(options, records, command_line, seconds, vertical_datum);
}

}  // namespace gissar::pipeline
