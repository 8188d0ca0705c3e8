// The field tables of the affine-camera commands (request_fields.h):
// `fmatrix`, `resect`, `register`, `epipolar` and `composite`. Each
// request's fields once, with the key its JSON output records, its one-line
// help and its flag; the commands' flags and the requests' ToJson read them.
#pragma once

#include "gissar/pipeline/mvg_commands.h"
#include "gissar/pipeline/request_fields.h"

namespace gissar::pipeline {

const FieldTable<FmatrixRequest>& FmatrixFields();
const FieldTable<ResectRequest>& ResectFields();
const FieldTable<RegisterRequest>& RegisterFields();
const FieldTable<EpipolarRequest>& EpipolarFields();
const FieldTable<CompositeRequest>& CompositeFields();

}  // namespace gissar::pipeline
