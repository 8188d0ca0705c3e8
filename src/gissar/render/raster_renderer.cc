#include "gissar/render/raster_renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "gissar/util/check.h"
#include "gissar/util/progress.h"

namespace gissar::render {
namespace {

// Internal flag of the mask: a surface covers the pixel centre (split into
// SarImage::footprint at the end).
constexpr uint8_t kCoveredFlag = 16;

// Horizon of an azimuth line that has not met the terrain yet.
constexpr float kNoHorizon = -1e30f;
// Image rows rendered by one task. Each task renders every cell that
// reaches its rows and writes only its rows, so tasks never share a pixel.
constexpr int kChunkRows = 128;
// Triangles wider than this (pixels, along range or azimuth) are split into
// sub-triangles for the intensity splat (each sampled at its three edge
// midpoints).
constexpr float kSampleSpacingPx = 1.5f;
// Partly shadowed triangles are split at least this many times per side, so
// that their lit share follows the shadow edge.
constexpr int kPartialSubdivision = 8;
// Horizon lines per post spacing across the sweep (at least; they are
// also aligned with the image rows, see Context::lines_per_row).
constexpr float kLinesPerPost = 2.0f;

// The DEM grid walked as (s, t): s steps along the horizontal look direction
// (ground range increasing), t across it with the along-track coordinate
// increasing. Post (s, t) is posts[base + s * ds + t * dt]; (c, r) =
// (c0 + s * cs + t * ct, r0 + s * rs + t * rt).
struct SweepView {
  int steps = 0, trans = 0;
  bool along_rows = true;  // azimuth lines run along the grid's rows (s = column)
  int c0 = 0, r0 = 0, cs = 0, ct = 0, rs = 0, rt = 0;
  int64_t base = 0, ds = 0, dt = 0;
  // Whether the mesh diagonal of a cell joins corners (s, t) and
  // (s - 1, t + 1) (otherwise (s - 1, t) and (s, t + 1)).
  bool diagonal_bc = true;
  // Orientation of (P1 - P0) x (P2 - P0) of the two triangle types
  // relative to the mesh's upward normals: +1 or -1.
  float sign1 = 1.0f, sign2 = 1.0f;
};

// Everything a task needs, in float relative to the scene centre.
// Single-bounce backscatter of a material: its sigma0 law sampled for the
// wavelength and polarisation (material::Sigma0Table).
using Reflectivity = material::Sigma0Table;

struct Context {
  const Eigen::Vector3f* posts = nullptr;
  int grid_width = 0;
  const scene::ClassId* classes = nullptr;  // per cell (c, r): r * (grid_width - 1) + c
  bool triangle_classes = false;  // classes per triangle: 2 (r * (grid_width - 1) + c) + k
  const Eigen::Vector3f* normals = nullptr;  // per-post shading normals (nullptr: flat)
  std::vector<Reflectivity> materials;  // by class id
  SweepView view;
  bool affine = true;
  Eigen::Vector3f xc, h, l, n, n_up;  // n_up: upward slant-plane normal (affine)
  float up_sign = 1;  // n_up = up_sign * n
  float range0 = 0, inv_dr = 0, inv_da = 0, u0 = 0, v0 = 0, da = 0;
  float power_scale = 0;  // 1 / (dr da): RCS per pixel area (beta0)
  // Horizon line J lies at along-track coordinate line_offset + J *
  // line_spacing (metres); line_offset = -v0 * da puts line J = r *
  // lines_per_row on the centres of image row r, so that the mask, which is
  // evaluated at pixel centres, reads exact horizons (no interpolation).
  float line_spacing = 0;
  float inv_line_spacing = 0;  // 1 / line_spacing
  double line_offset = 0;
  int lines_per_row = 1;
  float cell_span = 0;     // bound on the along-track extent of a cell, metres
  int width = 0, height = 0;
};

// Per-post quantities of one sweep step, for t in [t_lo, t_hi].
struct Step {
  int t_lo = 0, t_hi = -1;
  std::vector<float> x, y, z;  // position relative to Xc
  std::vector<float> a;        // along-track coordinate (metres)
  std::vector<float> xl, xn;   // offsets along l and n
  std::vector<float> e;        // elevation: metres along n (exact: R tan of the angle from l)
  std::vector<float> col, row; // continuous pixel
  std::vector<float> margin;   // e minus the horizon before the post (< 0: shadow)
  std::vector<Eigen::Vector3f> normal;  // shading normal (zero: flat), with ctx.normals
  bool Has(int t) const { return t >= t_lo && t <= t_hi; }
  bool empty() const { return t_hi < t_lo; }
  void Reserve(int n) {
    for (auto* v : {&x, &y, &z, &a, &xl, &xn, &e, &col, &row, &margin}) v->resize(size_t(n));
    normal.resize(size_t(n));
  }
};

inline float AlongTrack(const Context& ctx, int64_t index) {
  const Eigen::Vector3f& p = ctx.posts[index];
  return (p.x() - ctx.xc.x()) * ctx.h.x() + (p.y() - ctx.xc.y()) * ctx.h.y();
}

// Horizon between two lines at fraction f; a line that has not met the
// terrain (beyond the DEM's edge) takes the other's value.
inline float Interpolate(float h0, float h1, float f) {
  if (h0 == kNoHorizon) return h1;
  if (h1 == kNoHorizon) return h0;
  return h0 + f * (h1 - h0);
}

// floor(x) as an int for |x| < 2^31 (without SSE4.1's roundss).
inline int FloorInt(float x) {
  const int i = static_cast<int>(x);
  return i - (x < static_cast<float>(i));
}

// ceil(x) as an int for |x| < 2^31.
inline int CeilInt(float x) { return -FloorInt(-x); }

// Bilinear splat of `value` at (col, row) into rows [row0, row1).
inline void Splat(float* image, int width, int row0, int row1, float col, float row, float value) {
  const int c0 = FloorInt(col), r0 = FloorInt(row);
  const float fc = col - float(c0), fr = row - float(r0);
  const float wr[2] = {1.0f - fr, fr}, wc[2] = {1.0f - fc, fc};
  if (c0 >= 0 && c0 + 1 < width && r0 >= row0 && r0 + 1 < row1) {
    // All four pixels inside (the common case): the loop below unrolled,
    // the same products added in the same order.
    float* p = image + size_t(r0) * width + c0;
    p[0] += value * (wr[0] * wc[0]);
    p[1] += value * (wr[0] * wc[1]);
    p[width] += value * (wr[1] * wc[0]);
    p[width + 1] += value * (wr[1] * wc[1]);
    return;
  }
  for (int dr = 0; dr < 2; ++dr) {
    const int r = r0 + dr;
    if (r < row0 || r >= row1) continue;
    for (int dc = 0; dc < 2; ++dc) {
      const int c = c0 + dc;
      if (c < 0 || c >= width) continue;
      image[size_t(r) * width + c] += value * (wr[dr] * wc[dc]);
    }
  }
}

class ChunkRenderer {
 public:
  ChunkRenderer(const Context& ctx, int row0, int row1, float* intensity, uint8_t* mask)
      : ctx_(ctx), row0_(row0), row1_(row1), intensity_(intensity), mask_(mask) {
    // Cells whose splat reaches rows [row0, row1) have a sample row in
    // (row0 - 1, row1); their posts lie within a cell span of that.
    a_lo_cells_ = (row0 - 1 - ctx.v0) * ctx.da;
    a_hi_cells_ = (row1 - ctx.v0) * ctx.da;
    a_lo_posts_ = a_lo_cells_ - ctx.cell_span;
    a_hi_posts_ = a_hi_cells_ + ctx.cell_span;
    line_first_ = static_cast<int64_t>(std::floor((a_lo_posts_ - ctx.line_offset) / ctx.line_spacing)) - 1;
    const int64_t line_last =
        static_cast<int64_t>(std::ceil((a_hi_posts_ - ctx.line_offset) / ctx.line_spacing)) + 1;
    const int lines = static_cast<int>(line_last - line_first_ + 1);
    horizon_.assign(size_t(lines), kNoHorizon);
    horizon_before_.assign(size_t(lines), kNoHorizon);
    horizon_prev_.assign(size_t(lines), kNoHorizon);
    rho_.assign(size_t(lines), std::numeric_limits<float>::quiet_NaN());
    line_a_.resize(size_t(lines));
    for (int k = 0; k < lines; ++k) {
      line_a_[k] = static_cast<float>(ctx.line_offset + (line_first_ + k) * double(ctx.line_spacing));
    }
  }

  void Run() {
    const SweepView& v = ctx_.view;
    int guess_lo = -1, guess_hi = -1;
    for (int s = 0; s < v.steps; ++s) {
      std::swap(prev_, cur_);
      if (!FindRange(s, guess_lo, guess_hi)) {
        cur_.t_lo = 0;
        cur_.t_hi = -1;
        guess_lo = guess_hi = -1;
        std::fill(rho_.begin(), rho_.end(), std::numeric_limits<float>::quiet_NaN());
        continue;
      }
      ComputePosts(s);
      ComputeMargins();
      // The previous step's horizons move to horizon_prev_ (for this step's
      // cells); UpdateLines rewrites every entry of horizon_before_.
      std::swap(horizon_prev_, horizon_before_);
      UpdateLines();
      if (!prev_.empty()) RenderCells(s);
    }
  }

 private:
  // Range of t at step s whose posts have a in [a_lo_posts, a_hi_posts],
  // widened by one post on each side. False when empty.
  bool FindRange(int s, int& guess_lo, int& guess_hi) {
    const SweepView& v = ctx_.view;
    const int64_t row_base = v.base + int64_t(s) * v.ds;
    auto a_at = [&](int t) { return AlongTrack(ctx_, row_base + int64_t(t) * v.dt); };
    const int T = v.trans;
    if (a_at(T - 1) < a_lo_posts_ || a_at(0) > a_hi_posts_) return false;
    // First t with a >= a_lo (T when none).
    int lo = guess_lo;
    if (lo < 0) {
      int a = 0, b = T;
      while (a < b) {
        const int m = (a + b) / 2;
        if (a_at(m) < a_lo_posts_) a = m + 1; else b = m;
      }
      lo = a;
    } else {
      while (lo > 0 && a_at(lo - 1) >= a_lo_posts_) --lo;
      while (lo < T && a_at(lo) < a_lo_posts_) ++lo;
    }
    // Last t with a <= a_hi (-1 when none).
    int hi = guess_hi;
    if (hi < 0) {
      int a = -1, b = T - 1;
      while (a < b) {
        const int m = (a + b + 1) / 2;
        if (a_at(m) > a_hi_posts_) b = m - 1; else a = m;
      }
      hi = a;
    } else {
      while (hi < T - 1 && a_at(hi + 1) <= a_hi_posts_) ++hi;
      while (hi >= 0 && a_at(hi) > a_hi_posts_) --hi;
    }
    guess_lo = std::max(lo, 0);
    guess_hi = std::max(hi, 0);
    cur_.t_lo = std::max(0, lo - 1);
    cur_.t_hi = std::min(T - 1, hi + 1);
    return cur_.t_hi > cur_.t_lo;
  }

  void ComputePosts(int s) {
    const SweepView& v = ctx_.view;
    const int n = cur_.t_hi - cur_.t_lo + 1;
    if (int(cur_.a.size()) < n) cur_.Reserve(n + 64);
    const Eigen::Vector3f* row = ctx_.posts + v.base + int64_t(s) * v.ds + int64_t(cur_.t_lo) * v.dt;
    const int64_t dt = v.dt;
    const float R = ctx_.range0;
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3f& p = row[k * dt];
      const float x = p.x() - ctx_.xc.x(), y = p.y() - ctx_.xc.y(), z = p.z() - ctx_.xc.z();
      const float a = x * ctx_.h.x() + y * ctx_.h.y();
      const float xl = x * ctx_.l.x() + y * ctx_.l.y() + z * ctx_.l.z();
      const float xn = x * ctx_.n.x() + y * ctx_.n.y() + z * ctx_.n.z();
      float range_offset, e;
      // Elevation: offset along the upward slant-plane normal (exact mode:
      // R times the tangent of the angle above l seen from P(a)).
      if (ctx_.affine) {
        range_offset = xl;
        e = ctx_.up_sign * xn;
      } else {
        // |X - P(a)| - R without cancellation: X - P(a) = (R + xl) l + xn n.
        const float d = R + xl;
        const float r = std::sqrt(d * d + xn * xn);
        range_offset = (xl * (2.0f * R + xl) + xn * xn) / (r + R);
        e = ctx_.up_sign * R * xn / d;
      }
      cur_.x[k] = x;
      cur_.y[k] = y;
      cur_.z[k] = z;
      cur_.a[k] = a;
      cur_.xl[k] = xl;
      cur_.xn[k] = xn;
      cur_.e[k] = e;
      cur_.col[k] = range_offset * ctx_.inv_dr + ctx_.u0;
      cur_.row[k] = a * ctx_.inv_da + ctx_.v0;
      if (ctx_.normals != nullptr) cur_.normal[k] = ctx_.normals[&p - ctx_.posts];
    }
  }

  // Margin of every post: its elevation minus the horizon before it on its
  // azimuth line: the horizon lines around it (terrain before the previous
  // step's column, interpolated), the previous column where its own line
  // crosses it (exact), and the mesh edges its line crosses in between
  // (edges through the post itself excluded: they reach it).
  void ComputeMargins() {
    const int n = cur_.t_hi - cur_.t_lo + 1;
    const float inv_w = ctx_.inv_line_spacing;
    const float first = static_cast<float>(line_first_);
    const float offset = static_cast<float>(ctx_.line_offset);
    const int last_line = static_cast<int>(horizon_.size()) - 2;
    const bool strip = !prev_.empty();
    int j = 0;  // previous-step index with prev.a[j] <= a < prev.a[j + 1]
    const int np = prev_.t_hi - prev_.t_lo + 1;
    for (int k = 0; k < n; ++k) {
      const float A = cur_.a[k];
      if (!std::isfinite(A + cur_.e[k])) {  // a post outside the scene (non-finite height)
        cur_.margin[k] = std::numeric_limits<float>::quiet_NaN();
        continue;
      }
      const float fl = (A - offset) * inv_w - first;
      int line = FloorInt(fl);
      line = std::clamp(line, 0, last_line);
      const float f = std::clamp(fl - float(line), 0.0f, 1.0f);
      const float h0 = horizon_before_[line], h1 = horizon_before_[line + 1];
      float horizon = Interpolate(h0, h1, f);
      if (strip && A >= prev_.a[0] && A < prev_.a[np - 1]) {
        while (j > 0 && prev_.a[j] > A) --j;
        while (prev_.a[j + 1] <= A) ++j;
        const float da = prev_.a[j + 1] - prev_.a[j];
        const float mu = da > 0.0f ? (A - prev_.a[j]) / da : 0.0f;
        horizon = std::max(horizon, prev_.e[j] + mu * (prev_.e[j + 1] - prev_.e[j]));
        const int t = cur_.t_lo + k;
        horizon = StripCrossings(A, float(prev_.t_lo + j) + mu, float(t), horizon, t);
      }
      cur_.margin[k] = cur_.e[k] - horizon;
    }
  }

  // Advances every horizon line to this step: the mesh edges it crossed
  // since the previous step (row edges and diagonals of the cells in
  // between: ridges between the steps) give horizon_before_, then its
  // terrain crossing on the step's own column of posts.
  void UpdateLines() {
    const int n = cur_.t_hi - cur_.t_lo + 1;
    const float a_first = cur_.a[0], a_last = cur_.a[n - 1];
    int k = 0;
    for (size_t line = 0; line < horizon_.size(); ++line) {
      const float A = line_a_[line];
      if (!(A >= a_first && A < a_last)) {
        rho_[line] = std::numeric_limits<float>::quiet_NaN();
        horizon_before_[line] = horizon_[line];
        continue;
      }
      while (cur_.a[k + 1] <= A) ++k;
      const float da = cur_.a[k + 1] - cur_.a[k];
      const float mu = da > 0.0f ? (A - cur_.a[k]) / da : 0.0f;
      const float rho = float(cur_.t_lo + k) + mu;
      float before = horizon_[line];
      if (!prev_.empty() && !std::isnan(rho_[line])) before = StripCrossings(A, rho_[line], rho, before);
      horizon_before_[line] = before;
      horizon_[line] = std::max(before, cur_.e[k] + mu * (cur_.e[k + 1] - cur_.e[k]));
      rho_[line] = rho;
    }
  }

  // Highest elevation where the line of along-track coordinate A crosses a
  // row edge or a diagonal of the cells between the previous and the
  // current step (between transverse positions rho1 and rho2), or `best`.
  // Edges ending at the current step's post `skip_t` are left out.
  float StripCrossings(float A, float rho1, float rho2, float best, int skip_t = -1) const {
    // Cells whose four corners both steps hold.
    const int t_a = std::max(FloorInt(std::min(rho1, rho2)), std::max(prev_.t_lo, cur_.t_lo));
    const int t_b = std::min(FloorInt(std::max(rho1, rho2)), std::min(prev_.t_hi, cur_.t_hi) - 1);
    for (int t = t_a; t <= t_b; ++t) {
      const int p0 = t - prev_.t_lo, c0 = t - cur_.t_lo;
      // Corners: A=(prev, t) C=(prev, t+1) B=(cur, t) D=(cur, t+1).
      const float ea = prev_.e[p0], ec = prev_.e[p0 + 1], eb = cur_.e[c0], ed = cur_.e[c0 + 1];
      if (std::max(std::max(ea, ec), std::max(eb, ed)) <= best) continue;
      const float aa = prev_.a[p0], ac = prev_.a[p0 + 1], ab = cur_.a[c0], ad = cur_.a[c0 + 1];
      auto cross = [&](float a1, float e1, float a2, float e2) {
        if ((A - a1) * (A - a2) > 0.0f || a1 == a2) return;
        best = std::max(best, e1 + (A - a1) / (a2 - a1) * (e2 - e1));
      };
      const bool skip_b = t == skip_t, skip_d = t + 1 == skip_t;
      if (!skip_b) cross(aa, ea, ab, eb);
      if (!skip_d) cross(ac, ec, ad, ed);
      if (ctx_.view.diagonal_bc) {
        if (!skip_b) cross(ab, eb, ac, ec);
      } else {
        if (!skip_d) cross(aa, ea, ad, ed);
      }
    }
    return best;
  }

  // Margin of a point of the cell (s - 1, s) x (t, t + 1) at along-track
  // A, elevation e and fraction u of the way from the previous to the
  // current step: the horizon lines before the previous column
  // (interpolated), the previous column where its line crosses it and the
  // mesh edges its line crosses between that column and the point (exact).
  // A point at the centre of image row `row` (>= 0) reads the horizon line
  // of that row itself, without interpolation.
  float PointMargin(float A, float e, float u, int t, int row = -1) const {
    float horizon;
    const int64_t row_line = int64_t(row) * ctx_.lines_per_row - line_first_;
    if (row >= 0 && row_line >= 0 && row_line < int64_t(horizon_prev_.size())) {
      horizon = horizon_prev_[size_t(row_line)];
    } else {
      const float fl = (A - static_cast<float>(ctx_.line_offset)) * ctx_.inv_line_spacing - float(line_first_);
      const int line = std::clamp(FloorInt(fl), 0, int(horizon_prev_.size()) - 2);
      const float f = std::clamp(fl - float(line), 0.0f, 1.0f);
      horizon = Interpolate(horizon_prev_[line], horizon_prev_[line + 1], f);
    }
    const int np = prev_.t_hi - prev_.t_lo + 1;
    if (!(A >= prev_.a[0] && A < prev_.a[np - 1])) return e - horizon;
    int j = std::clamp(t - prev_.t_lo, 0, np - 2);
    while (j > 0 && prev_.a[j] > A) --j;
    while (prev_.a[j + 1] <= A) ++j;
    const float da = prev_.a[j + 1] - prev_.a[j];
    const float mu = da > 0.0f ? (A - prev_.a[j]) / da : 0.0f;
    horizon = std::max(horizon, prev_.e[j] + mu * (prev_.e[j + 1] - prev_.e[j]));
    const int t_entry = prev_.t_lo + j;
    for (int tc = std::min(t_entry, t); tc <= std::max(t_entry, t); ++tc) {
      if (!prev_.Has(tc) || !prev_.Has(tc + 1) || !cur_.Has(tc) || !cur_.Has(tc + 1)) continue;
      const int p0 = tc - prev_.t_lo, c0 = tc - cur_.t_lo;
      const float ea = prev_.e[p0], ec = prev_.e[p0 + 1], eb = cur_.e[c0], ed = cur_.e[c0 + 1];
      const float aa = prev_.a[p0], ac = prev_.a[p0 + 1], ab = cur_.a[c0], ad = cur_.a[c0 + 1];
      // Crossing of edge (1 -> 2) with u running from u1 to u2; only
      // crossings before the point (smaller u: the line runs monotonically
      // from the previous to the current step) count.
      auto cross = [&](float a1, float e1, float u1, float a2, float e2, float u2) {
        if ((A - a1) * (A - a2) > 0.0f || a1 == a2) return;
        const float m = (A - a1) / (a2 - a1);
        if (u1 + m * (u2 - u1) >= u) return;
        horizon = std::max(horizon, e1 + m * (e2 - e1));
      };
      cross(aa, ea, 0.0f, ab, eb, 1.0f);
      cross(ac, ec, 0.0f, ad, ed, 1.0f);
      if (ctx_.view.diagonal_bc) {
        cross(ab, eb, 1.0f, ac, ec, 0.0f);
      } else {
        cross(aa, ea, 0.0f, ad, ed, 1.0f);
      }
    }
    return e - horizon;
  }

  struct Vertex {
    const Step* step;
    int k;
  };

  void RenderCells(int s) {
    const int t_lo = std::max(prev_.t_lo, cur_.t_lo);
    const int t_hi = std::min(prev_.t_hi, cur_.t_hi) - 1;
    const SweepView& v = ctx_.view;
    for (int t = t_lo; t <= t_hi; ++t) {
      const Vertex A{&prev_, t - prev_.t_lo}, C{&prev_, t + 1 - prev_.t_lo};
      const Vertex B{&cur_, t - cur_.t_lo}, D{&cur_, t + 1 - cur_.t_lo};
      const float amin = std::min(std::min(A.step->a[A.k], C.step->a[C.k]), std::min(B.step->a[B.k], D.step->a[D.k]));
      const float amax = std::max(std::max(A.step->a[A.k], C.step->a[C.k]), std::max(B.step->a[B.k], D.step->a[D.k]));
      if (amax <= a_lo_cells_ || amin >= a_hi_cells_) continue;
      // A cell with a non-finite post (outside the scene: a DEM's collar) is
      // a hole: no return, no mask, no horizon of its own.
      if (!std::isfinite(A.step->e[A.k] + B.step->e[B.k] + C.step->e[C.k] + D.step->e[D.k])) continue;
      // Materials of the cell's two triangles: the first one rendered below
      // is (A, B, C) or (A, B, D), the second (B, D, C) or (A, D, C).
      const Reflectivity* m1 = &ctx_.materials[0];
      const Reflectivity* m2 = m1;
      if (ctx_.classes != nullptr) {
        // The cell's lowest (c, r) corner.
        const int c = std::min(v.c0 + (s - 1) * v.cs, v.c0 + s * v.cs) + std::min(t * v.ct, (t + 1) * v.ct);
        const int r = std::min(v.r0 + (s - 1) * v.rs, v.r0 + s * v.rs) + std::min(t * v.rt, (t + 1) * v.rt);
        const size_t cell = size_t(r) * (ctx_.grid_width - 1) + c;
        auto material_of = [&](scene::ClassId id) { return &ctx_.materials[id < ctx_.materials.size() ? id : 0]; };
        if (!ctx_.triangle_classes) {
          m1 = m2 = material_of(ctx_.classes[cell]);
        } else {
          // MeshFromGrid's triangle 0 holds post (c, r), triangle 1 post
          // (c + 1, r + 1): the corners off the diagonal. Which of the two is
          // the first triangle's corner off the diagonal decides.
          auto post_of = [&](int ss, int tt) {
            return std::array<int, 2>{v.c0 + ss * v.cs + tt * v.ct, v.r0 + ss * v.rs + tt * v.rt};
          };
          const std::array<int, 2> low{c, r};
          // The first triangle's corner off the diagonal: A for a (B, C)
          // diagonal, B for an (A, D) diagonal.
          const std::array<int, 2> off = v.diagonal_bc ? post_of(s - 1, t) : post_of(s, t);
          const bool first_holds_low = off == low;
          m1 = material_of(ctx_.classes[2 * cell + (first_holds_low ? 0 : 1)]);
          m2 = material_of(ctx_.classes[2 * cell + (first_holds_low ? 1 : 0)]);
        }
      }
      cell_t_ = t;
      if (v.diagonal_bc) {
        Triangle(A, B, C, v.sign1, *m1);
        Triangle(B, D, C, v.sign2, *m2);
      } else {
        Triangle(A, B, D, v.sign1, *m1);
        Triangle(A, D, C, v.sign2, *m2);
      }
    }
  }

  // Bilinear splat of `value` at (col, row).
  void Deposit(float col, float row, float value) {
    Splat(intensity_, ctx_.width, row0_, row1_, col, row, value);
  }

  [[gnu::always_inline]] inline void Triangle(const Vertex& v0, const Vertex& v1, const Vertex& v2,
                                              float sign, const Reflectivity& material) {
    const Step &s0 = *v0.step, &s1 = *v1.step, &s2 = *v2.step;
    const int k0 = v0.k, k1 = v1.k, k2 = v2.k;
    const Eigen::Vector3f p0(s0.x[k0], s0.y[k0], s0.z[k0]);
    const Eigen::Vector3f e1 = Eigen::Vector3f(s1.x[k1], s1.y[k1], s1.z[k1]) - p0;
    const Eigen::Vector3f e2 = Eigen::Vector3f(s2.x[k2], s2.y[k2], s2.z[k2]) - p0;
    // The normal and (exact geometry) the look direction are left at their
    // lengths: cos_in divides once by both (one division per triangle
    // instead of a normalisation each).
    const Eigen::Vector3f normal = sign * e1.cross(e2);
    const float twice_area = normal.norm();
    if (!(twice_area > 0.0f)) return;
    Eigen::Vector3f dir = ctx_.l, n_up = ctx_.n_up;  // dir: unit (affine) or of length look_length
    float look_length = 1.0f;
    if (!ctx_.affine) {
      // Towards the centroid from the sensor: 3 (R + mean xl) l + 3 (mean xn) n.
      const float xl3 = s0.xl[k0] + s1.xl[k1] + s2.xl[k2];
      const float xn3 = s0.xn[k0] + s1.xn[k1] + s2.xn[k2];
      dir = (3.0f * ctx_.range0 + xl3) * ctx_.l + xn3 * ctx_.n;
      look_length = dir.norm();
      n_up = dir.cross(ctx_.h);
      if (n_up.z() < 0.0f) n_up = -n_up;
    }
    const float cos_in = -normal.dot(dir) / (twice_area * look_length);
    const bool turned_away = cos_in <= 1e-9f;
    const bool edge_on = cos_in <= static_cast<float>(kMaskEdgeOnCos);  // mask: shadow
    const bool flipped = normal.dot(n_up) < 0.0f;
    const float m0 = s0.margin[k0], m1 = s1.margin[k1], m2 = s2.margin[k2];
    const bool all_lit = m0 >= 0.0f && m1 >= 0.0f && m2 >= 0.0f;
    const bool all_dark = m0 < 0.0f && m1 < 0.0f && m2 < 0.0f;
    const float c0 = s0.col[k0], c1 = s1.col[k1], c2 = s2.col[k2];
    // Fraction of the way from the previous to the current step.
    const float u0 = &s0 == &cur_ ? 1.0f : 0.0f, u1 = &s1 == &cur_ ? 1.0f : 0.0f,
                u2 = &s2 == &cur_ ? 1.0f : 0.0f;
    const float r0 = s0.row[k0], r1 = s1.row[k1], r2 = s2.row[k2];

    // Smooth shading: the sigma0 law at the normal interpolated between the
    // posts' shading normals (RenderSar's rule); flat when one is zero.
    const bool smooth = ctx_.normals != nullptr && !s0.normal[k0].isZero() && !s1.normal[k1].isZero() &&
                        !s2.normal[k2].isZero();
    if (smooth && look_length != 1.0f) dir /= look_length;  // the shading below takes the unit direction
    if (!turned_away && !all_dark) {
      const float power = 0.5f * twice_area * material.Fast(cos_in) * ctx_.power_scale;
      const float area_power = 0.5f * twice_area * ctx_.power_scale;
      const float extent = std::max({std::abs(c1 - c0), std::abs(c2 - c0), std::abs(c2 - c1),
                                     std::abs(r1 - r0), std::abs(r2 - r0), std::abs(r2 - r1)});
      int m = 1;  // without a division for the common small triangle
      if (extent > kSampleSpacingPx) m = std::clamp(CeilInt(std::min(extent / kSampleSpacingPx, 1e6f)), 1, 256);
      if (!all_lit) m = std::max(m, kPartialSubdivision);
      // The m^2 congruent sub-triangles, each integrated with the
      // edge-midpoint rule (exact for quadratic functions: the bilinear
      // splat is sampled to second order): a third of its power at each
      // edge midpoint, unless that point lies in shadow. In barycentric
      // (u, v) times m, the upward sub-triangle (i, j) has its midpoints at
      // (i + 1/2, j), (i, j + 1/2), (i + 1/2, j + 1/2); the downward one at
      // (i + 1/2, j + 1/2), (i + 1, j + 1/2), (i + 1/2, j + 1).
      const float inv_m = 1.0f / float(m);
      const float share = power * inv_m * inv_m / 3.0f;
      const float area_share = area_power * inv_m * inv_m / 3.0f;
      auto sample = [&](float u, float v) {
        u *= inv_m;
        v *= inv_m;
        if (!all_lit && m0 + u * (m1 - m0) + v * (m2 - m0) < 0.0f) return;
        float value = share;
        if (smooth) {
          const Eigen::Vector3f ns = (1.0f - u - v) * s0.normal[k0] + u * s1.normal[k1] + v * s2.normal[k2];
          const float norm = ns.norm();
          const float cos_shade = norm > 0.0f ? std::max(0.0f, -ns.dot(dir) / norm) : cos_in;
          value = area_share * material.Fast(cos_shade);
        }
        Deposit(c0 + u * (c1 - c0) + v * (c2 - c0), r0 + u * (r1 - r0) + v * (r2 - r0), value);
      };
      if (m == 1 && all_lit && !smooth) {
        // The common case (a lit, flat-shaded triangle at most 1.5 pixels
        // wide): the loop below with one sub-triangle, unrolled.
        const float dc1 = 0.5f * (c1 - c0), dc2 = 0.5f * (c2 - c0);
        const float dr1 = 0.5f * (r1 - r0), dr2 = 0.5f * (r2 - r0);
        Deposit(c0 + dc1, r0 + dr1, share);
        Deposit(c0 + dc2, r0 + dr2, share);
        Deposit(c0 + dc1 + dc2, r0 + dr1 + dr2, share);
      } else {
        for (int i = 0; i < m; ++i) {
          for (int j = 0; i + j < m; ++j) {
            const float fi = float(i), fj = float(j);
            sample(fi + 0.5f, fj);
            sample(fi, fj + 0.5f);
            sample(fi + 0.5f, fj + 0.5f);
            if (i + j <= m - 2) {
              sample(fi + 0.5f, fj + 0.5f);
              sample(fi + 1.0f, fj + 0.5f);
              sample(fi + 0.5f, fj + 1.0f);
            }
          }
        }
      }
    }

    {
      // Pixel centres covered by the projected triangle (the tracer's
      // barycentric test), each coded from the surface at that centre. Even
      // a triangle whose three corners are lit is evaluated at every centre:
      // the horizon is not convex along the triangle (a peak or the end of a
      // ridge edge in front can shadow its middle).
      const int c_lo = std::max(0, CeilInt(std::min({c0, c1, c2})));
      const int c_hi = std::min(ctx_.width - 1, FloorInt(std::max({c0, c1, c2})));
      const int r_lo = std::max(row0_, CeilInt(std::min({r0, r1, r2})));
      const int r_hi = std::min(row1_ - 1, FloorInt(std::max({r0, r1, r2})));
      // No pixel centre in its bounding box (a third of the triangles on a
      // 1000^2 fractal DEM with pixels of the post spacing).
      if (c_lo > c_hi || r_lo > r_hi) return;
      const double area2 = double(c1 - c0) * (r2 - r0) - double(r1 - r0) * (c2 - c0);
      if (std::abs(area2) < 1e-12) return;
      // Barycentrics as affine functions of the pixel: w1 = qc w1_c + qr
      // w1_r, w2 = qc w2_c + qr w2_r with (qc, qr) = (c - c0, r - r0).
      const double inv_area2 = 1.0 / area2;
      const double w1_c = double(r2 - r0) * inv_area2, w1_r = -double(c2 - c0) * inv_area2;
      const double w2_c = -double(r1 - r0) * inv_area2, w2_r = double(c1 - c0) * inv_area2;
      for (int r = r_lo; r <= r_hi; ++r) {
        const double qr = r - r0;
        for (int c = c_lo; c <= c_hi; ++c) {
          const double qc = c - c0;
          const double w1 = qc * w1_c + qr * w1_r;
          const double w2 = qc * w2_c + qr * w2_r;
          const double w0 = 1.0 - w1 - w2;
          constexpr double kTol = -1e-9;
          if (w0 < kTol || w1 < kTol || w2 < kTol) continue;
          uint8_t code;
          // Lit unless turned away or below the horizon of its own azimuth
          // line, evaluated at the centre itself. A horizon within a few
          // float roundings of the point is its own surface (an edge through
          // the centre), as the tracer's visibility ray ignores hits within
          // its t_near.
          const float e = float(w0 * s0.e[k0] + w1 * s1.e[k1] + w2 * s2.e[k2]);
          const bool shadow =
              edge_on ||
              PointMargin(float(w0 * s0.a[k0] + w1 * s1.a[k1] + w2 * s2.a[k2]), e,
                          float(w0 * u0 + w1 * u1 + w2 * u2), cell_t_, r) < -(1e-4f + 2.5e-7f * std::abs(e));
          if (shadow) {
            code = kMaskShadow;
          } else {
            code = flipped ? kMaskLayover : kMaskNone;
          }
          mask_[size_t(r) * ctx_.width + c] |= code | kCoveredFlag;
        }
      }
    }
  }

  const Context& ctx_;
  const int row0_, row1_;
  float* intensity_;
  uint8_t* mask_;
  float a_lo_cells_, a_hi_cells_, a_lo_posts_, a_hi_posts_;
  int64_t line_first_ = 0;
  // Per horizon line: the highest elevation met so far (horizon_), the
  // same before the last step's column (horizon_before_), and that of the
  // previous step (horizon_prev_, while its cells are rendered).
  std::vector<float> horizon_, horizon_before_, horizon_prev_, rho_, line_a_;
  int cell_t_ = 0;
  Step prev_, cur_;
};

// Chooses the sweep over the grid: steps along the axis closest to the
// horizontal look direction, in the direction of increasing ground range.
SweepView MakeSweepView(const std::vector<Eigen::Vector3f>& posts, int width, int height,
                        const Eigen::Vector3f& h, const Eigen::Vector3f& ground_look) {
  const int cm = std::min(width / 2, width - 2), rm = std::min(height / 2, height - 2);
  const Eigen::Vector3f p = posts[size_t(rm) * width + cm];
  const Eigen::Vector3f dc = posts[size_t(rm) * width + cm + 1] - p;
  const Eigen::Vector3f dr = posts[size_t(rm + 1) * width + cm] - p;
  const float a_c = dc.dot(h), a_r = dr.dot(h), g_c = dc.dot(ground_look), g_r = dr.dot(ground_look);
  SweepView v;
  if (std::abs(a_r) >= std::abs(a_c)) {
    // Azimuth lines run along rows: step over columns.
    v.along_rows = true;
    v.steps = width;
    v.trans = height;
    v.cs = g_c >= 0 ? 1 : -1;
    v.rt = a_r >= 0 ? 1 : -1;
  } else {
    v.along_rows = false;
    v.steps = height;
    v.trans = width;
    v.rs = g_r >= 0 ? 1 : -1;
    v.ct = a_c >= 0 ? 1 : -1;
  }
  v.c0 = (v.cs < 0 || v.ct < 0) ? width - 1 : 0;
  v.r0 = (v.rs < 0 || v.rt < 0) ? height - 1 : 0;
  v.base = int64_t(v.r0) * width + v.c0;
  v.ds = int64_t(v.rs) * width + v.cs;
  v.dt = int64_t(v.rt) * width + v.ct;
  // The mesh diagonal joins (c + 1, r) and (c, r + 1): (dc, dr) products -1.
  // From corner C = (s - 1, t + 1) to B = (s, t): (dc, dr) = (cs - ct, rs - rt).
  v.diagonal_bc = (v.cs - v.ct) * (v.rs - v.rt) == -1;
  // Triangle orientation at a cell in the middle of the grid.
  auto post = [&](int s, int t) {
    return posts[size_t(v.base + int64_t(s) * v.ds + int64_t(t) * v.dt)];
  };
  const int s = std::max(1, v.steps / 2), t = std::min(v.trans / 2, v.trans - 2);
  const Eigen::Vector3f A = post(s - 1, t), C = post(s - 1, t + 1), B = post(s, t), D = post(s, t + 1);
  auto up = [](const Eigen::Vector3f& p0, const Eigen::Vector3f& p1, const Eigen::Vector3f& p2) {
    return (p1 - p0).cross(p2 - p0).z() >= 0.0f ? 1.0f : -1.0f;
  };
  if (v.diagonal_bc) {
    v.sign1 = up(A, B, C);
    v.sign2 = up(B, D, C);
  } else {
    v.sign1 = up(A, B, D);
    v.sign2 = up(A, D, C);
  }
  return v;
}

}  // namespace

SarImage RenderSarRaster(const std::vector<Eigen::Vector3f>& posts, int width, int height,
                         const material::MaterialTable& materials,
                         const sensor::SarGeometry& geometry,
                         const std::vector<scene::ClassId>& cell_classes, double wavelength_m,
                         material::Polarization polarization, const std::vector<Eigen::Vector3f>& post_normals) {
  GISSAR_CHECK(width >= 2 && height >= 2);
  GISSAR_CHECK(posts.size() == size_t(width) * height);
  const size_t cells = size_t(width - 1) * (height - 1);
  GISSAR_CHECK(cell_classes.empty() || cell_classes.size() == cells || cell_classes.size() == 2 * cells);
  GISSAR_CHECK(post_normals.empty() || post_normals.size() == posts.size());
  Stopwatch watch;
  Context ctx;
  ctx.posts = posts.data();
  ctx.grid_width = width;
  ctx.classes = cell_classes.empty() ? nullptr : cell_classes.data();
  ctx.triangle_classes = cell_classes.size() == 2 * cells;
  ctx.normals = post_normals.empty() ? nullptr : post_normals.data();
  for (size_t id = 0; id < std::max<size_t>(materials.size(), 1); ++id) {
    ctx.materials.emplace_back(materials.Get(static_cast<scene::ClassId>(id)), wavelength_m, polarization);
  }
  ctx.affine = geometry.mode() == sensor::ProjectionMode::kAffine;
  ctx.xc = geometry.scene_centre().cast<float>();
  ctx.h = geometry.flight_direction().cast<float>();
  ctx.l = geometry.look_direction().cast<float>();
  ctx.n = geometry.range_plane_normal().cast<float>();
  ctx.up_sign = ctx.n.z() >= 0.0f ? 1.0f : -1.0f;
  ctx.n_up = ctx.up_sign * ctx.n;
  ctx.range0 = static_cast<float>(geometry.slant_range_m());
  ctx.inv_dr = static_cast<float>(1.0 / geometry.range_spacing_m());
  ctx.inv_da = static_cast<float>(1.0 / geometry.azimuth_spacing_m());
  ctx.da = static_cast<float>(geometry.azimuth_spacing_m());
  ctx.u0 = static_cast<float>(geometry.u0());
  ctx.v0 = static_cast<float>(geometry.v0());
  ctx.power_scale = static_cast<float>(1.0 / (geometry.range_spacing_m() * geometry.azimuth_spacing_m()));
  ctx.width = geometry.width();
  ctx.height = geometry.height();

  Eigen::Vector3f ground_look(ctx.l.x(), ctx.l.y(), 0.0f);
  ground_look.normalize();
  ctx.view = MakeSweepView(posts, width, height, ctx.h, ground_look);

  // Horizon lines half a post apart across the sweep; the cell span bounds
  // the along-track extent of any cell. Both from the post spacing measured
  // at the grid's corners and centre (posts need not be evenly spaced).
  float min_transverse = std::numeric_limits<float>::infinity(), max_span = 0.0f;
  for (int r : {0, height / 2, height - 2}) {
    for (int c : {0, width / 2, width - 2}) {
      const Eigen::Vector3f& p = posts[size_t(r) * width + c];
      const float a_c = std::abs((posts[size_t(r) * width + c + 1] - p).dot(ctx.h));
      const float a_r = std::abs((posts[size_t(r + 1) * width + c] - p).dot(ctx.h));
      const float transverse = ctx.view.along_rows ? a_r : a_c;
      min_transverse = std::min(min_transverse, transverse);
      max_span = std::max(max_span, a_c + a_r);
    }
  }
  GISSAR_CHECK(min_transverse > 0.0f);
  // Lines at least kLinesPerPost per post and an integer number per image
  // row, one through every row's centres.
  ctx.lines_per_row = std::max(1, static_cast<int>(std::ceil(ctx.da * kLinesPerPost / min_transverse)));
  ctx.line_spacing = static_cast<float>(geometry.azimuth_spacing_m() / ctx.lines_per_row);
  ctx.inv_line_spacing = 1.0f / ctx.line_spacing;
  ctx.line_offset = -geometry.v0() * geometry.azimuth_spacing_m();
  ctx.cell_span = 1.25f * max_span + 1e-3f;

  SarImage image;
  image.width = ctx.width;
  image.height = ctx.height;
  // The planes' first touch (fresh pages) on both threads: the single-bounce
  // layer is filled by the chunks below (single bounce only: the other
  // layers stay empty).
  const size_t pixels = size_t(ctx.width) * ctx.height;
  std::vector<float>& single = image.bounce_layers[0];
  tbb::parallel_invoke([&] { image.intensity.assign(pixels, 0.0f); }, [&] { single.resize(pixels); },
                       [&] {
                         image.mask.assign(pixels, kMaskNone);
                         image.footprint.resize(pixels);
                       });
  const int chunks = (ctx.height + kChunkRows - 1) / kChunkRows;
  tbb::parallel_for(tbb::blocked_range<int>(0, chunks, 1), [&](const tbb::blocked_range<int>& range) {
    for (int k = range.begin(); k != range.end(); ++k) {
      const int row0 = k * kChunkRows, row1 = std::min(ctx.height, row0 + kChunkRows);
      ChunkRenderer(ctx, row0, row1, image.intensity.data(), image.mask.data()).Run();
      // The chunk's rows are final: the covered flag becomes the footprint,
      // the intensity the single-bounce layer.
      const size_t begin = size_t(row0) * ctx.width, end = size_t(row1) * ctx.width;
      for (size_t i = begin; i < end; ++i) {
        image.footprint[i] = (image.mask[i] & kCoveredFlag) != 0;
        image.mask[i] &= kMaskLayover | kMaskShadow;
      }
      std::copy(image.intensity.begin() + begin, image.intensity.begin() + end, single.begin() + begin);
    }
  });
  image.stats.cells = int64_t(width - 1) * (height - 1);
  image.stats.trace_seconds = watch.ElapsedSeconds();
  return image;
}

GridHeightfield::GridHeightfield(const std::vector<Eigen::Vector3f>& posts, int width, int height,
                                 std::optional<double> top_z)
    : posts_(posts.data()), width_(width), height_(height) {
  GISSAR_CHECK(width >= 2 && height >= 2);
  GISSAR_CHECK(posts.size() == size_t(width) * height);
  if (top_z) {
    top_z_ = *top_z;
  } else {
    top_z_ = -std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3f& p : posts) {
      if (std::isfinite(p.z())) top_z_ = std::max(top_z_, double(p.z()));
    }
  }
  // A quarter of the smallest horizontal post spacing at the corners and
  // the centre.
  double spacing = std::numeric_limits<double>::infinity();
  for (int r : {0, height / 2, height - 2}) {
    for (int c : {0, width / 2, width - 2}) {
      const Eigen::Vector3d p = Post(c, r);
      spacing = std::min({spacing, (Post(c + 1, r) - p).head<2>().norm(), (Post(c, r + 1) - p).head<2>().norm()});
    }
  }
  step_m_ = std::isfinite(spacing) && spacing > 0.0 ? 0.25 * spacing : 1.0;
  corner_origin_ = Post(0, 0).head<2>();
  Eigen::Matrix2d m;
  m.col(0) = (Post(width - 1, 0).head<2>() - corner_origin_) / (width - 1);
  m.col(1) = (Post(0, height - 1).head<2>() - corner_origin_) / (height - 1);
  corner_affine_valid_ = std::abs(m.determinant()) > 0.0;
  if (corner_affine_valid_) corner_inverse_ = m.inverse();
}

Eigen::Vector2d GridHeightfield::GridCoordinates(double x, double y) const {
  const Eigen::Vector2d q(x, y);
  // Start from the affine grid through three corners, then invert the local
  // affine map of the cell found until the cell no longer changes.
  auto solve = [&](int c0, int r0, int dc, int dr) {
    const Eigen::Vector2d p0 = Post(c0, r0).head<2>();
    Eigen::Matrix2d m;
    m.col(0) = (Post(c0 + dc, r0).head<2>() - p0) / dc;
    m.col(1) = (Post(c0, r0 + dr).head<2>() - p0) / dr;
    const double det = m.determinant();
    if (!(std::abs(det) > 0.0)) return Eigen::Vector2d(std::numeric_limits<double>::quiet_NaN(), 0.0);
    return Eigen::Vector2d(Eigen::Vector2d(c0, r0) + m.inverse() * (q - p0));
  };
  // The corners' affine map is the same for every point: inverted once (the
  // constructor), the same arithmetic as solve(0, 0, width - 1, height - 1).
  Eigen::Vector2d g = corner_affine_valid_
                          ? Eigen::Vector2d(Eigen::Vector2d(0, 0) + corner_inverse_ * (q - corner_origin_))
                          : Eigen::Vector2d(std::numeric_limits<double>::quiet_NaN(), 0.0);
  for (int iteration = 0; iteration < 12 && g.allFinite(); ++iteration) {
    const int c0 = std::clamp(static_cast<int>(std::floor(std::clamp(g.x(), -1e9, 1e9))), 0, width_ - 2);
    const int r0 = std::clamp(static_cast<int>(std::floor(std::clamp(g.y(), -1e9, 1e9))), 0, height_ - 2);
    const Eigen::Vector2d next = solve(c0, r0, 1, 1);
    const bool same_cell = std::clamp(static_cast<int>(std::floor(std::clamp(next.x(), -1e9, 1e9))), 0, width_ - 2) == c0 &&
                           std::clamp(static_cast<int>(std::floor(std::clamp(next.y(), -1e9, 1e9))), 0, height_ - 2) == r0;
    g = next;
    if (same_cell) break;
  }
  return g;
}

std::optional<double> GridHeightfield::SurfaceHeight(double x, double y) const {
  const Eigen::Vector2d g = GridCoordinates(x, y);
  constexpr double kTol = 1e-6;
  if (!g.allFinite() || g.x() < -kTol || g.y() < -kTol || g.x() > width_ - 1 + kTol || g.y() > height_ - 1 + kTol) {
    return std::nullopt;
  }
  const int c = std::clamp(static_cast<int>(std::floor(g.x())), 0, width_ - 2);
  const int r = std::clamp(static_cast<int>(std::floor(g.y())), 0, height_ - 2);
  auto height_in = [&](const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                       double* out) {
    const Eigen::Vector2d u = (p1 - p0).head<2>(), v = (p2 - p0).head<2>(), w = Eigen::Vector2d(x, y) - p0.head<2>();
    const double det = u.x() * v.y() - u.y() * v.x();
    if (!(std::abs(det) > 0.0)) return false;
    const double s = (w.x() * v.y() - w.y() * v.x()) / det, t = (u.x() * w.y() - u.y() * w.x()) / det;
    *out = p0.z() + s * (p1.z() - p0.z()) + t * (p2.z() - p0.z());
    return s >= -1e-9 && t >= -1e-9 && s + t <= 1.0 + 1e-9;
  };
  // MeshFromGrid's triangles (a, b, d) and (b, e, d) of cell (cc, rr):
  // a = (cc, rr), b = (cc + 1, rr), d = (cc, rr + 1), e = (cc + 1, rr + 1).
  // The last call's z is the plane of (b, e, d).
  auto height_in_cell = [&](int cc, int rr, double* out) {
    const Eigen::Vector3d a = Post(cc, rr), b = Post(cc + 1, rr), d = Post(cc, rr + 1), e = Post(cc + 1, rr + 1);
    return height_in(a, b, d, out) || height_in(b, e, d, out);
  };
  double z = 0.0;
  if (height_in_cell(c, r, &z)) return z;
  // The local affine inversion of a grid that is not a parallelogram
  // lattice (a geographic DEM in ENU) can land one cell off near a cell's
  // edge: the neighbours hold the point then.
  for (int dr = -1; dr <= 1; ++dr) {
    for (int dc = -1; dc <= 1; ++dc) {
      const int cc = c + dc, rr = r + dr;
      if ((dc == 0 && dr == 0) || cc < 0 || rr < 0 || cc > width_ - 2 || rr > height_ - 2) continue;
      double zn = 0.0;
      if (height_in_cell(cc, rr, &zn)) return zn;
    }
  }
  // At the grid's border (within the tolerance of GridCoordinates' bounds):
  // the plane of the found cell's second half.
  return std::isfinite(z) ? std::optional<double>(z) : std::nullopt;
}

double GridHeightfield::HitCell(int c, int r, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                double t_near, double t_far) const {
  const Eigen::Vector3d a = Post(c, r), b = Post(c + 1, r), d = Post(c, r + 1), e = Post(c + 1, r + 1);
  double best = std::numeric_limits<double>::infinity();
  // Moller-Trumbore, both faces.
  auto triangle = [&](const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2) {
    const Eigen::Vector3d e1 = p1 - p0, e2 = p2 - p0;
    const Eigen::Vector3d pv = dir.cross(e2);
    const double det = e1.dot(pv);
    if (!(std::abs(det) > 1e-300)) return;
    const double inv = 1.0 / det;
    const Eigen::Vector3d tv = origin - p0;
    const double u = tv.dot(pv) * inv;
    if (u < 0.0 || u > 1.0) return;
    const Eigen::Vector3d qv = tv.cross(e1);
    const double v = dir.dot(qv) * inv;
    if (v < 0.0 || u + v > 1.0) return;
    const double t = e2.dot(qv) * inv;
    if (t >= t_near && t <= t_far) best = std::min(best, t);
  };
  triangle(a, b, d);
  triangle(b, e, d);
  return best;
}

bool GridHeightfield::Occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_near,
                               double t_far) const {
  if (!(t_far >= t_near)) return false;
  // Beyond the highest post a rising segment meets nothing.
  double t_end = t_far;
  if (dir.z() > 0.0) t_end = std::min(t_end, (top_z_ - origin.z()) / dir.z() + 1e-6);
  if (dir.z() >= 0.0 && origin.z() + t_near * dir.z() > top_z_) return false;
  const double horizontal = std::hypot(dir.x(), dir.y());
  const double dt = horizontal > 1e-12 ? step_m_ / horizontal : std::max(t_end - t_near, 1e-3);
  // Cells already tested (the 3 x 3 neighbourhoods of successive steps overlap).
  std::array<int64_t, 64> tested;
  tested.fill(-1);
  size_t next = 0;
  int outside_steps = 0;
  for (double t = t_near; t <= t_end + dt; t += dt) {
    const Eigen::Vector3d p = origin + std::min(t, t_end) * dir;
    const Eigen::Vector2d g = GridCoordinates(p.x(), p.y());
    if (!g.allFinite()) return false;
    const int ci = static_cast<int>(std::floor(std::clamp(g.x(), -1e9, 1e9)));
    const int ri = static_cast<int>(std::floor(std::clamp(g.y(), -1e9, 1e9)));
    // Far outside the grid the segment cannot come back (the grid's plan is
    // convex to within its curvature).
    if (ci < -2 || ri < -2 || ci > width_ || ri > height_) {
      if (++outside_steps > 8) return false;
      continue;
    }
    outside_steps = 0;
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int c = ci + dc, r = ri + dr;
        if (c < 0 || r < 0 || c > width_ - 2 || r > height_ - 2) continue;
        const int64_t id = int64_t(r) * width_ + c;
        if (std::find(tested.begin(), tested.end(), id) != tested.end()) continue;
        tested[next] = id;
        next = (next + 1) % tested.size();
        if (HitCell(c, r, origin, dir, t_near, t_far) < std::numeric_limits<double>::infinity()) return true;
      }
    }
    if (t >= t_end) break;
  }
  return false;
}

std::vector<PointReturn> ReflectorReturns(const GridHeightfield& terrain, const std::vector<SceneReflector>& reflectors,
                                          const sensor::SarGeometry& geometry, double wavelength_m,
                                          std::optional<material::Polarization> polarization) {
  return ReflectorReturns(
      [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_near, double t_far) {
        return terrain.Occluded(origin, dir, t_near, t_far);
      },
      reflectors, geometry, wavelength_m, polarization);
}

}  // namespace gissar::render
