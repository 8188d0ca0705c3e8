#include "gissar/mvg/match_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

std::string_view Trim(std::string_view s) {
  auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  if (s.size() >= 2 && s.front() == '"' && s.back() == '"') {
    s = s.substr(1, s.size() - 2);
    while (!s.empty() && blank(s.front())) s.remove_prefix(1);
    while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  }
  return s;
}

std::vector<std::string_view> SplitFields(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t start = 0;
  for (;;) {
    const size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields.push_back(Trim(line.substr(start)));
      return fields;
    }
    fields.push_back(Trim(line.substr(start, comma - start)));
    start = comma + 1;
  }
}

bool IsBlank(std::string_view line) {
  return Trim(line).empty() && line.find(',') == std::string_view::npos;
}

// Reads the file's records and returns, per record, the values of the
// `names` columns.
std::vector<std::vector<double>> ReadColumns(const std::filesystem::path& path,
                                             const std::vector<std::string>& names) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError("file does not exist or is not a regular file", file);
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot open file for reading", file);

  std::string line;
  int line_number = 0;
  // Header: the first non-blank line.
  bool have_header = false;
  while (std::getline(in, line)) {
    ++line_number;
    if (line_number == 1 && line.size() >= 3 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) {
      line.erase(0, 3);  // UTF-8 byte order mark
    }
    if (!IsBlank(line)) {
      have_header = true;
      break;
    }
  }
  if (!have_header) throw InputError("empty CSV file: no header line", file);
  const std::vector<std::string_view> header_views = SplitFields(line);
  const std::vector<std::string> header(header_views.begin(), header_views.end());
  for (size_t i = 0; i < header.size(); ++i) {
    for (size_t j = i + 1; j < header.size(); ++j) {
      if (!header[i].empty() && header[i] == header[j]) {
        throw InputError("column '" + header[i] + "' appears twice in the header",
                         file + ":" + std::to_string(line_number));
      }
    }
  }
  std::vector<size_t> index;
  size_t needed_fields = 0;
  for (const std::string& name : names) {
    size_t found = header.size();
    for (size_t i = 0; i < header.size(); ++i) {
      if (header[i] == name) found = i;
    }
    if (found == header.size()) {
      std::string all;
      for (const std::string& n : names) all += (all.empty() ? "" : ", ") + n;
      throw InputError("required column '" + name + "' missing from the header (need " + all + ")",
                       file);
    }
    index.push_back(found);
    needed_fields = std::max(needed_fields, found + 1);
  }

  std::vector<std::vector<double>> records;
  while (std::getline(in, line)) {
    ++line_number;
    if (IsBlank(line)) continue;
    const std::string where = file + ":" + std::to_string(line_number);
    const std::vector<std::string_view> fields = SplitFields(line);
    if (fields.size() < needed_fields) {
      throw InputError("record has " + std::to_string(fields.size()) + " fields, fewer than the " +
                           std::to_string(needed_fields) + " the required columns need",
                       where);
    }
    std::vector<double> values;
    values.reserve(names.size());
    for (size_t k = 0; k < names.size(); ++k) {
      const std::string_view text = fields[index[k]];
      double v = 0.0;
      const char* begin = text.data();
      const char* end = text.data() + text.size();
      if (!text.empty() && *begin == '+') ++begin;  // from_chars rejects a leading '+'
      const std::from_chars_result r = std::from_chars(begin, end, v);
      if (text.empty() || r.ec != std::errc() || r.ptr != end) {
        throw InputError("column '" + names[k] + "' is not a number: '" + std::string(text) + "'",
                         where);
      }
      if (!std::isfinite(v)) {
        throw InputError("column '" + names[k] + "' is not finite: '" + std::string(text) + "'",
                         where);
      }
      // Pixels and metres beyond 1e9 are no image or terrain; their squares
      // would overflow the fits to infinity.
      if (std::abs(v) > kMaxPointCoordinate) {
        throw InputError("column '" + names[k] + "' is out of range [-1e9, 1e9]: '" + std::string(text) + "'",
                         where);
      }
      values.push_back(v);
    }
    records.push_back(std::move(values));
  }
  if (in.bad()) throw InputError("read error", file);
  return records;
}

}  // namespace

std::vector<PointMatch> ReadMatchesCsv(const std::filesystem::path& path) {
  const auto records = ReadColumns(path, {"x1", "y1", "x2", "y2"});
  std::vector<PointMatch> out;
  out.reserve(records.size());
  for (const auto& r : records) {
    PointMatch m;
    m.p1 = {r[0], r[1]};
    m.p2 = {r[2], r[3]};
    out.push_back(m);
  }
  return out;
}

std::vector<ControlPoint> ReadControlPointsCsv(const std::filesystem::path& path) {
  const auto records = ReadColumns(path, {"X", "Y", "Z", "x", "y"});
  std::vector<ControlPoint> out;
  out.reserve(records.size());
  for (const auto& r : records) {
    ControlPoint p;
    p.world = {r[0], r[1], r[2]};
    p.pixel = {r[3], r[4]};
    out.push_back(p);
  }
  return out;
}

}  // namespace gissar::mvg
