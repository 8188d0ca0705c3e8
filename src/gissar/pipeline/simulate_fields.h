// The field table of a `simulate` request (request_fields.h): every
// SimulateRequest field once, with its JSON key (the Python keyword, the
// options-file key, the sidecar key), its one-line help and its flag. The
// CLI's simulate, sequence, ortho and validate flags, the corridor's
// simulate flags (through the Python module), the Python keywords and
// SimulateRequest::ToJson/ApplyJson all read it, so an option reads alike in
// every command and is added in one place.
#pragma once

#include <map>
#include <string>

#include "gissar/pipeline/request_fields.h"
#include "gissar/pipeline/simulate.h"

namespace gissar::pipeline {

const FieldTable<SimulateRequest>& SimulateFields();

// Field name -> help text (without a default; the doors append the default
// they show) of the fields a door offers as a flag or keyword: not
// max_memory_bytes, which the doors spell as --max-memory SIZE.
const std::map<std::string, std::string>& SimulateFieldHelp();

// The help of `field`; a field without help is a bug in the caller.
const std::string& SimulateHelp(const std::string& field);

}  // namespace gissar::pipeline
