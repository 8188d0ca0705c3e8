#include "gissar/image/point_target.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

#include "gissar/image/irf_plot.h"
#include "gissar/util/error.h"

namespace gissar::image {
namespace {

// sinc(t) = sin(pi t) / (pi t). Its power sinc^2 is 1/2 at t = +-0.442946,
// so the -3 dB width of sinc(B x) is 0.885893 / B pixels for a band of B
// cycles per pixel. The first sidelobe is sinc(1.4303) = -0.217234, PSLR
// 20 log10(0.217234) = -13.26 dB.
double Sinc(double t) { return t == 0.0 ? 1.0 : std::sin(M_PI * t) / (M_PI * t); }

constexpr double kSincWidthFactor = 0.885893;

// Bands for 1.3 (range) and 1.45 (azimuth) samples per resolution cell.
const double kBandRange = kSincWidthFactor / 1.3;    // 0.6815 cycles/px
const double kBandAzimuth = kSincWidthFactor / 1.45;  // 0.6110 cycles/px

struct Target {
  double col = 32.37;  // +0.37 px from the prediction (32, 32)
  double row = 31.79;  // -0.21 px
  double band_range = kBandRange;
  double band_azimuth = kBandAzimuth;
  bool hamming = false;
  // Spectrum centre (cycles per pixel): the Doppler centroid in azimuth.
  double centre_range = 0.0;
  double centre_azimuth = 0.0;
  double amplitude = 1.0;
  double phase = 0.0;
};

// Amplitude response of a rectangular band B (cycles/px), optionally with
// the Hamming weighting 0.54 + 0.46 cos(2 pi f / B) over |f| <= B/2, whose
// inverse transform is 0.54 sinc(B x) + 0.23 [sinc(B x - 1) + sinc(B x + 1)]
// (up to the factor B, dropped: the peak is 1 and 0.54 respectively).
double Response(double x, double band, bool hamming) {
  const double t = band * x;
  if (!hamming) return Sinc(t);
  return 0.54 * Sinc(t) + 0.23 * (Sinc(t - 1.0) + Sinc(t + 1.0));
}

std::vector<std::complex<float>> Synthesise(int width, int height, const Target& target) {
  std::vector<std::complex<float>> slc(size_t(width) * height);
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const double a = target.amplitude * Response(c - target.col, target.band_range, target.hamming) *
                       Response(r - target.row, target.band_azimuth, target.hamming);
      const double phase =
          target.phase + 2.0 * M_PI * (target.centre_range * c + target.centre_azimuth * r);
      slc[size_t(r) * width + c] = std::complex<float>(std::polar(a, phase));
    }
  }
  return slc;
}

// Circular complex Gaussian clutter of mean power `power` per sample.
void AddClutter(std::vector<std::complex<float>>& slc, double power, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, std::sqrt(power / 2.0));
  for (auto& s : slc) s += std::complex<float>(float(normal(rng)), float(normal(rng)));
}

PointTargetOptions Options() {
  PointTargetOptions options;
  options.range_spacing_m = 1.5;
  options.azimuth_spacing_m = 2.0;
  return options;
}

// Integral of sinc^2(t) by Simpson's rule in long double over [a, b].
long double SincSquaredIntegral(long double a, long double b) {
  const int steps = 2 * int(std::ceil((b - a) / 2e-4L));
  const long double step = (b - a) / steps;
  auto f = [](long double t) {
    if (t == 0.0L) return 1.0L;
    const long double s = std::sin(M_PIl * t) / (M_PIl * t);
    return s * s;
  };
  long double sum = f(a) + f(b);
  for (int i = 1; i < steps; ++i) sum += (i % 2 ? 4.0L : 2.0L) * f(a + i * step);
  return sum * step / 3.0L;
}

// 1-D ISLR of sinc^2 with the null-to-null main lobe t in [-1, 1] and the
// sidelobes over [t_first, t_last] (the cut's extent, in units of 1 / B).
// Over the whole line the main lobe holds 0.9028 of the energy: ISLR =
// 10 log10(0.0972 / 0.9028) = -9.68 dB; a finite cut holds less sidelobe
// energy (the tails beyond T hold about 1 / (pi^2 T) each).
double SincIslrDb(double t_first, double t_last) {
  const long double main = SincSquaredIntegral(-1.0L, 1.0L);
  const long double side = SincSquaredIntegral(t_first, -1.0L) + SincSquaredIntegral(1.0L, t_last);
  return double(10.0L * std::log10(side / main));
}

// Unweighted 2-D sinc at (+0.37, -0.21) px from the prediction, 64 x 64
// samples, 1.3 / 1.45 samples per resolution cell.
TEST(PointTargetTest, UnweightedSincMatchesTheory) {
  const Target target;
  const auto slc = Synthesise(64, 64, target);
  std::string why;
  const auto m = MeasurePointTarget(slc, 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(m) << why;
  EXPECT_EQ(m->peak_sample_col, 32);
  EXPECT_EQ(m->peak_sample_row, 32);
  EXPECT_NEAR(m->peak_px.range, target.col, 0.05);
  EXPECT_NEAR(m->peak_px.azimuth, target.row, 0.05);
  EXPECT_NEAR(m->location_error_px.range, 0.37, 0.05);
  EXPECT_NEAR(m->location_error_px.azimuth, -0.21, 0.05);
  EXPECT_NEAR(m->location_error_m.range, m->location_error_px.range * 1.5, 1e-12);
  EXPECT_NEAR(m->location_error_m.azimuth, m->location_error_px.azimuth * 2.0, 1e-12);
  // -3 dB widths 0.885893 / B: 1.3 px = 1.95 m, 1.45 px = 2.9 m.
  EXPECT_NEAR(m->resolution_px.range, 1.3, 0.013);
  EXPECT_NEAR(m->resolution_px.azimuth, 1.45, 0.0145);
  EXPECT_NEAR(m->resolution_m.range, 1.95, 0.0195);
  EXPECT_NEAR(m->resolution_m.azimuth, 2.9, 0.029);
  // Null to null: 2 / B.
  EXPECT_NEAR(m->main_lobe_px.range, 2.0 / kBandRange, 0.05);
  EXPECT_NEAR(m->main_lobe_px.azimuth, 2.0 / kBandAzimuth, 0.05);
  EXPECT_NEAR(m->pslr_db.range, -13.26, 0.3);
  EXPECT_NEAR(m->pslr_db.azimuth, -13.26, 0.3);
  // The cuts span the chip's samples: columns and rows 16..47 (brightest
  // sample 32, chip half-size 16), i.e. t = B (16 - x0) .. B (47 - x0).
  const double islr_range = SincIslrDb(kBandRange * (16 - target.col), kBandRange * (47 - target.col));
  const double islr_azimuth = SincIslrDb(kBandAzimuth * (16 - target.row), kBandAzimuth * (47 - target.row));
  EXPECT_NEAR(islr_range, -10.1, 0.1);  // vs -9.68 dB over the whole line
  EXPECT_NEAR(m->islr_db.range, islr_range, 0.2);
  EXPECT_NEAR(m->islr_db.azimuth, islr_azimuth, 0.2);
  // A centred spectrum (real samples) gets no phase ramp at all.
  EXPECT_EQ(m->spectrum_centre_cycles_per_px.range, 0.0);
  EXPECT_EQ(m->spectrum_centre_cycles_per_px.azimuth, 0.0);
  EXPECT_NEAR(std::abs(m->peak_value), 1.0, 0.005);
  EXPECT_FALSE(m->calibrated);
  EXPECT_GT(m->scr_db, 60.0);  // the corner boxes hold only sidelobe products
  std::cout << "sinc: location error " << m->peak_px.range - target.col << ", " << m->peak_px.azimuth - target.row
            << " px; width " << m->resolution_px.range << ", " << m->resolution_px.azimuth << " px; PSLR "
            << m->pslr_db.range << ", " << m->pslr_db.azimuth << " dB; ISLR " << m->islr_db.range << ", "
            << m->islr_db.azimuth << " dB (reference " << islr_range << ", " << islr_azimuth << "); 2-D ISLR "
            << m->islr_2d_db << " dB\n";
}

// Hamming weighting 0.54 + 0.46 cos: highest sidelobe -42.7 dB, -3 dB width
// 1.30 / B (Harris 1978).
TEST(PointTargetTest, HammingWeightedResponse) {
  Target target;
  target.hamming = true;
  const auto slc = Synthesise(64, 64, target);
  std::string why;
  const auto m = MeasurePointTarget(slc, 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(m) << why;
  EXPECT_NEAR(m->peak_px.range, target.col, 0.05);
  EXPECT_NEAR(m->peak_px.azimuth, target.row, 0.05);
  EXPECT_NEAR(m->resolution_px.range, 1.30 / kBandRange, 0.02 * 1.30 / kBandRange);
  EXPECT_NEAR(m->resolution_px.azimuth, 1.30 / kBandAzimuth, 0.02 * 1.30 / kBandAzimuth);
  EXPECT_NEAR(m->pslr_db.range, -42.7, 1.0);
  EXPECT_NEAR(m->pslr_db.azimuth, -42.7, 1.0);
  std::cout << "hamming: width " << m->resolution_px.range * kBandRange << ", "
            << m->resolution_px.azimuth * kBandAzimuth << " / B; PSLR " << m->pslr_db.range << ", "
            << m->pslr_db.azimuth << " dB; ISLR " << m->islr_db.range << ", " << m->islr_db.azimuth << " dB\n";
}

// A spectrum centred at (0.23, -0.31) cycles/px (a Doppler centroid of
// -0.31 PRF): the range band spans -0.11..0.57 and wraps, so padding the
// uncentred spectrum would split it. After removing the centroid, location,
// widths and PSLR equal those of the centred response.
TEST(PointTargetTest, SpectrumOffCentreMeasuresLikeCentred) {
  Target centred;
  Target shifted = centred;
  shifted.centre_range = 0.23;
  shifted.centre_azimuth = -0.31;
  shifted.phase = 0.4;
  std::string why;
  const auto a = MeasurePointTarget(Synthesise(64, 64, centred), 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(a) << why;
  const auto b = MeasurePointTarget(Synthesise(64, 64, shifted), 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(b) << why;
  EXPECT_NEAR(b->spectrum_centre_cycles_per_px.range, 0.23, 0.005);
  EXPECT_NEAR(b->spectrum_centre_cycles_per_px.azimuth, -0.31, 0.005);
  EXPECT_NEAR(b->peak_px.range, a->peak_px.range, 0.01);
  EXPECT_NEAR(b->peak_px.azimuth, a->peak_px.azimuth, 0.01);
  EXPECT_NEAR(b->resolution_px.range, a->resolution_px.range, 0.005);
  EXPECT_NEAR(b->resolution_px.azimuth, a->resolution_px.azimuth, 0.005);
  EXPECT_NEAR(b->pslr_db.range, a->pslr_db.range, 0.1);
  EXPECT_NEAR(b->pslr_db.azimuth, a->pslr_db.azimuth, 0.1);
  EXPECT_NEAR(b->islr_db.range, a->islr_db.range, 0.1);
  EXPECT_NEAR(b->islr_db.azimuth, a->islr_db.azimuth, 0.1);
  EXPECT_NEAR(b->rcs_dbsm, a->rcs_dbsm, 1e-6);  // |s| is the same
  // The peak's complex value keeps the ramp: phase 0.4 + 2 pi (0.23 x0 -
  // 0.31 y0) at the peak (the grid maximum is within 1/64 px of it: 0.03 rad).
  const double expected = 0.4 + 2.0 * M_PI * (0.23 * centred.col - 0.31 * centred.row);
  EXPECT_NEAR(std::remainder(std::arg(b->peak_value) - expected, 2.0 * M_PI), 0.0, 0.06);
  EXPECT_NEAR(std::abs(b->peak_value), 1.0, 0.005);
  std::cout << "off-centre: centroid " << b->spectrum_centre_cycles_per_px.range << ", "
            << b->spectrum_centre_cycles_per_px.azimuth << "; peak difference "
            << b->peak_px.range - a->peak_px.range << ", " << b->peak_px.azimuth - a->peak_px.azimuth
            << " px; PSLR " << b->pslr_db.range << ", " << b->pslr_db.azimuth << " dB\n";
}

// InterpolateComplex (the quad-pol channels of `gissar pta` are read at the
// co-pol peak with it): on an off-centre sinc it gives the value of the
// continuous response at any sub-pixel position (to 2e-4 of the peak), and
// at the measured peak the upsampled peak value; the cuts for plots are 0 dB at the peak, and
// their main lobes are null to null.
TEST(PointTargetTest, InterpolateComplexAndCuts) {
  Target target;
  target.centre_range = 0.23;
  target.centre_azimuth = -0.31;
  target.phase = 0.4;
  const auto slc = Synthesise(64, 64, target);
  std::string why;
  const auto m = MeasurePointTarget(slc, 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(m) << why;
  const auto at_peak = InterpolateComplex(slc, 64, 64, m->peak_px.range, m->peak_px.azimuth,
                                          m->spectrum_centre_cycles_per_px);
  ASSERT_TRUE(at_peak);
  // The peak value is taken at the upsampled grid's maximum, within 1/64 px
  // of peak_px: the same amplitude, the phase within 2 pi 0.54 / 64 rad.
  EXPECT_NEAR(std::abs(*at_peak), std::abs(m->peak_value), 1e-3);
  EXPECT_NEAR(std::remainder(std::arg(*at_peak) - std::arg(m->peak_value), 2.0 * M_PI), 0.0, 0.06);
  double worst = 0.0;
  for (const auto& [dc, dr] : std::vector<std::pair<double, double>>{{0, 0}, {0.5, 0.25}, {-0.3, 0.7}, {1.1, -0.6}}) {
    const double c = target.col + dc, r = target.row + dr;
    const auto v = InterpolateComplex(slc, 64, 64, c, r, m->spectrum_centre_cycles_per_px);
    ASSERT_TRUE(v);
    const std::complex<double> truth =
        std::polar(Response(dc, target.band_range, false) * Response(dr, target.band_azimuth, false),
                   target.phase + 2.0 * M_PI * (target.centre_range * c + target.centre_azimuth * r));
    worst = std::max(worst, std::abs(*v - truth));
  }
  EXPECT_LT(worst, 0.01);  // the chip's periodic wrap of the sinc tails
  EXPECT_FALSE(InterpolateComplex(slc, 64, 64, 3.0, 32.0, {}));  // the chip leaves the image
  EXPECT_THROW(InterpolateComplex(slc, 64, 63, 32.0, 32.0, {}), InputError);
  for (const PointTargetCut* cut : {&m->range_cut, &m->azimuth_cut}) {
    ASSERT_EQ(cut->power_db.size(), size_t(31 * 32 + 1));
    EXPECT_DOUBLE_EQ(cut->step_px, 1.0 / 32);
    EXPECT_LE(*std::max_element(cut->power_db.begin(), cut->power_db.end()), 1e-12);
    EXPECT_LT(cut->null_first_px, cut->null_last_px);
  }
  EXPECT_DOUBLE_EQ(m->range_cut.first_px, 16.0);
  EXPECT_NEAR(m->range_cut.null_last_px - m->range_cut.null_first_px, m->main_lobe_px.range, 1e-9);
  EXPECT_NEAR(0.5 * (m->azimuth_cut.null_first_px + m->azimuth_cut.null_last_px), target.row, 0.1);
  std::cout << "InterpolateComplex: worst error " << worst << " of a unit peak\n";
}

// The picture of `gissar pta`: one row of two panels per target.
TEST(PointTargetTest, IrfPlotDrawsTwoPanelsPerTarget) {
  const Target target;
  std::string why;
  const auto m = MeasurePointTarget(Synthesise(64, 64, target), 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(m) << why;
  const RgbImage one = IrfPlot({{"row 1", *m, 1.5, 2.0}});
  const RgbImage two = IrfPlot({{"row 1", *m, 1.5, 2.0}, {"row 2", *m, 1.5, 2.0}});
  EXPECT_EQ(two.width, one.width);
  EXPECT_EQ(two.height, 2 * one.height - 8);
  ASSERT_EQ(one.rgb.size(), size_t(one.width) * one.height * 3);
  size_t blue = 0;  // the curves (anti-aliased)
  for (size_t i = 0; i < one.rgb.size(); i += 3) blue += one.rgb[i + 2] > one.rgb[i] + 80;
  EXPECT_GT(blue, 200u);
  const RgbImage none = IrfPlot({});
  EXPECT_GT(none.width, 0);
  EXPECT_LT(none.height, one.height);
}

// Samples of a band-limited g(x) = sinc^2(B x) (band |f| < B <= 1) sum to
// its integral, 1 / B (Poisson: sum_n g(n - x0) = sum_k G(k) e^(-2 pi i k
// x0) with G(k) = 0 for every k != 0). So a sinc of amplitude A has
// sum |s|^2 = A^2 / (B_range B_azimuth): the samples per 1/B in range times
// those in azimuth, and RCS = A^2 dr da / (B_range B_azimuth).
TEST(PointTargetTest, IntegratedEnergyGivesTheRcs) {
  Target target;
  target.col = 128.37;
  target.row = 127.79;
  target.amplitude = 3.0;
  const auto slc = Synthesise(256, 256, target);
  const double expected_m2 = 9.0 * 1.5 * 2.0 / (kBandRange * kBandAzimuth);  // 65.0 m^2
  const double expected_dbsm = 10.0 * std::log10(expected_m2);                // 18.13 dBsm
  // A 193 x 193 box misses 1 / (pi^2 B 96.5) of the sidelobe energy per
  // axis: 0.15 % + 0.17 % = -0.014 dB.
  PointTargetOptions options = Options();
  options.integration_half_size_px = 96;
  std::string why;
  const auto wide = MeasurePointTarget(slc, 256, 256, 128.0, 128.0, options, &why);
  ASSERT_TRUE(wide) << why;
  EXPECT_NEAR(wide->rcs_dbsm, expected_dbsm, 0.05);
  EXPECT_NEAR(wide->rcs_m2, wide->energy * 3.0, 1e-9);
  // The default 33 x 33 box misses 0.90 % + 1.00 % = -0.083 dB.
  const auto chip = MeasurePointTarget(slc, 256, 256, 128.0, 128.0, Options(), &why);
  ASSERT_TRUE(chip) << why;
  const double loss_db = 10.0 * std::log10((1.0 - 1.0 / (M_PI * M_PI * kBandRange * 16.5)) *
                                           (1.0 - 1.0 / (M_PI * M_PI * kBandAzimuth * 16.5)));
  EXPECT_NEAR(chip->rcs_dbsm - expected_dbsm, loss_db, 0.03);
  // A calibration factor of 2 adds 3.01 dB and is reported.
  options.beta0_calibration = 2.0;
  const auto calibrated = MeasurePointTarget(slc, 256, 256, 128.0, 128.0, options, &why);
  ASSERT_TRUE(calibrated) << why;
  EXPECT_TRUE(calibrated->calibrated);
  EXPECT_NEAR(calibrated->rcs_dbsm - wide->rcs_dbsm, 10.0 * std::log10(2.0), 1e-9);
  EXPECT_NEAR(calibrated->peak_beta0_db, 10.0 * std::log10(2.0 * 9.0), 0.05);
  std::cout << "energy: wide box " << wide->rcs_dbsm - expected_dbsm << " dB, default box "
            << chip->rcs_dbsm - expected_dbsm << " dB (predicted " << loss_db << ")\n";
}

// Complex Gaussian clutter with SCR = peak / mean clutter power = 30 dB.
TEST(PointTargetTest, RcsInClutter) {
  Target target;
  const double expected_dbsm = 10.0 * std::log10(1.5 * 2.0 / (kBandRange * kBandAzimuth));
  auto slc = Synthesise(64, 64, target);
  AddClutter(slc, 1e-3, 20240611);
  std::string why;
  const auto m = MeasurePointTarget(slc, 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(m) << why;
  EXPECT_NEAR(m->rcs_dbsm, expected_dbsm, 0.3);
  EXPECT_NEAR(m->scr_db, 30.0, 1.5);
  EXPECT_NEAR(m->peak_px.range, target.col, 0.05);
  EXPECT_NEAR(m->peak_px.azimuth, target.row, 0.05);
  std::cout << "clutter: RCS error " << m->rcs_dbsm - expected_dbsm << " dB, SCR " << m->scr_db
            << " dB, location error " << m->peak_px.range - target.col << ", " << m->peak_px.azimuth - target.row
            << " px, PSLR " << m->pslr_db.range << ", " << m->pslr_db.azimuth << " dB\n";
}

// Not a lucky seed: over 12 clutter realisations (SCR 30 dB) the RCS error
// has the box's truncation bias (-0.083 dB, above) as mean and a spread set
// by the clutter: the target-clutter cross term (std sqrt(2 E c) for energy
// E = 2.4 and clutter power c = 1e-3: 0.069, 2.9 % of E) and the background
// estimate from 256 corner samples (1089 c / 16 = 0.068, 2.8 %), with the
// box's own clutter sum (1.4 %): about 4.3 % = 0.18 dB rms.
TEST(PointTargetTest, RcsInClutterOverSeeds) {
  const double expected_dbsm = 10.0 * std::log10(1.5 * 2.0 / (kBandRange * kBandAzimuth));
  double sum = 0.0, sum2 = 0.0, worst = 0.0;
  const int runs = 12;
  for (int seed = 1; seed <= runs; ++seed) {
    auto slc = Synthesise(64, 64, Target());
    AddClutter(slc, 1e-3, seed);
    std::string why;
    const auto m = MeasurePointTarget(slc, 64, 64, 32.0, 32.0, Options(), &why);
    ASSERT_TRUE(m) << why;
    const double e = m->rcs_dbsm - expected_dbsm;
    sum += e;
    sum2 += e * e;
    worst = std::max(worst, std::abs(e));
  }
  std::cout << "clutter over " << runs << " seeds: mean " << sum / runs << " dB, rms " << std::sqrt(sum2 / runs)
            << " dB, worst " << worst << " dB\n";
  EXPECT_NEAR(sum / runs, -0.083, 0.15);
  EXPECT_LT(std::sqrt(sum2 / runs), 0.25);
}

TEST(PointTargetTest, ExpectedFailuresGiveAReason) {
  std::string why;
  // Near the edge: the 32 x 32 chip around column 5 leaves the image.
  Target edge;
  edge.col = 5.2;
  EXPECT_FALSE(MeasurePointTarget(Synthesise(64, 64, edge), 64, 64, 5.0, 32.0, Options(), &why));
  EXPECT_NE(why.find("edge"), std::string::npos) << why;
  // A prediction whose search circle holds no sample.
  why.clear();
  EXPECT_FALSE(MeasurePointTarget(Synthesise(64, 64, Target()), 64, 64, 100.0, 32.0, Options(), &why));
  EXPECT_NE(why.find("no image sample"), std::string::npos) << why;
  // A uniform image: nothing above the background.
  why.clear();
  const std::vector<std::complex<float>> flat(64 * 64, {1.0f, 0.0f});
  EXPECT_FALSE(MeasurePointTarget(flat, 64, 64, 32.0, 32.0, Options(), &why));
  EXPECT_NE(why.find("no target"), std::string::npos) << why;
  // Clutter only.
  why.clear();
  std::vector<std::complex<float>> clutter(64 * 64);
  AddClutter(clutter, 1.0, 7);
  EXPECT_FALSE(MeasurePointTarget(clutter, 64, 64, 32.0, 32.0, Options(), &why));
  EXPECT_FALSE(why.empty());
  // The target 12 px from the prediction with an 8 px search radius: the
  // search finds its sidelobes, never a peak.
  why.clear();
  EXPECT_FALSE(MeasurePointTarget(Synthesise(64, 64, Target()), 64, 64, 44.0, 32.0, Options(), &why));
  EXPECT_FALSE(why.empty());
  std::cout << "outside the search radius: " << why << "\n";
}

TEST(PointTargetTest, BadOptionsAndInputThrow) {
  const auto slc = Synthesise(64, 64, Target());
  auto where = [&](PointTargetOptions options) -> std::string {
    try {
      MeasurePointTarget(slc, 64, 64, 32.0, 32.0, options);
    } catch (const ConfigError& e) {
      return e.where();
    }
    return "";
  };
  PointTargetOptions options = Options();
  options.upsampling = 1;
  EXPECT_EQ(where(options), "upsampling");
  options = Options();
  options.range_spacing_m = 0.0;
  EXPECT_EQ(where(options), "range_spacing_m");
  options = Options();
  options.azimuth_spacing_m = -2.0;
  EXPECT_EQ(where(options), "azimuth_spacing_m");
  EXPECT_EQ(where(PointTargetOptions()), "range_spacing_m");  // spacings have no default
  options = Options();
  options.beta0_calibration = 0.0;
  EXPECT_EQ(where(options), "beta0_calibration");
  options = Options();
  options.chip_half_size_px = 2;
  EXPECT_EQ(where(options), "chip_half_size_px");
  EXPECT_THROW(MeasurePointTarget(slc, 64, 63, 32.0, 32.0, Options()), InputError);
  EXPECT_THROW(MeasurePointTarget(slc, 64, 64, NAN, 32.0, Options()), InputError);
  auto bad = slc;
  bad[size_t(40) * 64 + 30] = {NAN, 0.0f};
  EXPECT_THROW(MeasurePointTarget(bad, 64, 64, 32.0, 32.0, Options()), InputError);
}

TEST(PointTargetTest, JsonHasTheCommandKeys) {
  std::string why;
  const auto m = MeasurePointTarget(Synthesise(64, 64, Target()), 64, 64, 32.0, 32.0, Options(), &why);
  ASSERT_TRUE(m) << why;
  const nlohmann::json json = ToJson(*m);
  for (const char* key : {"predicted_px", "peak_px", "location_error_px", "location_error_m", "resolution_m",
                          "pslr_db", "islr_db"}) {
    ASSERT_TRUE(json.contains(key)) << key;
    EXPECT_EQ(json[key].size(), 2u) << key;
    EXPECT_TRUE(json[key]["range"].is_number()) << key;
    EXPECT_TRUE(json[key]["azimuth"].is_number()) << key;
  }
  ASSERT_TRUE(json.contains("rcs_dbsm"));
  EXPECT_TRUE(json["rcs_dbsm"].is_number());
  EXPECT_EQ(json.size(), 8u);
  EXPECT_DOUBLE_EQ(json["predicted_px"]["range"].get<double>(), 32.0);
  EXPECT_DOUBLE_EQ(json["pslr_db"]["azimuth"].get<double>(), m->pslr_db.azimuth);
  EXPECT_DOUBLE_EQ(json["resolution_m"]["range"].get<double>(), m->resolution_m.range);
}

}  // namespace
}  // namespace gissar::image
