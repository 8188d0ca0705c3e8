// The field table of a `locate` request (request_fields.h): every
// LocateRequest field once, with its JSON key (the Python keyword of
// gissar.locate_product, the options-file key), its one-line help and its
// flag. `gissar locate`'s flags and LocateRequest::ToJson/ApplyJson read it;
// the fields it shares with `evaluate` (a product's terrain and multilook,
// the matcher, the database) take their help from the evaluate table.
#pragma once

#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/request_fields.h"

namespace gissar::pipeline {

const FieldTable<LocateRequest>& LocateFields();

// `matchpair`'s table (the matchers' comparison on a real pair): its flags
// and the keys of its options file.
const FieldTable<MatchPairRequest>& MatchPairFields();

}  // namespace gissar::pipeline
