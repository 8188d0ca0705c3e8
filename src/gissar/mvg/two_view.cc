#include "gissar/mvg/two_view.h"

#include <cmath>
#include <string>

#include "gissar/util/error.h"

namespace gissar::mvg {

std::optional<TwoViewAnalysis> AnalyseTwoViews(const std::vector<PointMatch>& matches,
                                               const TwoViewOptions& options) {
  for (const Eigen::Matrix3d* k : {&options.k1, &options.k2}) {
    const std::string what = (k == &options.k1) ? "K1" : "K2";
    if (!k->allFinite() || (*k)(1, 0) != 0.0 || (*k)(2, 0) != 0.0 || (*k)(2, 1) != 0.0 ||
        (*k)(2, 2) != 1.0 || (*k)(0, 0) == 0.0 || (*k)(1, 1) == 0.0) {
      throw ConfigError("intrinsic matrix must be finite, [sx k u0; 0 sy v0; 0 0 1], sx, sy != 0",
                        what);
    }
  }
  for (const std::optional<double>* d : {&options.depression1_deg, &options.depression2_deg}) {
    if (d->has_value() && (!std::isfinite(**d) || **d <= 0.0 || **d >= 90.0)) {
      throw ConfigError("depression must be in (0, 90) degrees",
                        d == &options.depression1_deg ? "depression1_deg" : "depression2_deg");
    }
  }

  TwoViewAnalysis out;
  out.num_matches = static_cast<int>(matches.size());
  if (options.robust) {
    const std::optional<RobustFundamentalFit> fit =
        EstimateAffineFundamentalRansac(matches, options.ransac);
    if (!fit) return std::nullopt;
    out.f = fit->f;
    out.inliers = fit->inliers;
    out.ransac_iterations = fit->iterations;
    out.refits = fit->refits;
    out.refit_converged = fit->refit_converged;
  } else {
    const std::optional<Eigen::Matrix3d> f = EstimateAffineFundamental(matches);
    if (!f) return std::nullopt;
    out.f = *f;
    out.inliers.resize(matches.size());
    for (size_t i = 0; i < matches.size(); ++i) out.inliers[i] = static_cast<int>(i);
    out.refits = 1;
  }
  out.residuals = ComputeResiduals(out.f, matches);
  out.rms_gs_px = RootMeanSquare(out.residuals.gs_px, out.inliers);
  out.rms_epi1_px = RootMeanSquare(out.residuals.epi1_px, out.inliers);
  out.rms_epi2_px = RootMeanSquare(out.residuals.epi2_px, out.inliers);
  out.f_calibrated = CalibrateFundamental(out.f, options.k1, options.k2);
  // A zero (a, b) or (c, d) part means the data relate no coordinate of one
  // image to the other: there is no KvD decomposition.
  const double ab = std::hypot(out.f_calibrated(0, 2), out.f_calibrated(1, 2));
  const double cd = std::hypot(out.f_calibrated(2, 0), out.f_calibrated(2, 1));
  if (ab == 0.0 || cd == 0.0) return std::nullopt;
  out.kvd = KvdFromFundamental(out.f_calibrated);
  out.epipole1 = EpipoleDirection1(out.f);
  out.epipole2 = EpipoleDirection2(out.f);
  if (options.depression1_deg && options.depression2_deg) {
    out.sar = InterpretKvdForSar(out.kvd, *options.depression1_deg, *options.depression2_deg,
                                 options.look1, options.look2);
  }
  return out;
}

}  // namespace gissar::mvg
