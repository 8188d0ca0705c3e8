// One table per request (docs/architecture.md "Adding an option"): every
// field of a request struct declared once, with its name, help text and how
// it is read and written, and every door derived from that table:
//   - the JSON options (ToJson: the sidecar's provenance record and
//     `--options` files' keys; ApplyJson: options files, Python keywords);
//   - the CLI flags and their help (cli/command.h RequestFlags binds the
//     table's fields to a CLI11 subcommand);
//   - the Python keywords and their help (gissar._core.*_request_defaults()
//     and *_request_help(), which the Python package and the corridor read).
// A new option is a member of the request, one row of its table, the code
// that uses it and its test.
//
// Kinds of field:
//   - plain: bool, int, int64_t, uint64_t, double, std::string or a list of
//     strings (std::vector<std::string>: JSON ["a", "b"], CLI --NAME A B),
//     stored as is (a bool is an on/off switch at the CLI: --NAME and
//     --no-NAME);
//   - nullable number: a double whose NaN means "not set" (JSON null);
//   - enum: stored as the enum, written and read as its name (util::EnumTable);
//   - optional pair: std::optional<Eigen::Vector2d>, JSON [a, b] or null,
//     CLI text "A,B";
//   - optional integer window: std::optional<std::array<int, 4>>, JSON of
//     four integers or null, CLI text "A,B,C,D".
// JSON null: a nullable field's "not set"; for the others an error, or the
// default kept in a table made with null_keeps_default (evaluate's: the
// Python door passes None for keywords not given).
// Failures: reading a value of the wrong type or shape is a ConfigError
// naming the key and the source (file, "Python keywords", "command line");
// an unknown key is a ConfigError with a "did you mean" (UnknownKeyMessage).
// A table with a name twice is a bug (GISSAR_CHECK).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/pipeline/field_names.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::pipeline {

// Where a plain field is stored, for a door that binds it directly (the CLI
// binds these with its own type conversion); monostate for the fields a
// door takes as text (enums, pairs, windows, nullable numbers keep their
// NaN default as a double).
using FieldRef = std::variant<std::monostate, bool*, int*, int64_t*, uint64_t*, double*, std::string*,
                              std::vector<std::string>*>;

template <class R>
struct RequestField {
  std::string name;  // snake_case with its unit suffix: JSON key, Python keyword, sidecar key
  // One line for --help and docstrings, without the default (the doors add
  // it); "" = offered by no door as a flag (e.g. max_memory_bytes, spelt
  // --max-memory SIZE).
  std::string help;
  bool show_default = true;     // --help shows the default value
  std::string extra_negations;  // a switch's older spellings of --no-NAME ("--fixed-sampling")
  std::function<nlohmann::json(const R&)> get;
  std::function<void(R&, const nlohmann::json&, const std::string& key, const std::string& source)> set;
  std::function<FieldRef(R&)> ref;  // see FieldRef
  // A text field's flag value as the JSON value `set` takes ("1,2" ->
  // [1, 2]); ConfigError naming `flag` when malformed. Empty for plain fields.
  std::function<nlohmann::json(const std::string& text, const std::string& flag)> from_text;

  // The CLI flag: FlagOfField(name), or an older spelling the command kept
  // (`flag_override`, e.g. evaluate's speckle_looks is --looks).
  std::string flag_override;
  // JSON null is this field's "not set" (nullable numbers, optional pairs and
  // windows); for the other fields a table either refuses null or keeps the
  // default (FieldTable's `null_keeps_default`).
  bool accepts_null = false;

  // Other spellings the CLI also accepts for this flag, comma-separated
  // ("--looks"): listed in --help beside the flag.
  std::string aliases;

  std::string Flag() const { return flag_override.empty() ? FlagOfField(name) : flag_override; }
  RequestField&& WithFlag(std::string flag) && {
    flag_override = std::move(flag);
    return std::move(*this);
  }
  RequestField&& WithAliases(std::string other_flags) && {
    aliases = std::move(other_flags);
    return std::move(*this);
  }
  RequestField&& WithHelp(std::string text) && {
    help = std::move(text);
    return std::move(*this);
  }
  bool IsSwitch(R& r) const { return std::holds_alternative<bool*>(ref(r)); }
};

template <class R>
class FieldTable {
 public:
  // `null_keeps_default`: ApplyJson skips a null value of a field that does
  // not accept null (the request keeps its value), instead of refusing it.
  explicit FieldTable(std::vector<RequestField<R>> fields, bool null_keeps_default = false)
      : fields_(std::move(fields)), null_keeps_default_(null_keeps_default) {
    std::set<std::string> seen;
    for (const RequestField<R>& f : fields_) GISSAR_CHECK_MSG(seen.insert(f.name).second, "field twice: " << f.name);
  }
  const std::vector<RequestField<R>>& fields() const { return fields_; }
  // The field `name`, or nullptr.
  const RequestField<R>* Find(const std::string& name) const {
    for (const RequestField<R>& f : fields_) {
      if (f.name == name) return &f;
    }
    return nullptr;
  }
  // The field `name`; a name not in the table is a bug in the caller.
  const RequestField<R>& at(const std::string& name) const {
    const RequestField<R>* f = Find(name);
    GISSAR_CHECK_MSG(f != nullptr, "no request field " << name);
    return *f;
  }
  std::vector<std::string> Names() const {
    std::vector<std::string> names;
    for (const RequestField<R>& f : fields_) names.push_back(f.name);
    return names;
  }
  // {name: value} of every field.
  nlohmann::json ToJson(const R& r) const {
    nlohmann::json j = nlohmann::json::object();
    for (const RequestField<R>& f : fields_) j[f.name] = f.get(r);
    return j;
  }
  // Sets the fields named by `values` (null: the field's "not set", or its
  // default for a plain field); ConfigError naming the key and `source`.
  void ApplyJson(R& r, const nlohmann::json& values, const std::string& source) const {
    if (!values.is_object()) throw ConfigError("options must be a JSON object", source);
    for (const auto& [key, value] : values.items()) {
      const RequestField<R>* f = Find(key);
      if (f == nullptr) throw ConfigError(UnknownKeyMessage(key, Names()), source);
      if (value.is_null() && !f->accepts_null && null_keeps_default_) continue;
      f->set(r, value, key, source);
    }
  }
  // {name: help} of the fields a door offers (help not empty).
  std::map<std::string, std::string> Help() const {
    std::map<std::string, std::string> help;
    for (const RequestField<R>& f : fields_) {
      if (!f.help.empty()) help[f.name] = f.help;
    }
    return help;
  }

 private:
  std::vector<RequestField<R>> fields_;
  bool null_keeps_default_ = false;
};

// Builders of the rows of a table of requests R. `access` is a function
// R& -> T&: At(&R::member), or At(&R::outer, &Outer::member) for a member
// of a member.
// How a door's text becomes a field's JSON value (see RequestField::from_text).
using TextReader = std::function<nlohmann::json(const std::string& text, const std::string& flag)>;

// The reader of "A,B" (ParseNumberPair): JSON [a, b].
inline nlohmann::json NumberPairText(const std::string& text, const std::string& flag) {
  const Eigen::Vector2d v = ParseNumberPair(text, flag);
  return nlohmann::json{v.x(), v.y()};
}

template <class R>
struct Fields {
  // The accessor of a member of R (or of a base of R's), or of a member of
  // a member of R.
  template <class T, class B>
    requires std::is_base_of_v<B, R>
  static auto At(T B::*member) {
    return [member](R& r) -> T& { return r.*member; };
  }
  template <class S, class T>
  static auto At(S R::*outer, T S::*inner) {
    return [outer, inner](R& r) -> T& { return (r.*outer).*inner; };
  }

  template <class Access>
  static RequestField<R> Plain(std::string name, Access access, std::string help, bool show_default = true,
                               std::string extra_negations = "") {
    using T = std::remove_reference_t<decltype(access(std::declval<R&>()))>;
    RequestField<R> f;
    f.name = std::move(name);
    f.help = std::move(help);
    f.show_default = show_default;
    f.extra_negations = std::move(extra_negations);
    f.get = [access](const R& r) { return nlohmann::json(access(const_cast<R&>(r))); };
    f.set = [access](R& r, const nlohmann::json& value, const std::string& key, const std::string& source) {
      AssignField(access(r), value, key, source);
    };
    f.ref = [access](R& r) { return FieldRef(&access(r)); };
    static_assert(std::is_constructible_v<FieldRef, T*>,
                  "a plain field is bool, int, int64, uint64, double, string or a list of strings");
    return f;
  }

  // A double whose NaN means "not set" (JSON null).
  template <class Access>
  static RequestField<R> NullableNumber(std::string name, Access access, std::string help,
                                        bool show_default = false) {
    RequestField<R> f = Plain(std::move(name), access, std::move(help), show_default);
    f.accepts_null = true;
    f.get = [access](const R& r) {
      const double v = access(const_cast<R&>(r));
      return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v);
    };
    f.set = [access](R& r, const nlohmann::json& value, const std::string& key, const std::string& source) {
      if (value.is_null()) {
        access(r) = std::numeric_limits<double>::quiet_NaN();
      } else {
        AssignField(access(r), value, key, source);
      }
    };
    return f;
  }

  // An enum written and read as its name in `table` (parse errors name the
  // field's flag, as the CLI spells it).
  template <class Access, class Table>
  static RequestField<R> Enum(std::string name, Access access, const Table& table, std::string help) {
    RequestField<R> f;
    f.name = std::move(name);
    f.help = std::move(help);
    const std::string flag = f.Flag();
    f.get = [access, &table](const R& r) { return nlohmann::json(std::string(table.Name(access(const_cast<R&>(r))))); };
    f.set = [access, &table, flag](R& r, const nlohmann::json& value, const std::string& key,
                                   const std::string& source) {
      std::string text;
      AssignField(text, value, key, source);
      access(r) = table.Parse(text, flag);
    };
    f.ref = [](R&) { return FieldRef(); };
    f.from_text = [](const std::string& text, const std::string&) { return nlohmann::json(text); };
    return f;
  }

  // std::vector<double> of `count` numbers: JSON [a, b, ...]; CLI text "A,B,..." (ConfigError naming the
  // flag: "needs N numbers A,B,..., got 'TEXT'").
  template <class Access>
  static RequestField<R> Numbers(std::string name, Access access, size_t count, std::string help) {
    RequestField<R> f;
    f.name = std::move(name);
    f.help = std::move(help);
    f.get = [access](const R& r) { return nlohmann::json(access(const_cast<R&>(r))); };
    f.set = [access, count](R& r, const nlohmann::json& value, const std::string& key, const std::string& source) {
      std::vector<double> v;
      AssignField(v, value, key, source);
      if (v.size() != count) {
        throw ConfigError("key '" + key + "' needs " + std::to_string(count) + " numbers", source);
      }
      access(r) = std::move(v);
    };
    f.ref = [](R&) { return FieldRef(); };
    f.from_text = NumbersText(count);
    return f;
  }

  // The reader of `count` comma-separated numbers "A,B,..." (ConfigError
  // naming the flag: "needs N comma-separated numbers, got 'TEXT'").
  static TextReader NumbersText(size_t count) {
    return [count](const std::string& text, const std::string& flag) {
      std::vector<double> v;
      std::string item;
      bool ok = !text.empty() && text.back() != ',';
      for (size_t start = 0; ok && start <= text.size();) {
        const size_t comma = std::min(text.find(',', start), text.size());
        item = text.substr(start, comma - start);
        try {
          size_t used = 0;
          v.push_back(std::stod(item, &used));
          ok = used == item.size() && std::isfinite(v.back());
        } catch (const std::exception&) {
          ok = false;
        }
        start = comma + 1;
      }
      if (!ok || v.size() != count) {
        throw ConfigError("needs " + std::to_string(count) + " comma-separated numbers, got '" + text + "'", flag);
      }
      return nlohmann::json(v);
    };
  }

  // std::vector<int>: JSON [a, b, ...]; CLI text "A,B,..." (ParseIntegerList,
  // whose error names `expected`, e.g. "two integers R,A"). `count` > 0:
  // exactly that many ("key 'K' needs N integers" otherwise); the values'
  // bounds are the request's Check().
  template <class Access>
  static RequestField<R> Integers(std::string name, Access access, size_t count, std::string help,
                                  std::string expected, bool show_default = true) {
    RequestField<R> f;
    f.name = std::move(name);
    f.help = std::move(help);
    f.show_default = show_default;
    f.get = [access](const R& r) { return nlohmann::json(access(const_cast<R&>(r))); };
    f.set = [access, count](R& r, const nlohmann::json& value, const std::string& key, const std::string& source) {
      std::vector<int> v;
      AssignField(v, value, key, source);
      if (count > 0 && v.size() != count) {
        throw ConfigError("key '" + key + "' needs " + std::to_string(count) + " integers", source);
      }
      access(r) = std::move(v);
    };
    f.ref = [](R&) { return FieldRef(); };
    f.from_text = [count, expected](const std::string& text, const std::string& flag) {
      return nlohmann::json(ParseIntegerList(text, flag, expected, count));
    };
    return f;
  }

  // The row `row` of the table of the request S that R holds as `member`
  // (validate's simulate request): same name, help and flag, reading and
  // writing r.*member.
  template <class S>
  static RequestField<R> Of(S R::*member, const RequestField<S>& row) {
    RequestField<R> f;
    f.name = row.name;
    f.help = row.help;
    f.show_default = row.show_default;
    f.extra_negations = row.extra_negations;
    f.flag_override = row.flag_override;
    f.accepts_null = row.accepts_null;
    f.aliases = row.aliases;
    f.from_text = row.from_text;
    f.get = [member, get = row.get](const R& r) { return get(r.*member); };
    f.set = [member, set = row.set](R& r, const nlohmann::json& value, const std::string& key,
                                    const std::string& source) { set(r.*member, value, key, source); };
    f.ref = [member, ref = row.ref](R& r) { return ref(r.*member); };
    return f;
  }

  // std::optional<Eigen::Vector2d>: JSON [a, b] or null; CLI text read by `from_text` ("A,B").
  template <class Access>
  static RequestField<R> OptionalPair(std::string name, Access access, std::string help, TextReader from_text) {
    return OptionalList<double, 2>(std::move(name), access, std::move(help), std::move(from_text), "two numbers");
  }

  // std::optional<std::array<int, 4>>: JSON of four integers or null; CLI text read by `from_text`.
  template <class Access>
  static RequestField<R> OptionalWindow(std::string name, Access access, std::string help, TextReader from_text) {
    return OptionalList<int, 4>(std::move(name), access, std::move(help), std::move(from_text), "four integers");
  }

 private:
  // std::optional of N values of type Item (an Eigen vector, a std::array):
  // JSON of N items or null ("key 'K' needs <needs>" otherwise).
  template <class Item, size_t N, class Access>
  static RequestField<R> OptionalList(std::string name, Access access, std::string help, TextReader from_text,
                                      std::string needs) {
    using Value = typename std::remove_reference_t<decltype(access(std::declval<R&>()))>::value_type;
    RequestField<R> f;
    f.name = std::move(name);
    f.help = std::move(help);
    f.show_default = false;
    f.accepts_null = true;
    f.get = [access](const R& r) {
      const std::optional<Value>& v = access(const_cast<R&>(r));
      if (!v) return nlohmann::json(nullptr);
      nlohmann::json items = nlohmann::json::array();
      for (size_t i = 0; i < N; ++i) items.push_back(Item((*v)[i]));
      return items;
    };
    f.set = [access, needs](R& r, const nlohmann::json& value, const std::string& key, const std::string& source) {
      if (value.is_null()) {
        access(r).reset();
        return;
      }
      std::vector<Item> v;
      AssignField(v, value, key, source);
      if (v.size() != N) throw ConfigError("key '" + key + "' needs " + needs, source);
      Value out;
      for (size_t i = 0; i < N; ++i) out[i] = v[i];
      access(r) = out;
    };
    f.ref = [](R&) { return FieldRef(); };
    f.from_text = std::move(from_text);
    return f;
  }
};

}  // namespace gissar::pipeline
