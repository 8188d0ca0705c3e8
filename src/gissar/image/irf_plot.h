// The impulse-response picture of `gissar pta` (PREFIX_irf.png): the two
// upsampled cuts of each measured point target (image/point_target.h), in
// dB, one row of two panels per target.
#pragma once

#include <string>
#include <vector>

#include "gissar/image/class_map.h"
#include "gissar/image/point_target.h"

namespace gissar::image {

// One measured target: its caption (e.g. "row 1 trihedral, HH") and the
// measurement whose cuts, peak, spacings and figures are drawn.
struct IrfPlotEntry {
  std::string caption;
  PointTargetMeasurement measurement;
  double range_spacing_m = 1.0;    // metres per column (> 0)
  double azimuth_spacing_m = 1.0;  // metres per row (> 0)
};

// One row per entry: the range cut (left) and the azimuth cut (right),
// power in dB relative to the peak from `floor_db` (< 0) to +3 dB against
// the offset from the sub-pixel peak in metres; the -3 dB level dashed, the
// main lobe (first nulls) shaded, the original samples' positions marked
// on the axis; each panel titled with its -3 dB width, PSLR and ISLR. No
// entry: a small picture saying `empty_text`. CHECKs floor_db < 0 and the
// spacings > 0.
RgbImage IrfPlot(const std::vector<IrfPlotEntry>& entries, double floor_db = -40.0,
                 const std::string& empty_text = "no point target measured");

}  // namespace gissar::image
