// The field tables of `sequence` and `ortho` (request_fields.h): the
// terrain, geometry and sensor rows they share with simulate are
// simulate's rows (simulate_fields.cc) reading and writing the request's
// `base`; their own rows follow. `gissar sequence` and `gissar ortho` read
// them for their flags.
#pragma once

#include "gissar/pipeline/request_fields.h"
#include "gissar/pipeline/views.h"

namespace gissar::pipeline {

const FieldTable<SequenceRequest>& SequenceFields();
const FieldTable<OrthoRequest>& OrthoFields();

}  // namespace gissar::pipeline
