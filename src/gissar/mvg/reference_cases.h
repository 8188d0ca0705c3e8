// Test-only access to the affine reference cases
// (tests/data/affine, computed by independent code; see its README).
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "gissar/mvg/point_match.h"
#include "gissar/util/check.h"
#include "gissar/util/testing.h"

namespace gissar::mvg::testing {

inline constexpr const char* kCase2 = "case2_thesis_dpsi30_dep40_noisefree";
inline constexpr const char* kCase3 = "case3_dpsi30_dep40_45_res1_0.75";

struct ReferenceCase {
  nlohmann::json json;
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;

  int Column(const std::string& name) const {
    for (size_t i = 0; i < header.size(); ++i) {
      if (header[i] == name) return static_cast<int>(i);
    }
    GISSAR_CHECK_MSG(false, "no column " << name);
    return -1;
  }
  std::vector<double> Values(const std::string& name) const {
    const int c = Column(name);
    std::vector<double> out;
    for (const auto& row : rows) out.push_back(row[c]);
    return out;
  }
  // Noisy matches (x1, y1, x2, y2) of every row.
  std::vector<PointMatch> Matches() const {
    const int x1 = Column("x1"), y1 = Column("y1"), x2 = Column("x2"), y2 = Column("y2");
    std::vector<PointMatch> out;
    for (const auto& row : rows) {
      PointMatch m;
      m.p1 = {row[x1], row[y1]};
      m.p2 = {row[x2], row[y2]};
      out.push_back(m);
    }
    return out;
  }
  // 0-based indices of the rows whose column `name` is non-zero.
  std::vector<int> RowsWhere(const std::string& name) const {
    const int c = Column(name);
    std::vector<int> out;
    for (size_t i = 0; i < rows.size(); ++i) {
      if (rows[i][c] != 0.0) out.push_back(static_cast<int>(i));
    }
    return out;
  }
  std::vector<int> RowsWhereNot(const std::string& name) const {
    const int c = Column(name);
    std::vector<int> out;
    for (size_t i = 0; i < rows.size(); ++i) {
      if (rows[i][c] == 0.0) out.push_back(static_cast<int>(i));
    }
    return out;
  }
};

inline ReferenceCase LoadReferenceCase(const std::string& name) {
  ReferenceCase rc;
  {
    std::ifstream in(gissar::testing::TestDataPath("affine/" + name + ".json"));
    GISSAR_CHECK_MSG(in.good(), "cannot open reference case " << name);
    in >> rc.json;
  }
  std::ifstream in(gissar::testing::TestDataPath("affine/" + name + "_points.csv"));
  GISSAR_CHECK_MSG(in.good(), "cannot open reference points " << name);
  std::string line;
  std::getline(in, line);
  std::stringstream hs(line);
  for (std::string cell; std::getline(hs, cell, ',');) rc.header.push_back(cell);
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::stringstream ls(line);
    std::vector<double> row;
    for (std::string cell; std::getline(ls, cell, ',');) row.push_back(std::stod(cell));
    GISSAR_CHECK(row.size() == rc.header.size());
    rc.rows.push_back(row);
  }
  return rc;
}

// `v` in scientific notation with 6 significant digits (for RecordProperty).
inline std::string Sci(double v) {
  std::ostringstream s;
  s.precision(6);
  s << std::scientific << v;
  return s.str();
}

template <int R, int C>
Eigen::Matrix<double, R, C> JsonMatrix(const nlohmann::json& j) {
  Eigen::Matrix<double, R, C> m;
  GISSAR_CHECK(j.size() == static_cast<size_t>(R));
  for (int r = 0; r < R; ++r) {
    GISSAR_CHECK(j[r].size() == static_cast<size_t>(C));
    for (int c = 0; c < C; ++c) m(r, c) = j[r][c].get<double>();
  }
  return m;
}

}  // namespace gissar::mvg::testing
