// Reproducible random sampling for the robust estimators of the mvg module,
// and the check of the sampling budget they share.
// Only the raw 32-bit outputs of std::mt19937 are used (which the standard
// fixes), not std::uniform_int_distribution (whose algorithm is left to the
// library), so a seed gives the same samples with every standard library.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::mvg {

// Uniform integer in [0, n), n >= 1, by rejection sampling.
inline int UniformIndex(std::mt19937& rng, int n) {
  GISSAR_CHECK(n >= 1);
  const uint64_t range = static_cast<uint64_t>(n);
  const uint64_t limit = (uint64_t{1} << 32) / range * range;
  for (;;) {
    const uint64_t r = static_cast<uint64_t>(rng());
    if (r < limit) return static_cast<int>(r % range);
  }
}

// `k` distinct indices in [0, n), k <= n, in the order drawn.
inline std::vector<int> SampleDistinct(std::mt19937& rng, int n, int k) {
  GISSAR_CHECK(k >= 0 && k <= n);
  std::vector<int> sample;
  sample.reserve(k);
  while (static_cast<int>(sample.size()) < k) {
    const int candidate = UniformIndex(rng, n);
    bool seen = false;
    for (int s : sample) seen = seen || (s == candidate);
    if (!seen) sample.push_back(candidate);
  }
  return sample;
}

template <int K>
std::array<int, K> SampleDistinct(std::mt19937& rng, int n) {
  const std::vector<int> v = SampleDistinct(rng, n, K);
  std::array<int, K> out;
  for (int i = 0; i < K; ++i) out[i] = v[i];
  return out;
}

// The sampling budget every RANSAC here shares: throws ConfigError naming
// the field unless confidence is in (0, 1), max_iterations >= 1,
// min_iterations in [0, max_iterations] and max_refits >= 1.
inline void CheckSamplingBudget(double confidence, int max_iterations, int min_iterations, int max_refits) {
  if (!std::isfinite(confidence) || confidence <= 0.0 || confidence >= 1.0) {
    throw ConfigError("RANSAC confidence must be in (0, 1)", "confidence");
  }
  if (max_iterations < 1) throw ConfigError("RANSAC needs at least 1 iteration", "max_iterations");
  if (min_iterations < 0 || min_iterations > max_iterations) {
    throw ConfigError("min_iterations must be in [0, max_iterations]", "min_iterations");
  }
  if (max_refits < 1) throw ConfigError("at least 1 refit is needed", "max_refits");
}

}  // namespace gissar::mvg
