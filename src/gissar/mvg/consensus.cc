#include "gissar/mvg/consensus.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "gissar/mvg/affine_fundamental.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

// log(exp(x) + exp(y)), exact for -inf arguments.
double LogAddExp(double x, double y) {
  if (x == -std::numeric_limits<double>::infinity()) return y;
  if (y == -std::numeric_limits<double>::infinity()) return x;
  const double m = std::max(x, y);
  return m + std::log1p(std::exp(-std::abs(x - y)));
}

// log P(X >= j) for j = 0..n (entry n + 1: -inf), X ~ Binomial(n, p), 0 < p < 1.
std::vector<double> LogUpperTails(int n, double p) {
  const double log_p = std::log(p), log_q = std::log1p(-p);
  std::vector<double> log_pmf(size_t(n) + 1);
  double log_choose = 0.0;  // log C(n, i), updated term by term
  for (int i = 0; i <= n; ++i) {
    log_pmf[i] = log_choose + i * log_p + (n - i) * log_q;
    log_choose += std::log(double(n - i)) - std::log(double(i + 1));
  }
  std::vector<double> tails(size_t(n) + 2, -std::numeric_limits<double>::infinity());
  for (int i = n; i >= 0; --i) tails[i] = LogAddExp(tails[i + 1], log_pmf[i]);
  return tails;
}

// P(X >= j) for j = 0..n + 1.
std::vector<double> UpperTails(int n, double p) {
  p = std::clamp(p, 0.0, 1.0);
  std::vector<double> tails(size_t(n) + 2, 0.0);
  if (p <= 0.0) {
    tails[0] = 1.0;  // X = 0 surely
  } else if (p >= 1.0) {
    std::fill(tails.begin(), tails.end() - 1, 1.0);  // X = n surely
  } else {
    const std::vector<double> logs = LogUpperTails(n, p);
    for (size_t j = 0; j < logs.size(); ++j) tails[j] = std::min(1.0, std::exp(logs[j]));
    tails[0] = 1.0;
  }
  return tails;
}

}  // namespace

double BinomialUpperTail(int n, double p, int k) {
  if (n < 0) throw ConfigError("a binomial count must not be negative", "n");
  if (k <= 0) return 1.0;
  if (k > n) return 0.0;
  return UpperTails(n, p)[k];
}

int64_t DistinctSamples(int matches, int sample_size) {
  if (sample_size < 0 || matches < sample_size) return 0;
  // C(n, k) = prod_{i=1..k} (n - k + i) / i, exact in integers at each step.
  int64_t c = 1;
  for (int i = 1; i <= sample_size; ++i) {
    const int64_t factor = int64_t(matches) - sample_size + i;
    if (c > std::numeric_limits<int64_t>::max() / factor) return std::numeric_limits<int64_t>::max();
    c = c * factor / i;
  }
  return c;
}

ConsensusTest TestConsensus(int matches, int inliers, double chance_probability, int64_t hypotheses, double alpha,
                            int sample_size) {
  if (!(alpha > 0.0 && alpha < 1.0)) throw ConfigError("the false-alarm rate must be in (0, 1)", "alpha");
  if (hypotheses < 1) throw ConfigError("at least one hypothesis is tested", "hypotheses");
  if (matches < 0 || sample_size < 0) throw ConfigError("counts must not be negative", "matches");
  ConsensusTest t;
  t.matches = matches;
  t.inliers = std::clamp(inliers, 0, matches);
  t.sample_size = sample_size;
  t.chance_probability = std::isfinite(chance_probability) ? std::clamp(chance_probability, 0.0, 1.0) : 1.0;
  t.hypotheses = hypotheses;
  t.alpha = alpha;
  const int trials = std::max(0, matches - sample_size);  // matches outside the sample
  t.expected_by_chance = std::min(matches, sample_size) + trials * t.chance_probability;
  const std::vector<double> tails = UpperTails(trials, t.chance_probability);
  auto tail = [&](int k) {  // P(X >= k - sample_size)
    const int j = k - sample_size;
    return j <= 0 ? 1.0 : (j > trials ? 0.0 : tails[j]);
  };
  const double level = alpha / double(hypotheses);
  t.p_value = tail(t.inliers);
  t.significant = t.p_value <= level;
  for (int k = std::min(sample_size, matches); k <= matches; ++k) {
    if (tail(k) <= level) {
      t.required = k;
      break;
    }
  }
  return t;
}

double ChanceInlierProbability(const Eigen::Matrix3d& f, const std::vector<PointMatch>& matches,
                               double threshold_px) {
  const Eigen::Matrix3d g = NormalizeAffineFundamental(f);  // ||(a, b, c, d)|| = 1
  const double a = g(0, 2), b = g(1, 2);
  if (matches.empty()) return 1.0;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const PointMatch& m : matches) {
    const double v = a * m.p2.x() + b * m.p2.y();
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  const double extent = hi - lo;
  if (!(extent > 0.0) || !std::isfinite(extent)) return 1.0;
  return std::min(1.0, 2.0 * threshold_px / extent);
}

}  // namespace gissar::mvg
