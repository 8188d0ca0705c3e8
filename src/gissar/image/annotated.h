// Pictures for people: annotated quicklooks (dB colour bar, axes in metres)
// and the Koenderink-van Doorn diagram of a two-view geometry.
#pragma once

#include <string>
#include <vector>

#include "gissar/image/class_map.h"
#include "gissar/image/quicklook.h"

namespace gissar::image {

// The dB quicklook of `intensity` (width x height, linear) with a title, a
// horizontal axis in slant-range metres, a vertical axis in azimuth metres
// (relative to the image origin, ticks every "nice" step) and a grey-scale
// colour bar labelled in dB. Spacings in metres per pixel, > 0.
RgbImage AnnotatedQuicklook(const std::vector<float>& intensity, int width, int height,
                            double range_spacing_m, double azimuth_spacing_m, const std::string& title);

// The KvD reading of an affine F: the image plane with the rotation axis at
// angle phi (the bas-relief axis, about which the unknown rho turns), the
// cyclorotation theta as an arc, scale s, and (when known) the heading change.
RgbImage KvdDiagram(double s, double theta_deg, double phi_deg, double heading_change_deg,
                    bool heading_known);

}  // namespace gissar::image
