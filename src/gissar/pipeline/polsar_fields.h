// The field table of a `polsar` request (request_fields.h): every
// PolsarRequest field once, with its JSON key (the keyword of gissar.polsar,
// the options-file key), its one-line help and its flag. `gissar polsar`'s
// flags and PolsarRequest::ToJson/ApplyJson read it.
#pragma once

#include "gissar/pipeline/polsar.h"
#include "gissar/pipeline/request_fields.h"

namespace gissar::pipeline {

const FieldTable<PolsarRequest>& PolsarFields();

}  // namespace gissar::pipeline
