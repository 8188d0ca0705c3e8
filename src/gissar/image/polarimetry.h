// Polarimetric decomposition of a quad-pol SLC (docs/radiometry.md,
// "Polarimetric decomposition"): the multilooked covariance C3 or coherency
// T3, the Cloude-Pottier entropy / anisotropy / mean alpha, and the Pauli
// RGB quicklook. The core of a future `gissar polsar` command; nothing here
// reads or writes files.
//
// Conventions (those of material/scattering.h, which this module reuses):
//  - Channels HH, HV, VH, VV, first letter transmit; S = [[S_HH, S_HV],
//    [S_VH, S_VV]], backscatter alignment (BSA).
//  - The data's two cross-polarised channels are symmetrised: S_X =
//    (S_HV + S_VH) / 2 (= S_HV under reciprocity). Pauli vector
//    k = (S_HH + S_VV, S_HH - S_VV, S_HV + S_VH) / sqrt 2 (= 2 S_HV / sqrt 2
//    when S_HV = S_VH); lexicographic vector k_L = (S_HH, sqrt 2 S_X, S_VV).
//    The antisymmetric part (S_HV - S_VH) / sqrt 2, zero for a monostatic
//    return, is dropped.
//  - C3 = <k_L k_L^H>, T3 = <k k^H>, <.> the boxcar average; element ij =
//    <a_i a_j*> (so C13 = <S_HH S_VV*>). T3 = U C3 U^H with the real
//    orthogonal U of LexicographicToPauli().
//  - Images are row-major, row = azimuth line (top first), column = range
//    sample; `width` columns, `height` rows.
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/image/class_map.h"
#include "gissar/util/enum_table.h"

namespace gissar::image {

// The four complex channels of one SLC on a common grid, each width x height
// samples, row-major. Non-finite samples are data gaps: they propagate as NaN.
struct QuadPolImage {
  int width = 0;
  int height = 0;
  std::vector<std::complex<float>> hh, hv, vh, vv;

  // Throws InputError for width or height < 1 (where "width" / "height") or
  // a channel whose size is not width x height (where "hh", "hv", "vh" or
  // "vv").
  void Check() const;
};

enum class PolarimetricMatrix { kCovariance, kCoherency };
// The names of `polsar --matrix` and its options key "matrix".
inline constexpr auto kPolarimetricMatrices = util::MakeEnumTable<PolarimetricMatrix>(
    "matrix", {{PolarimetricMatrix::kCovariance, "covariance"}, {PolarimetricMatrix::kCoherency, "coherency"}});

// Number of real bands of a 3 x 3 Hermitian matrix image.
inline constexpr int kPolarimetricBandCount = 9;

// A multilooked 3 x 3 Hermitian matrix per output pixel, stored as nine
// float32 planes in the band order of PolarimetricBandNames: 11, 22, 33
// (real, >= 0), then 12, 13, 23 as (real, imaginary) pairs. Units: those of
// |S|^2 of the input (the image's phasor units).
struct PolarimetricMatrixImage {
  PolarimetricMatrix kind = PolarimetricMatrix::kCoherency;
  int width = 0;   // floor(input width / looks_range)
  int height = 0;  // floor(input height / looks_azimuth)
  int looks_range = 1;
  int looks_azimuth = 1;
  std::array<std::vector<float>, kPolarimetricBandCount> bands;

  // The full Hermitian matrix of pixel (row, col) (NaN entries where the
  // block had a non-finite sample). CHECKs the indices.
  Eigen::Matrix3cd At(int row, int col) const;
};

// Band names in storage order, prefixed by the kind: "C11", "C22", "C33",
// "C12_real", "C12_imag", "C13_real", "C13_imag", "C23_real", "C23_imag"
// (T.. for the coherency). For float32 GeoTIFF band descriptions.
std::vector<std::string> PolarimetricBandNames(PolarimetricMatrix kind);

// U with k = U k_L: (1/sqrt 2) [[1, 0, 1], [1, 0, -1], [0, sqrt 2, 0]];
// T3 = U C3 U^T, C3 = U^T T3 U (U is real orthogonal, hence unitary).
Eigen::Matrix3d LexicographicToPauli();

// Boxcar (non-overlapping block) averages of k_L k_L^H (covariance) or
// k k^H (coherency) over looks_range columns x looks_azimuth rows. Output
// floor(W / looks_range) x floor(H / looks_azimuth); partial blocks at the
// right and bottom are dropped. Output pixel (r, c) is the block of input
// rows [r la, (r + 1) la) and columns [c lr, (c + 1) lr); its centre is the
// input position (row r la + (la - 1) / 2, column c lr + (lr - 1) / 2),
// exact (a half-integer for even looks), the grid of image::Multilook.
// Averaged in double, stored in float. A block with any non-finite sample
// in any channel is NaN in all nine bands (unlike Multilook, gaps are not
// skipped: a partial average would bias the matrix's structure).
// Throws InputError from image.Check(); ConfigError for a look count < 1
// (where "looks_range" / "looks_azimuth") or larger than the image's width /
// height (the output would be empty).
PolarimetricMatrixImage MultilookCovariance(const QuadPolImage& image, int looks_range, int looks_azimuth);
PolarimetricMatrixImage MultilookCoherency(const QuadPolImage& image, int looks_range, int looks_azimuth);
PolarimetricMatrixImage MultilookPolarimetricMatrix(const QuadPolImage& image, PolarimetricMatrix kind,
                                                    int looks_range, int looks_azimuth);

// The image converted to the other representation (T3 = U C3 U^T or back),
// pixel by pixel; NaN stays NaN. Returns a copy when `kind` is already the
// image's.
PolarimetricMatrixImage ConvertPolarimetricMatrix(const PolarimetricMatrixImage& image, PolarimetricMatrix kind);

// Relative size of lambda_2 + lambda_3 below which T3 is treated as rank 1
// (a pure target within the float precision of a stored T3): anisotropy 0.
inline constexpr double kRankOneTolerance = 1e-6;

// Cloude-Pottier eigen-decomposition of one coherency matrix T3 (Hermitian;
// only its lower triangle is read, as by Eigen's SelfAdjointEigenSolver):
//  - eigenvalues lambda_1 >= lambda_2 >= lambda_3, negative round-off
//    clipped to 0; p_i = lambda_i / sum lambda;
//  - entropy H = -sum p_i log_3 p_i in [0, 1] (0 log 0 = 0): 0 for a pure
//    target (rank 1), 1 for T3 proportional to I;
//  - anisotropy A = (lambda_2 - lambda_3) / (lambda_2 + lambda_3) in [0, 1];
//    defined as 0 when lambda_2 + lambda_3 <= kRankOneTolerance * sum lambda
//    (rank 1: A is 0/0 there);
//  - alpha_i = acos |e_i1| (e_i the unit eigenvector of lambda_i, e_i1 its
//    first, surface-like Pauli component), mean alpha = sum p_i alpha_i,
//    degrees in [0, 90]: 0 for a trihedral, 90 for a dihedral at any roll.
// All NaN when T3 has a non-finite entry or sum lambda <= 0 (all-zero
// pixel). With a degenerate eigenvalue the eigenvectors within its space are
// arbitrary, and so are their alpha_i; for T3 proportional to I mean alpha
// is not defined (the limit of diag(1, m, m), m -> 1, is 60 deg; a sampled
// isotropic T3 has random eigenvectors and mean alpha averages 56.25 deg).
struct CloudePottierParameters {
  double entropy = 0.0;
  double anisotropy = 0.0;
  double alpha_deg = 0.0;
  std::array<double, 3> eigenvalues{};  // descending, T3's units
  std::array<double, 3> alpha_i_deg{};  // alpha of each eigenvector, same order
};
CloudePottierParameters CloudePottier(const Eigen::Matrix3cd& t3);

// Per-pixel entropy, anisotropy and mean alpha (deg) planes, on the grid of
// the matrix image (a covariance image is converted to T3 first). NaN where
// CloudePottier gives NaN.
struct CloudePottierImage {
  int width = 0;
  int height = 0;
  std::vector<float> entropy;
  std::vector<float> anisotropy;
  std::vector<float> alpha_deg;
};
CloudePottierImage CloudePottierPlanes(const PolarimetricMatrixImage& image);
// Band names of CloudePottierImage in the order above: "entropy",
// "anisotropy", "alpha_deg".
std::vector<std::string> CloudePottierBandNames();

// The dB stretch of a Pauli RGB, common to the three channels: a channel's
// power P (|k_i|^2, or T_ii when multilooked) maps to 8-bit
// 1 + 254 clamp((10 log10 P - low_db) / (high_db - low_db), 0, 1); P <= 0
// or not finite maps to 0. 10 log10 P = 20 log10 of the channel amplitude
// |S_HH - S_VV| / sqrt 2 (R), |S_HV + S_VH| / sqrt 2 (G), |S_HH + S_VV| /
// sqrt 2 (B). Units dB of the input's |S|^2.
struct PauliStretch {
  double low_db = 0.0;   // maps to 1
  double high_db = 0.0;  // maps to 255
};

// Pauli RGB of a single-look image (R = |k_2|, G = |k_3|, B = |k_1|): the
// stretch runs from the `low_percentile` to the `high_percentile` (in
// [0, 100], low < high; defaults 2 and 98) of the pooled dB values of all
// three channels' positive powers (one scale, so colours compare across
// channels). When the two percentiles coincide (e.g. a uniform image), low
// is set 1 dB below high, so that the common value maps to 255. No positive
// power anywhere: all black, stretch {0, 0}. A pixel with a non-finite
// sample in any channel is black. Only an exactly zero power is black: a
// round-off residue (1e-32) is a positive power the percentiles include. `stretch` (if not null) receives the
// stretch used, for the product's metadata. Throws InputError from
// image.Check(); ConfigError for bad percentiles (where "low_percentile" /
// "high_percentile").
RgbImage PauliRgb(const QuadPolImage& image, PauliStretch* stretch = nullptr, double low_percentile = 2.0,
                  double high_percentile = 98.0);
// The same from a multilooked matrix image: powers T11 (B), T22 (R), T33
// (G) (a covariance image converted first); black where NaN.
RgbImage PauliRgb(const PolarimetricMatrixImage& image, PauliStretch* stretch = nullptr,
                  double low_percentile = 2.0, double high_percentile = 98.0);
// With a given stretch (e.g. shared by several images); throws ConfigError
// for a stretch with high_db <= low_db or non-finite (where "stretch").
RgbImage PauliRgbWithStretch(const QuadPolImage& image, const PauliStretch& stretch);
RgbImage PauliRgbWithStretch(const PolarimetricMatrixImage& image, const PauliStretch& stretch);

}  // namespace gissar::image
