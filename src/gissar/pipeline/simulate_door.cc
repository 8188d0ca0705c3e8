#include "gissar/pipeline/simulate_door.h"

#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/simulation_output.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"

namespace gissar::pipeline {

SimulateResult RunTerrainSimulate(const SimulateRequest& options, const std::string& command_line,
                                  Reporter& reporter) {
  options.Check();
  if (options.UsesProductGeometry()) {
    throw ConfigError("a radar grid is rendered by RunProductSimulate (product_simulate.h)",
                      options.product.empty() ? "--orbit" : "--product");
  }
  Stopwatch total;
  // Reserve every output first: a missing or read-only directory fails now.
  SimulationOutputs outputs;
  ReserveSimulationOutputs(options, outputs);
  SimulatedImage simulated = SimulateImage(options, reporter);
  return WriteSimulation(options, simulated, command_line, outputs, total);
}

SimulateResult RunSimulate(const SimulateRequest& options, const std::string& command_line, Reporter& reporter) {
  // Each path Check()s the request first.
  if (options.UsesProductGeometry()) return RunProductSimulate(options, command_line, reporter);
  return RunTerrainSimulate(options, command_line, reporter);
}

}  // namespace gissar::pipeline
