// The field table of an `evaluate` request (request_fields.h): every
// EvaluateRequest field once, with its JSON key (the Python keyword of
// gissar.evaluate and distributed_evaluate, the options-file key, the
// sidecar key), its one-line help and its flag. `gissar evaluate`'s flags,
// EvaluateRequest::ToJson/ApplyJson and the Python keywords read it;
// `gissar locate` takes the help of the fields it shares (a product's
// terrain and multilook, the matcher, the database) from it.
#pragma once

#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/request_fields.h"

namespace gissar::pipeline {

const FieldTable<EvaluateRequest>& EvaluateFields();

}  // namespace gissar::pipeline
