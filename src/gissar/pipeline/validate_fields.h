// The field table of a `validate` request (request_fields.h): the fields a
// user gives, each once, with its key, one-line help and flag. The rows it
// shares with simulate (terrain, product selection, rays) are simulate's
// rows (simulate_fields.cc) reading and writing ValidateRequest::simulate;
// its own rows are the comparison's (radiometry, noise removal, looks, the
// peer's geolocation). `gissar validate`'s flags read it.
#pragma once

#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/request_fields.h"

namespace gissar::pipeline {

const FieldTable<ValidateRequest>& ValidateFields();

}  // namespace gissar::pipeline
