// The field table of a `pta` request (request_fields.h): every PtaRequest
// field once, with its JSON key (the Python keyword of gissar.pta, the
// options-file key), its one-line help and its flag. `gissar pta`'s flags and
// PtaRequest::ToJson/ApplyJson read it.
#pragma once

#include "gissar/pipeline/pta.h"
#include "gissar/pipeline/request_fields.h"

namespace gissar::pipeline {

const FieldTable<PtaRequest>& PtaFields();

}  // namespace gissar::pipeline
