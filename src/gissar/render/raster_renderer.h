// DEM-raster SAR image formation (`simulate --engine raster`): the approach
// of the DEM-based simulators used for terrain correction. Instead of
// tracing rays, every triangle of the DEM's grid mesh is projected
// analytically to (slant range, azimuth) and returns its share of power at
// once; shadow comes from a sweep along each azimuth (zero-Doppler) line
// that keeps the highest elevation seen so far, layover from the surfaces
// whose slant range decreases with ground range. Single bounce only;
// canonical reflectors through GridHeightfield and ReflectorReturns below.
//
// It renders the same image as RenderSar on a single-bounce scene of the
// same mesh (docs/performance.md, "DEM-raster engine"): the tracer's rays
// cover every lit surface, each returning sigma0 times the area it covers,
// so a lit patch of area A returns
//     A sigma0(theta_l) / (dr da)
// (dr, da the pixel spacings) in both affine and exact mode; the raster
// engine deposits exactly that, splatted bilinearly at the patch's
// projection.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "gissar/material/material.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::render {

// Renders the single-bounce image and the layover/shadow mask of the grid
// mesh of `posts` (row-major, `width` x `height` ENU positions in metres,
// triangulated as scene::MeshFromGrid does: two triangles per cell split
// along the diagonal from post (c+1, r) to (c, r+1), normals up) seen with
// `geometry`, in affine or exact mode.
//
// `cell_classes`: empty (every cell class 0), one class per cell,
// (width - 1) x (height - 1) row-major, or one class per triangle in
// scene::MeshFromGrid's order (2 per cell: first the triangle holding post
// (c, r), then the one holding post (c + 1, r + 1)), so that a mesh's
// `classes` (e.g. the sea of scene::MarkSeaTriangles) can be passed as they
// are; the class indexes `materials`, whose single-bounce sigma0 law for
// `wavelength_m` and `polarization` is used (the mirror share is ignored: no
// multi-bounce).
//
// `post_normals`: empty (flat shading) or one unit shading normal per post
// (e.g. scene::TriangleMesh::SmoothShadingNormals of the grid mesh; a zero
// normal means flat shading for the triangles that use the post). As in
// RenderSar, the local incidence of the sigma0 law then comes from the
// normal interpolated at each sample point of a triangle (cos clamped at 0),
// while the geometry (what is lit, the projected area) keeps the facet.
//
// Returns the SarImage of RenderSar: `intensity` calibrated identically
// (beta0: each patch of area A returns sigma0(theta_l) A over the pixel
// area),
// bounce_layers[0] equal to it and the other layers empty, the mask with the
// same codes and semantics (value at each pixel centre: kMaskShadow when a
// surface covering it faces away from the radar or lies below the horizon
// of its azimuth line, kMaskLayover when a lit surface covering it is imaged
// flipped). Shadow is exact along horizon lines at most half a post apart
// in azimuth, one through the centres of every image row (so the mask,
// evaluated at pixel centres, is exact), and interpolated between them for
// the intensity; each triangle is sampled at
// sub-triangles at most about a pixel wide. A cell with a post whose height
// is not finite is a hole (outside the scene, e.g. a DEM's collar): it
// returns nothing, covers no pixel and hides nothing. stats.cells counts the DEM cells;
// stats.trace_seconds is the rendering time. The result does not depend on
// the thread count.
//
// CHECKs that the grid has at least 2 x 2 posts, that posts.size() ==
// width * height, that cell_classes is empty or has one class per cell or
// per triangle, and that post_normals is empty or has one normal per post.
SarImage RenderSarRaster(const std::vector<Eigen::Vector3f>& posts, int width, int height,
                         const material::MaterialTable& materials,
                         const sensor::SarGeometry& geometry,
                         const std::vector<scene::ClassId>& cell_classes = {},
                         double wavelength_m = 0.031,
                         material::Polarization polarization = material::Polarization::kVV,
                         const std::vector<Eigen::Vector3f>& post_normals = {});

// The grid mesh of RenderSarRaster (scene::MeshFromGrid's triangles of a
// row-major grid of ENU posts) as a height field, without a BVH: the surface
// below a point and line-of-sight tests, for canonical reflectors in the
// raster engine. Cells are found by local affine inversion of the grid
// (posts on a map grid need not be evenly spaced in ENU); a line of sight
// is marched at a quarter of the smallest post spacing, testing the two
// triangles of every cell around each step exactly (the tracer's triangles,
// so both engines agree on what hides a reflector).
class GridHeightfield {
 public:
  // CHECKs at least 2 x 2 posts and posts.size() == width * height. Keeps a
  // pointer to `posts`, which must outlive it. `top_z`: the highest finite
  // post height when the caller knows it (else found here).
  GridHeightfield(const std::vector<Eigen::Vector3f>& posts, int width, int height,
                  std::optional<double> top_z = std::nullopt);
  // Height of the surface at ENU (x, y): the grid triangle whose plan
  // contains it; nullopt outside the grid.
  std::optional<double> SurfaceHeight(double x, double y) const;
  // Whether the segment origin + t dir, t in [t_near, t_far], meets a
  // triangle of the grid (dir a unit vector).
  bool Occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_near, double t_far) const;

 private:
  // Continuous grid coordinates (column, row) of ENU (x, y).
  Eigen::Vector2d GridCoordinates(double x, double y) const;
  // Ray parameter of the first hit of the segment with the two triangles of
  // cell (c, r) in [t_near, t_far], or +inf.
  double HitCell(int c, int r, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_near,
                 double t_far) const;
  Eigen::Vector3d Post(int c, int r) const { return posts_[size_t(r) * width_ + c].cast<double>(); }
  const Eigen::Vector3f* posts_;
  int width_, height_;
  double top_z_ = 0.0;       // highest post
  double step_m_ = 1.0;      // march step (horizontal metres)
  // GridCoordinates' first guess: the affine map through the corner posts
  // (0, 0), (width - 1, 0) and (0, height - 1), inverted.
  Eigen::Vector2d corner_origin_ = Eigen::Vector2d::Zero();
  Eigen::Matrix2d corner_inverse_ = Eigen::Matrix2d::Zero();
  bool corner_affine_valid_ = false;
};

// Returns of `reflectors` in the raster engine: render::ReflectorReturns
// with the height field's line of sight (the same RCS, pattern, pixel and
// phase as the tracer's; `polarization` as there: nullopt the scalar RCS,
// a channel its share of the reflector's scattering matrix and phase).
std::vector<PointReturn> ReflectorReturns(const GridHeightfield& terrain, const std::vector<SceneReflector>& reflectors,
                                          const sensor::SarGeometry& geometry, double wavelength_m,
                                          std::optional<material::Polarization> polarization = std::nullopt);

}  // namespace gissar::render
