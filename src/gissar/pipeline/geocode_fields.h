// The field table of a `geocode` request (request_fields.h): every
// GeocodeRequest field a door offers, once, with its JSON key (the sidecar's
// and options files' key, the keyword of gissar.geocode), its one-line help
// and its flag. `gissar geocode`'s flags and GeocodeRequest::ToJson/ApplyJson
// read it. max_memory_bytes is not a row: `--max-memory SIZE` is its own
// door and the sidecar does not record it.
#pragma once

#include "gissar/pipeline/geocode.h"
#include "gissar/pipeline/request_fields.h"

namespace gissar::pipeline {

const FieldTable<GeocodeRequest>& GeocodeFields();

}  // namespace gissar::pipeline
