// GDAL/OGR process set-up, owned by the geo module: the only module that
// includes GDAL headers.
#pragma once

#include <string>

namespace gissar::geo {

// Registers all GDAL drivers once, routes GDAL's own messages to a quiet
// handler (they are reported through exceptions instead) and disables .aux.xml
// side files. Thread-safe; cheap after the first call.
void EnsureGdal();

// The last message GDAL reported on this thread ("" when none).
std::string LastGdalMessage();

}  // namespace gissar::geo
