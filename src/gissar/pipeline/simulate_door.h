// The door of `gissar simulate`: the one place where a request's source picks
// its path. A request on a product's radar grid (--product: a NISAR RSLC or a
// Sentinel-1 SAFE; or --orbit with --radar-grid) goes to RunProductSimulate
// (product_simulate.h); a DEM or GIS scene in an idealised geometry
// (--mode affine/exact) goes to RunTerrainSimulate. The CLI, the Python module
// and the tests call RunSimulate; neither path calls the other.
#pragma once

#include <string>

#include "gissar/pipeline/simulate.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

// A DEM or scene simulation, whole: ReserveSimulationOutputs, SimulateImage
// (simulate.h), WriteSimulation (simulation_output.h). Every output is
// written under a temporary name and renamed only when all of them
// succeeded. Throws the gissar::Error family (InputError, ConfigError,
// IoError) with context on failure, leaving no output behind; ConfigError for
// a request on a product's radar grid. `command_line` is recorded in the
// provenance JSON.
SimulateResult RunTerrainSimulate(const SimulateRequest& options, const std::string& command_line,
                                  Reporter& reporter = NullReporter());

// Any simulate request: RunProductSimulate when it
// renders on a product's radar grid (SimulateRequest::UsesProductGeometry),
// RunTerrainSimulate otherwise. Same promises and failures as those.
SimulateResult RunSimulate(const SimulateRequest& options, const std::string& command_line,
                           Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
