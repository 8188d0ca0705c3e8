// The thin-plate spline's vectorised kernel sums (thin_plate_spline.cc), in
// both vector widths, for tests: ThinPlateSpline picks one at run time, so a
// machine tests only the one it runs unless both are called directly.
#pragma once

#include <cstddef>

namespace gissar::geo::internal {

// sums[0] = sum_j c0s[j] phi(|q - p_j|^2), sums[1] the same with c1s, over
// the `count` nodes p_j = (xs[j], ys[j]) (count a multiple of 8), where
// phi(d) = d ln d (0 at d = 0) and q = (qx, qy). Four lanes at a time (the
// AVX2 + FMA or the x86-64 baseline build, as the CPU runs).
void KernelSums4(const double* xs, const double* ys, const double* c0s, const double* c1s, size_t count,
                 double qx, double qy, double* sums);
// The same eight lanes at a time; only on a CPU with AVX-512 (HasAvx512()),
// anything else faults with an illegal instruction.
void KernelSums8(const double* xs, const double* ys, const double* c0s, const double* c1s, size_t count,
                 double qx, double qy, double* sums);
// Whether the CPU runs AVX-512F.
bool HasAvx512();

}  // namespace gissar::geo::internal
