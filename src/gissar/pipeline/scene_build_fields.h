// The field table of a `scene build` request (request_fields.h): every
// SceneBuildRequest field once, with its JSON key (the sidecar's and options
// files' key, the keyword of gissar.Scene.build), its one-line help and its
// flag. `gissar scene build`'s flags and SceneBuildRequest::ToJson/ApplyJson
// read it; fill_nodata and vertical_datum take simulate's help.
// max_memory_bytes has no help (no flag from the table: --max-memory SIZE is
// its own door) but is a key of the sidecar.
#pragma once

#include "gissar/pipeline/request_fields.h"
#include "gissar/pipeline/scene_build.h"

namespace gissar::pipeline {

const FieldTable<SceneBuildRequest>& SceneBuildFields();

}  // namespace gissar::pipeline
