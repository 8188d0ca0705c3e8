// One string table per enum: the names an enum is read from and written as
// (options, options files, sidecars, CSV columns), declared once next to the
// enum, and everything that needs those names derived from it: parsing with
// one error format, printing, and the list of choices for help texts and
// messages.
//
//   enum class LookSide { kRight, kLeft };
//   inline constexpr auto kLookSides = util::MakeEnumTable<LookSide>(
//       "look side", {{LookSide::kRight, "right"}, {LookSide::kLeft, "left"}});
//
//   kLookSides.Parse("left", "--look")   -> LookSide::kLeft
//   kLookSides.Parse("up", "--look")     -> throws ConfigError
//       "unknown look side 'up': must be right or left (--look)"
//   kLookSides.Name(LookSide::kLeft)     -> "left"
//   kLookSides.List()                    -> "right, left"
//   kLookSides.Alternatives()            -> "right or left"
//
// Promises:
//  - The table is built at compile time (MakeEnumTable is consteval): an
//    empty name, or a name or alias given twice (compared as Parse compares
//    them), or a value named twice, does not compile.
//  - Name(v) is the one canonical name of v; Parse(Name(v)) == v for every
//    entry. Aliases are accepted by Parse and never printed or listed.
//  - Matching is exact, or ASCII case-insensitive for a table made with
//    EnumCase::kInsensitive (the canonical names are still printed as
//    written in the table).
//  - List() and Alternatives() give the canonical names in table order.
// Failures:
//  - Parse of any text that is neither a name nor an alias throws the
//    error type given (ConfigError unless stated; InputError where the text
//    comes from an input file) with what = UnknownMessage(text) and where =
//    the option, key or file row it came from.
//  - Name of a value the table lacks is a bug in gissar: GISSAR_CHECK aborts.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::util {

template <class E>
struct EnumName {
  E value{};
  std::string_view name;
};

enum class EnumCase { kExact, kInsensitive };

template <class E, size_t N, size_t A>
class EnumTable {
 public:
  using Entry = EnumName<E>;

  constexpr EnumTable(std::string_view noun, const std::array<Entry, N>& names, const std::array<Entry, A>& aliases,
                      EnumCase match)
      : noun_(noun), names_(names), aliases_(aliases), match_(match) {}

  // What the values are, in words ("look side"): the start of messages.
  constexpr std::string_view Noun() const { return noun_; }
  // The canonical entries (value, name) in table order.
  constexpr const std::array<Entry, N>& Entries() const { return names_; }
  constexpr const std::array<Entry, A>& Aliases() const { return aliases_; }

  // The canonical name of `value` (aborts for a value without an entry).
  std::string_view Name(E value) const {
    for (const Entry& e : names_) {
      if (e.value == value) return e.name;
    }
    GISSAR_CHECK_MSG(false, "no name for value " << static_cast<long long>(value) << " of the " << noun_
                                                 << " table");
    return {};
  }

  // The value named by `text` (a name or an alias), or nothing.
  constexpr std::optional<E> Find(std::string_view text) const {
    for (const Entry& e : names_) {
      if (Same(e.name, text, match_)) return e.value;
    }
    for (const Entry& e : aliases_) {
      if (Same(e.name, text, match_)) return e.value;
    }
    return std::nullopt;
  }

  // The value named by `text`; throws `Err` (what = UnknownMessage(text),
  // where = `where`) for any other text.
  template <class Err = ConfigError>
  E Parse(std::string_view text, const std::string& where) const {
    if (const std::optional<E> value = Find(text)) return *value;
    throw Err(UnknownMessage(text), where);
  }

  // "unknown <noun> '<text>': must be <Alternatives()>".
  std::string UnknownMessage(std::string_view text) const {
    return "unknown " + std::string(noun_) + " '" + std::string(text) + "': must be " + Alternatives();
  }

  // The canonical names in table order.
  std::vector<std::string> Names() const {
    std::vector<std::string> out;
    out.reserve(N);
    for (const Entry& e : names_) out.emplace_back(e.name);
    return out;
  }
  // The canonical names joined by `separator`: "a, b, c".
  std::string List(std::string_view separator = ", ") const {
    std::string out;
    for (size_t i = 0; i < N; ++i) {
      if (i > 0) out += separator;
      out += names_[i].name;
    }
    return out;
  }
  // The canonical names as a choice in words: "a", "a or b", "a, b or c".
  std::string Alternatives() const {
    std::string out;
    for (size_t i = 0; i < N; ++i) {
      if (i > 0) out += i + 1 == N ? " or " : ", ";
      out += names_[i].name;
    }
    return out;
  }

  static constexpr bool Same(std::string_view a, std::string_view b, EnumCase match) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i) {
      char x = a[i], y = b[i];
      if (match == EnumCase::kInsensitive) {
        if (x >= 'A' && x <= 'Z') x = static_cast<char>(x - 'A' + 'a');
        if (y >= 'A' && y <= 'Z') y = static_cast<char>(y - 'A' + 'a');
      }
      if (x != y) return false;
    }
    return true;
  }

 private:
  std::string_view noun_;
  std::array<Entry, N> names_;
  std::array<Entry, A> aliases_;
  EnumCase match_;
};

namespace internal {

// Not a constant expression: called only when a table is malformed, so that
// the consteval MakeEnumTable fails to compile there.
inline void BadEnumTable(const char* /*reason*/) {}

template <class E, size_t N, size_t A>
consteval EnumTable<E, N, A> Build(std::string_view noun, const EnumName<E> (&names)[N],
                                   const std::array<EnumName<E>, A>& aliases, EnumCase match) {
  std::array<EnumName<E>, N> entries{};
  for (size_t i = 0; i < N; ++i) {
    if (names[i].name.empty()) BadEnumTable("empty name");
    for (size_t j = 0; j < i; ++j) {
      if (names[j].value == names[i].value) BadEnumTable("a value named twice");
      if (EnumTable<E, N, A>::Same(names[j].name, names[i].name, match)) BadEnumTable("a name given twice");
    }
    entries[i] = names[i];
  }
  for (size_t i = 0; i < A; ++i) {
    for (size_t j = 0; j < N; ++j) {
      if (EnumTable<E, N, A>::Same(names[j].name, aliases[i].name, match)) BadEnumTable("an alias that is a name");
    }
    for (size_t j = 0; j < i; ++j) {
      if (EnumTable<E, N, A>::Same(aliases[j].name, aliases[i].name, match)) BadEnumTable("an alias given twice");
    }
  }
  return EnumTable<E, N, A>(noun, entries, aliases, match);
}

template <class E, size_t A>
consteval std::array<EnumName<E>, A> ToArray(const EnumName<E> (&items)[A]) {
  std::array<EnumName<E>, A> out{};
  for (size_t i = 0; i < A; ++i) out[i] = items[i];
  return out;
}

}  // namespace internal

// A table without aliases: `noun` names the values in messages ("look
// side"); `names` lists every value once with its canonical name.
template <class E, size_t N>
consteval EnumTable<E, N, 0> MakeEnumTable(std::string_view noun, const EnumName<E> (&names)[N],
                                           EnumCase match = EnumCase::kExact) {
  return internal::Build(noun, names, std::array<EnumName<E>, 0>{}, match);
}

// A table with aliases: other spellings Parse accepts (e.g. "" for a
// default), never printed.
template <class E, size_t N, size_t A>
consteval EnumTable<E, N, A> MakeEnumTable(std::string_view noun, const EnumName<E> (&names)[N],
                                           const EnumName<E> (&aliases)[A], EnumCase match = EnumCase::kExact) {
  return internal::Build(noun, names, internal::ToArray(aliases), match);
}

}  // namespace gissar::util
