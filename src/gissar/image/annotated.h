// Pictures for people: annotated quicklooks (dB colour bar, slant-range and
// along-track axes)
// and the Koenderink-van Doorn diagram of a two-view geometry.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "gissar/image/class_map.h"
#include "gissar/image/quicklook.h"

namespace gissar::image {

// Axes of an annotated quicklook: the value at the centre of column 0 / row 0
// and the metres per pixel (> 0). For a simulated image (sensor::SarGeometry)
// the column c shows slant range R + (c - u0) dr (the scene centre's range R
// at column u0, affine and exact mode alike) and row r the along-track
// coordinate (r - v0) da from the scene centre.
struct QuicklookAxes {
  double range_origin_m = 0.0;    // slant range of column 0
  double range_spacing_m = 1.0;   // slant-range metres per column
  double azimuth_origin_m = 0.0;  // along-track coordinate of row 0
  double azimuth_spacing_m = 1.0; // along-track metres per row
  // True when range_origin_m is relative to the scene centre (affine
  // geometry: parallel rays, no sensor position, so no true slant range);
  // the axis then reads "slant range from scene centre".
  bool range_relative = false;
};

// One labelled tick of an axis: its pixel coordinate (column or row of the
// image, pixel centres at integers), its value in metres and its label.
struct AxisTick {
  double pixel = 0.0;
  double value_m = 0.0;
  std::string label;
};

// Ticks every "nice" step (1, 2 or 5 x 10^k m, about `target_ticks` of them)
// over pixels 0 .. pixels-1 of an axis whose pixel p has value origin_m +
// p * spacing_m. Labels are in km when the largest |value| at the ends is
// 1000 m or more (*unit = "km"), else in m, with just enough decimals for
// the step.
std::vector<AxisTick> AxisTicks(double origin_m, double spacing_m, int pixels, int target_ticks,
                                std::string* unit);

// A one-channel 8-bit picture, row-major.
struct GreyImage {
  int width = 0, height = 0;
  std::vector<uint8_t> grey;
};

// The dB quicklook of `intensity` (width x height, linear) with a title, a
// horizontal slant-range axis and a vertical along-track axis (ticks from
// AxisTicks) and a grey-scale colour bar labelled in dB.
RgbImage AnnotatedQuicklook(std::span<const float> intensity, int width, int height,
                            const QuicklookAxes& axes, const std::string& title);
// The same picture around `levels`, the image's grey levels already
// stretched (DbQuicklook's, width x height) with `stretch` (the colour bar's
// labels). Every pixel of it is a grey level (the image, black text, a grey
// colour bar): drawn in one channel, it holds the pixels of
// AnnotatedQuicklook's channels (each the same).
GreyImage AnnotatedGreyQuicklook(std::span<const uint8_t> levels, const DbStretch& stretch, int width, int height,
                                 const QuicklookAxes& axes, const std::string& title);

// The KvD reading of an affine F: the image plane with the rotation axis at
// angle phi (the bas-relief axis, about which the unknown rho turns), the
// cyclorotation theta as an arc, scale s, and (when known) the heading change.
RgbImage KvdDiagram(double s, double theta_deg, double phi_deg, double heading_change_deg,
                    bool heading_known);

}  // namespace gissar::image
