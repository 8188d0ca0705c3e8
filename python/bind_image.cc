// Binds the image layer's pictures: quicklook, annotated_quicklook, composite, epipolar_plot, kvd_diagram,
// side_by_side and write_gif. (The render layer has no binding of its own: its images reach Python
// through simulate, bind_pipeline_simulate.cc.)
#include "bindings.h"

#include <cmath>
#include <optional>

#include "gissar/image/annotated.h"
#include "gissar/image/composite.h"
#include "gissar/image/contact_sheet.h"
#include "gissar/image/epipolar_plot.h"
#include "gissar/image/gif_writer.h"
#include "gissar/image/quicklook.h"
#include "gissar/image/side_by_side.h"
#include "gissar/mvg/affine_fundamental.h"
#include "gissar/util/atomic_output.h"

namespace gissar::python {

namespace {

void WriteGifFrames(const std::string& path, const std::vector<py::array_t<uint8_t, py::array::c_style | py::array::forcecast>>& frames,
                    int delay_cs) {
  if (frames.empty()) throw InputError("no frames", path);
  if (delay_cs < 1) throw ConfigError("must be >= 1", "delay_cs");
  const py::ssize_t h = frames[0].ndim() == 2 ? frames[0].shape(0) : 0, w = frames[0].ndim() == 2 ? frames[0].shape(1) : 0;
  std::vector<std::vector<uint8_t>> grey;
  for (const auto& f : frames) {
    if (f.ndim() != 2 || f.shape(0) != h || f.shape(1) != w || h < 1 || w < 1) {
      throw InputError("frames must be 2-D uint8 arrays of one size", path);
    }
    grey.emplace_back(f.data(), f.data() + f.size());
  }
  py::gil_scoped_release release;
  AtomicOutputs outputs;
  image::WriteAnimatedGif(outputs.Add(path), grey, static_cast<int>(w), static_cast<int>(h), delay_cs);
  outputs.Commit();
}

// quicklook, annotated_quicklook, composite: pictures of intensity images.
void BindQuicklooks(py::module_& m) {
  m.def("quicklook", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& intensity,
                        double low_percentile, double high_percentile) {
        const FloatImage im = ToFloatImage(intensity, "gissar.quicklook");
        if (!(low_percentile >= 0 && low_percentile < high_percentile && high_percentile <= 100)) {
          throw ConfigError("need 0 <= low < high <= 100", "low_percentile/high_percentile");
        }
        image::DbStretch stretch;
        std::vector<uint8_t> grey;
        {
          py::gil_scoped_release release;  // other Python threads run meanwhile (seconds for a large image)
          grey = image::DbQuicklook(im.values, low_percentile, high_percentile, &stretch);
        }
        return py::make_tuple(Image(grey, im.height, im.width), py::make_tuple(stretch.low_db, stretch.high_db));
      }, py::arg("intensity"), py::arg("low_percentile") = 2.0, py::arg("high_percentile") = 98.0,
      "dB quicklook of a linear intensity image: (grey (H, W) uint8, (low_db, high_db)); 10 log10 I mapped from "
      "its low to high percentile onto grey 1..255, no return (I <= 0) = 0.");
  m.def("annotated_quicklook", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& intensity,
                                  double range_spacing_m, double azimuth_spacing_m, const std::string& title,
                                  double near_range_m, double azimuth_origin_m) {
        const FloatImage im = ToFloatImage(intensity, "gissar.annotated_quicklook");
        if (!(range_spacing_m > 0 && azimuth_spacing_m > 0)) {
          throw ConfigError("pixel spacings must be positive", "range_spacing_m/azimuth_spacing_m");
        }
        if (!std::isfinite(near_range_m) || !std::isfinite(azimuth_origin_m)) {
          throw ConfigError("axis origins must be finite", "near_range_m/azimuth_origin_m");
        }
        image::RgbImage picture;
        {
          py::gil_scoped_release release;
          picture = image::AnnotatedQuicklook(
              im.values, im.width, im.height,
              image::QuicklookAxes{near_range_m, range_spacing_m, azimuth_origin_m, azimuth_spacing_m}, title);
        }
        return RgbArray(picture);
      }, py::arg("intensity"), py::arg("range_spacing_m"), py::arg("azimuth_spacing_m"), py::arg("title") = "",
      py::arg("near_range_m") = 0.0, py::arg("azimuth_origin_m") = 0.0,
      "dB quicklook with a slant-range axis (near_range_m = slant range of column 0) and an along-track axis "
      "(azimuth_origin_m = along-track coordinate of row 0, e.g. -v0 * azimuth_spacing_m for metres from the scene "
      "centre), km when values reach 1000 m, a dB colour bar and a title: (H', W', 3) uint8.");
  m.def("composite", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& green,
                        const py::array_t<float, py::array::c_style | py::array::forcecast>& magenta) {
        const FloatImage a = ToFloatImage(green, "gissar.composite: green");
        const FloatImage b = ToFloatImage(magenta, "gissar.composite: magenta");
        if (a.width != b.width || a.height != b.height) throw InputError("images differ in size", "gissar.composite");
        image::RgbImage picture;
        {
          py::gil_scoped_release release;
          picture = image::IntensityComposite(a.values, b.values, a.width, a.height);
        }
        return RgbArray(picture);
      }, py::arg("green"), py::arg("magenta"),
      "Green/magenta composite of two co-registered linear intensity images, each dB-stretched on its own: grey "
      "where they agree. (H, W, 3) uint8.");
}

// epipolar_plot, kvd_diagram, side_by_side, write_gif: figures and their files.
void BindFigures(py::module_& m) {
  m.def("epipolar_plot", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& image1,
                            const py::array_t<float, py::array::c_style | py::array::forcecast>& image2,
                            const py::array_t<double, py::array::c_style>& x1, const py::array_t<double, py::array::c_style>& x2,
                            const py::array_t<double, py::array::c_style | py::array::forcecast>& f,
                            std::optional<std::vector<int>> inliers) {
        const FloatImage a = ToFloatImage(image1, "gissar.epipolar_plot: image1");
        const FloatImage b = ToFloatImage(image2, "gissar.epipolar_plot: image2");
        const auto matches = Matches(x1, x2);
        if (f.ndim() != 2 || f.shape(0) != 3 || f.shape(1) != 3) throw InputError("F must be 3 x 3", "gissar.epipolar_plot");
        Eigen::Matrix3d m3;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) m3(r, c) = f.at(r, c);
        image::EpipolarPlotInput in;
        {
          py::gil_scoped_release release;
          in.image1 = image::DbQuicklook(a.values, 1.0, 99.0);
          in.image2 = image::DbQuicklook(b.values, 1.0, 99.0);
        }
        in.width1 = a.width;
        in.height1 = a.height;
        in.width2 = b.width;
        in.height2 = b.height;
        in.inlier.assign(matches.size(), !inliers.has_value());
        if (inliers) {
          for (int i : *inliers) {
            if (i < 0 || size_t(i) >= matches.size()) throw InputError("inlier index out of range", "gissar.epipolar_plot");
            in.inlier[i] = true;
          }
        }
        for (const mvg::PointMatch& mt : matches) {
          in.matches.push_back({mt.p1, mt.p2});
          in.lines_in_2.push_back(mvg::EpipolarLineInImage2(m3, mt.p1));
          in.lines_in_1.push_back(mvg::EpipolarLineInImage1(m3, mt.p2));
        }
        image::RgbImage picture;
        {
          py::gil_scoped_release release;
          picture = image::DrawEpipolarPair(in);
        }
        return RgbArray(picture);
      }, py::arg("image1"), py::arg("image2"), py::arg("x1"), py::arg("x2"), py::arg("F"), py::arg("inliers") = py::none(),
      "Image 1 | image 2 (dB quicklooks) with the matches x1 <-> x2 (N, 2 pixels): inliers green with their "
      "epipolar lines under F ([x2 y2 1] F [x1 y1 1]' = 0) in yellow, outliers red. (H, W, 3) uint8.");
  m.def("kvd_diagram", [](double s, double theta_deg, double phi_deg, std::optional<double> heading_change_deg) {
        return RgbArray(image::KvdDiagram(s, theta_deg, phi_deg, heading_change_deg.value_or(0.0),
                                          heading_change_deg.has_value()));
      }, py::arg("s"), py::arg("theta_deg"), py::arg("phi_deg"), py::arg("heading_change_deg") = py::none(),
      "The KvD reading of F: rho axis at phi, cyclorotation theta (degrees), scale s, heading change (degrees) "
      "when known. (H, W, 3) uint8.");
  m.def("side_by_side", [](const std::vector<py::array_t<uint8_t, py::array::c_style | py::array::forcecast>>& panels,
                           const std::vector<std::string>& titles) {
        if (panels.empty() || panels.size() != titles.size()) {
          throw InputError("give as many titles as panels (at least one)", "gissar.side_by_side");
        }
        std::vector<image::RgbImage> rgb;
        for (const auto& p : panels) {
          if (p.ndim() != 3 || p.shape(2) != 3 || p.shape(0) < 1 || p.shape(1) < 1) {
            throw InputError("panels must be (H, W, 3) uint8 arrays", "gissar.side_by_side");
          }
          rgb.push_back({static_cast<int>(p.shape(1)), static_cast<int>(p.shape(0)),
                         std::vector<uint8_t>(p.data(), p.data() + p.size())});
        }
        return RgbArray(image::SideBySide(rgb, titles));
      }, py::arg("panels"), py::arg("titles"),
      "RGB panels (H, W, 3) uint8 side by side, top-aligned on white, each under its title: (H', W', 3) uint8.");
  m.def("write_gif", &WriteGifFrames, py::arg("path"), py::arg("frames"), py::arg("delay_cs") = 50,
        "Write grey uint8 frames (a list of (H, W) arrays of one size) as a looping animated GIF, delay_cs "
        "hundredths of a second per frame.");
}

}  // namespace

void BindImage(py::module_& m) {
  BindQuicklooks(m);
  BindFigures(m);
}

}  // namespace gissar::python
