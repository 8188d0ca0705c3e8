// The one-line help of every `simulate` request field that a door offers as
// a flag or keyword: the CLI's `gissar simulate --help`, the corridor's
// `gissar corridor --help` (through the Python module) and the Python
// docstrings read the same text, so a flag reads alike in every command.
#pragma once

#include <map>
#include <string>

namespace gissar::pipeline {

// Field name (snake_case with unit suffix, docs/conventions.md) -> help
// text without a default (the doors append the default they show). Fields
// without an entry are not offered as flags (e.g. max_memory_bytes, which
// the doors spell as --max-memory SIZE).
const std::map<std::string, std::string>& SimulateFieldHelp();

// The help of `field`; throws std::out_of_range for a field without one
// (a programming error: every flag a door declares has its text here).
const std::string& SimulateHelp(const std::string& field);

}  // namespace gissar::pipeline
