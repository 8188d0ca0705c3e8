// The side a side-looking radar looks to, relative to its flight direction,
// with its one table of names ("right", "left"): products and orbit files
// (this layer) read and write it; sensor::LookSide is this type.
#pragma once

#include "gissar/util/enum_table.h"

namespace gissar::geo {

enum class LookSide { kRight, kLeft };
inline constexpr auto kLookSides =
    util::MakeEnumTable<LookSide>("look side", {{LookSide::kRight, "right"}, {LookSide::kLeft, "left"}});

// A product's look_left flag as a LookSide.
constexpr LookSide LookSideOf(bool look_left) { return look_left ? LookSide::kLeft : LookSide::kRight; }

}  // namespace gissar::geo
