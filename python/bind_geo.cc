// Binds the geo layer's readers and writers: _OpenedProduct (a Sentinel-1 SAFE's swath/burst or a NISAR
// RSLC's layer opened for reading windows, behind gissar.open_product) and write_png.
#include "bindings.h"

#include <cmath>
#include <complex>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>

#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/geo/sentinel1_measurement.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/utc_time.h"

namespace gissar::python {

namespace {

// gissar.open_product: one swath/polarisation (optionally one burst) of a
// Sentinel-1 SAFE, or one layer of a NISAR RSLC, opened for reading windows
// (gissar._adapt.ProductArray turns it into a lazy xarray variable). Rows and
// columns are relative to the opened window (a burst's first line is row 0).
class OpenedProduct {
 public:
  OpenedProduct(const std::string& path, const std::optional<std::string>& swath, const std::optional<int>& burst,
                const std::optional<std::string>& polarization, const std::optional<std::string>& radiometry,
                bool noise_removal, const std::optional<std::string>& frequency) {
    try {
      radiometry_ = geo::ParseSentinel1Radiometry(radiometry.value_or(""), "--radiometry");
      if (geo::IsSentinel1Path(path)) {
        if (frequency) throw ConfigError("a Sentinel-1 product has no frequency bands (NISAR only)", "--frequency");
        geo::Sentinel1ImageOptions o;
        o.swath = swath.value_or("");
        o.polarization = polarization.value_or("");
        o.burst = burst.value_or(0);
        if (burst && *burst < 1) throw ConfigError("must be 1 or more (bursts are numbered from 1)", "--burst");
        o.radiometry = radiometry_;
        o.remove_noise = noise_removal;
        s1_ = std::make_shared<const geo::Sentinel1Image>(geo::Sentinel1Image::Open(path, o));
      } else {
        OpenNisar(path, swath, burst, polarization, noise_removal, frequency);
      }
    } catch (const Error& e) {
      RethrowWithParameterNames(e);
    }
  }

  int rows() const { return s1_ ? s1_->window().lines : nisar_->rows(); }
  int cols() const { return s1_ ? s1_->window().samples : nisar_->cols(); }
  bool is_complex() const {
    return radiometry_ == geo::Sentinel1Radiometry::kNone && (!s1_ || s1_->measurement().is_complex());
  }

  py::dict Info() const {
    py::dict info;
    info["rows"] = rows();
    info["cols"] = cols();
    info["dtype"] = is_complex() ? "complex64" : "float32";
    const std::string radiometry = geo::ToString(radiometry_);
    py::dict attrs;
    attrs["look_side"] = sensor::ToString(sensor::LookSideOf(s1_ ? s1_->annotation().look_left : nisar_->look_left));
    attrs["radiometry"] = radiometry;
    std::vector<int64_t> time_ns(static_cast<size_t>(rows()));
    if (s1_) {
      const geo::Sentinel1Image& s = *s1_;
      const geo::Sentinel1Annotation& a = s.annotation();
      const geo::Sentinel1Window& w = s.window();
      const bool grd = a.is_grd();
      const bool swath_of_bursts = !a.bursts.empty() && s.options().burst == 0;
      info["kind"] = "sentinel1";
      info["dims"] = swath_of_bursts ? py::make_tuple("line", "pixel")
                                     : py::make_tuple("azimuth_time", grd ? "ground_range" : "slant_range");
      std::vector<int> lines(size_t(w.lines)), pixels(size_t(w.samples));
      for (int r = 0; r < w.lines; ++r) {
        lines[size_t(r)] = w.first_line + r;
        time_ns[size_t(r)] = NanosecondsOf(s.product().epoch_unix_s, geo::Sentinel1LineTime(a, w.first_line + r));
      }
      std::vector<double> range(size_t(w.samples));
      for (int c = 0; c < w.samples; ++c) {
        pixels[size_t(c)] = w.first_sample + c;
        const double j = double(w.first_sample + c);
        range[size_t(c)] = grd ? j * a.range_pixel_spacing_m
                               : a.SlantRangeOfTime(a.slant_range_time_s) + j * a.slant_range_spacing_m();
      }
      info["line"] = py::array_t<int32_t>(py::ssize_t(lines.size()), lines.data());
      info["pixel"] = py::array_t<int32_t>(py::ssize_t(pixels.size()), pixels.data());
      info[grd ? "ground_range_m" : "slant_range_m"] = py::array_t<double>(py::ssize_t(range.size()), range.data());
      const std::string mission = a.mission.empty() ? s.product().mission : a.mission;
      attrs["sensor"] = "Sentinel-1" + (mission.size() == 3 ? mission.substr(2) : std::string());
      attrs["mission"] = mission;
      attrs["product"] = s.product().name;
      attrs["product_type"] = a.product_type;
      attrs["mode"] = s.product().mode;
      attrs["swath"] = a.swath;
      if (s.options().burst != 0) attrs["burst"] = s.options().burst;
      attrs["polarization"] = a.polarization;
      attrs["orbit_pass"] = a.pass;
      attrs["wavelength_m"] = a.wavelength_m;
      attrs["azimuth_time_interval_s"] = a.azimuth_time_interval_s;
      attrs["azimuth_spacing_m"] = a.azimuth_pixel_spacing_m;
      if (grd) {
        attrs["ground_range_spacing_m"] = a.range_pixel_spacing_m;
      } else {
        attrs["range_spacing_m"] = a.slant_range_spacing_m();
      }
      attrs["noise_removal"] = int(s.options().remove_noise);
      py::list sources;
      sources.append(s.product().name + "/" + s.entry().annotation_file);
      sources.append(s.measurement().file());
      if (s.calibration()) sources.append(s.calibration()->file);
      if (s.noise()) sources.append(s.noise()->file);
      attrs["source_files"] = sources;
      std::string nodata = "NaN: DN = 0 (ESA's fill value)";
      if (!a.bursts.empty()) nodata += "; samples outside the burst's valid window (firstValidSample..lastValidSample)";
      if (radiometry_ != geo::Sentinel1Radiometry::kNone) {
        const char* lut = radiometry_ == geo::Sentinel1Radiometry::kSigma0  ? "sigmaNought"
                          : radiometry_ == geo::Sentinel1Radiometry::kBeta0 ? "betaNought"
                                                                             : "gamma";
        std::string text = radiometry + " = ";
        text += s.noise() ? "(|DN|^2 - N) / A^2" : "|DN|^2 / A^2";
        text += ", A = " + std::string(lut) + " of " + s.calibration()->file +
                ", bilinear in line and pixel (ESA)";
        if (s.noise()) {
          text += "; N = noiseRangeLut x noiseAzimuthLut of " + s.noise()->file;
          nodata += "; |DN|^2 - N < 0";
        }
        attrs["calibration"] = text;
      }
      attrs["nodata"] = nodata;
    } else {
      const geo::RslcProduct& p = *nisar_;
      info["kind"] = "nisar";
      info["dims"] = py::make_tuple("azimuth_time", "slant_range");
      const double epoch = ParseUtcSeconds(p.epoch_utc, p.path);
      for (int r = 0; r < p.rows(); ++r) time_ns[size_t(r)] = NanosecondsOf(epoch, p.zero_doppler_time_s[size_t(r)]);
      info["slant_range_m"] = py::array_t<double>(py::ssize_t(p.cols()), p.slant_range_m.data());
      attrs["sensor"] = p.mission.empty() ? "NISAR-format RSLC" : p.mission;
      attrs["mission"] = p.mission;
      attrs["product"] = std::filesystem::path(p.path).filename().string();
      attrs["product_type"] = "RSLC";
      attrs["frequency"] = p.frequency;
      attrs["polarization"] = p.polarization;
      attrs["wavelength_m"] = p.wavelength_m;
      attrs["azimuth_time_interval_s"] = p.azimuth_spacing_s();
      attrs["range_spacing_m"] = p.range_spacing_m();
      attrs["noise_removal"] = 0;
      py::list sources;
      sources.append(p.path);
      attrs["source_files"] = sources;
      if (radiometry_ == geo::Sentinel1Radiometry::kBeta0) {
        attrs["calibration"] = "beta0 = LUT x |DN|^2, LUT " + p.beta0_lut->dataset +
                               " (bilinear in zero-Doppler time and slant range)";
      }
      attrs["nodata"] = "NaN: non-finite samples as stored";
    }
    info["azimuth_time_ns"] = py::array_t<int64_t>(py::ssize_t(time_ns.size()), time_ns.data());
    info["name"] = radiometry_ != geo::Sentinel1Radiometry::kNone ? radiometry
                   : is_complex()                                 ? "slc"
                                                                  : "amplitude";
    info["long_name"] = radiometry_ != geo::Sentinel1Radiometry::kNone
                            ? radiometry + " (linear power)"
                            : (is_complex() ? "complex digital number (uncalibrated SLC)"
                                            : "amplitude digital number (uncalibrated)");
    info["attrs"] = attrs;
    return info;
  }

  // Rows [row, row + rows) x columns [col, col + cols) of the opened window.
  py::array Read(int row, int nrows, int col, int ncols) const {
    if (row < 0 || col < 0 || nrows < 0 || ncols < 0 || int64_t(row) + nrows > rows() ||
        int64_t(col) + ncols > cols()) {
      throw InputError("window outside the " + std::to_string(rows()) + " x " + std::to_string(cols()) + " image",
                       "gissar.open_product");
    }
    const double pixels = double(nrows) * double(ncols);
    const double bytes = pixels * (is_complex() ? 16.0 : 12.0);  // the DN read and the result
    const int64_t limit = DefaultMemoryLimitBytes();
    if (bytes > double(limit)) {
      throw ConfigError("reading " + std::to_string(nrows) + " x " + std::to_string(ncols) + " pixels needs about " +
                            FormatBytes(bytes) + ", over the memory limit of " + FormatBytes(double(limit)) +
                            "; select a smaller window first (isel/sel or [...] on the variable)",
                        "gissar.open_product");
    }
    if (is_complex()) {
      std::vector<std::complex<float>> v;
      {
        py::gil_scoped_release release;
        v = ReadComplex(row, nrows, col, ncols);
      }
      return Owning(std::move(v), nrows, ncols);
    }
    std::vector<float> v;
    {
      py::gil_scoped_release release;
      v = ReadFloat(row, nrows, col, ncols);
    }
    return Owning(std::move(v), nrows, ncols);
  }

 private:
  // A NumPy array that owns `v` (no copy of a large read).
  template <typename T>
  static py::array_t<T> Owning(std::vector<T>&& v, int nrows, int ncols) {
    auto* heap = new std::vector<T>(std::move(v));
    py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>({nrows, ncols}, heap->data(), owner);
  }

  static int64_t NanosecondsOf(double epoch_unix_s, double t_s) {
    const double whole = std::floor(epoch_unix_s);
    return int64_t(whole) * 1000000000LL + std::llround((epoch_unix_s - whole + t_s) * 1e9);
  }

  // The readers name CLI flags; open_product's parameters have Python names,
  // and an error about one of them is a bad argument (ConfigError).
  [[noreturn]] static void RethrowWithParameterNames(const Error& e) {
    static const std::pair<const char*, const char*> kNames[] = {
        {"--swath/--polarization", "swath/polarization"}, {"--swath", "swath"}, {"--burst", "burst"},
        {"--polarization", "polarization"}, {"--radiometry", "radiometry"}, {"--noise-removal", "noise_removal"},
        {"--frequency", "frequency"}};
    std::string message = e.message(), where = e.where();
    bool argument = false;
    for (const auto& [flag, name] : kNames) {
      if (where.rfind(flag, 0) == 0) argument = true;
      for (std::string* s : {&message, &where}) {
        for (size_t at = s->find(flag); at != std::string::npos; at = s->find(flag, at + std::strlen(name))) {
          s->replace(at, std::strlen(flag), name);
        }
      }
    }
    if (argument || dynamic_cast<const ConfigError*>(&e) != nullptr) throw ConfigError(message, where);
    if (dynamic_cast<const IoError*>(&e) != nullptr) throw IoError(message, where);
    if (dynamic_cast<const InputError*>(&e) != nullptr) throw InputError(message, where);
    throw Error(message, where);
  }

  void OpenNisar(const std::string& path, const std::optional<std::string>& swath, const std::optional<int>& burst,
                 const std::optional<std::string>& polarization, bool noise_removal,
                 const std::optional<std::string>& frequency) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw InputError("product does not exist", path);
    if (swath) throw ConfigError("a NISAR product has no swaths (Sentinel-1 only)", "--swath");
    if (burst) throw ConfigError("a NISAR product has no bursts (Sentinel-1 IW/EW only)", "--burst");
    if (noise_removal) throw ConfigError("no thermal noise LUT is read from NISAR products", "--noise-removal");
    if (radiometry_ == geo::Sentinel1Radiometry::kSigma0 || radiometry_ == geo::Sentinel1Radiometry::kGamma0) {
      throw ConfigError(std::string("a NISAR RSLC is calibrated to beta0 only (its beta0 LUT); ") +
                            geo::ToString(radiometry_) + " needs the incidence angle of every pixel",
                        "--radiometry");
    }
    geo::RslcReadOptions o;
    o.frequency = frequency.value_or("A");
    for (char& c : o.frequency) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    o.read_amplitude = false;
    o.read_complex = false;
    std::string pol = polarization.value_or("");
    for (char& c : pol) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    const auto no_layer = [](const InputError& e) {
      return e.message().rfind("product has no dataset", 0) == 0 &&
             e.message().find("polarisations stored") != std::string::npos;
    };
    const auto read = [&](const geo::RslcReadOptions& options) {
      try {
        return geo::ReadRslcProduct(path, options);
      } catch (const InputError& e) {
        if (e.message().rfind("product has no frequency band", 0) == 0) throw ConfigError(e.message(), "--frequency");
        throw;
      }
    };
    if (pol.empty()) {  // the first layer stored, in the order HH, VV, HV, VH
      std::string stored;
      for (const char* candidate : {"HH", "VV", "HV", "VH"}) {
        o.polarization = candidate;
        try {
          read(o);
          pol = candidate;
          break;
        } catch (const InputError& e) {
          if (!no_layer(e)) throw;
          stored = e.message();
        }
      }
      if (pol.empty()) throw InputError(stored, path);
    }
    o.polarization = pol;
    o.read_complex = true;
    o.read_calibration = radiometry_ == geo::Sentinel1Radiometry::kBeta0;
    o.max_bytes = DefaultMemoryLimitBytes();
    o.bytes_per_pixel = 8.0;
    try {
      nisar_ = std::make_shared<const geo::RslcProduct>(read(o));
    } catch (const InputError& e) {
      if (no_layer(e)) {
        const std::string m = e.message();
        throw ConfigError("polarization " + pol + " is not stored in " + path + m.substr(m.find(" (polarisations")),
                          "--polarization");
      }
      if (e.message().rfind("product has no frequency band", 0) == 0) throw ConfigError(e.message(), "--frequency");
      throw;
    }
    if (o.read_calibration && !nisar_->beta0_lut) {
      throw ConfigError("the product states no beta0 calibration (no metadata/calibrationInformation/geometry/beta0); "
                        "open it with radiometry=None for the uncalibrated SLC",
                        "--radiometry");
    }
  }

  std::vector<std::complex<float>> ReadComplex(int row, int nrows, int col, int ncols) const {
    if (s1_) {
      const geo::Sentinel1Window& w = s1_->window();
      return s1_->ReadDn({w.first_line + row, w.first_sample + col, nrows, ncols});
    }
    std::vector<std::complex<float>> out(size_t(nrows) * size_t(ncols));
    for (int r = 0; r < nrows; ++r) {
      const auto* src = nisar_->slc.data() + size_t(row + r) * size_t(nisar_->cols()) + size_t(col);
      std::copy(src, src + ncols, out.data() + size_t(r) * size_t(ncols));
    }
    return out;
  }

  std::vector<float> ReadFloat(int row, int nrows, int col, int ncols) const {
    if (s1_) {
      const geo::Sentinel1Window& w = s1_->window();
      return s1_->ReadFloat({w.first_line + row, w.first_sample + col, nrows, ncols});
    }
    const std::vector<std::complex<float>> dn = ReadComplex(row, nrows, col, ncols);
    std::vector<float> out(dn.size());
    const geo::RslcProduct& p = *nisar_;
    for (int r = 0; r < nrows; ++r) {
      for (int c = 0; c < ncols; ++c) {
        const size_t k = size_t(r) * size_t(ncols) + size_t(c);
        const double power = double(dn[k].real()) * dn[k].real() + double(dn[k].imag()) * dn[k].imag();
        out[k] = static_cast<float>(
            power * p.beta0_lut->At(p.zero_doppler_time_s[size_t(row + r)], p.slant_range_m[size_t(col + c)]));
      }
    }
    return out;
  }

  geo::Sentinel1Radiometry radiometry_ = geo::Sentinel1Radiometry::kNone;
  std::shared_ptr<const geo::Sentinel1Image> s1_;
  std::shared_ptr<const geo::RslcProduct> nisar_;
};

void WritePngArray(const std::string& path, const py::array_t<uint8_t, py::array::c_style | py::array::forcecast>& a) {
  int channels = 1;
  if (a.ndim() == 3 && (a.shape(2) == 3 || a.shape(2) == 4)) channels = static_cast<int>(a.shape(2));
  else if (a.ndim() != 2) throw InputError("expected (H, W) grey or (H, W, 3|4) RGB(A) uint8", path);
  if (a.shape(0) < 1 || a.shape(1) < 1) throw InputError("empty image", path);
  const std::vector<uint8_t> data(a.data(), a.data() + a.size());
  const int width = static_cast<int>(a.shape(1)), height = static_cast<int>(a.shape(0));
  py::gil_scoped_release release;
  AtomicOutputs outputs;
  geo::WritePng(outputs.Add(path), data, width, height, channels);
  outputs.Commit();
}

}  // namespace

void BindGeo(py::module_& m) {
  py::class_<OpenedProduct, std::shared_ptr<OpenedProduct>>(m, "_OpenedProduct",
                                                             "A product opened by gissar.open_product (internal).")
      .def(py::init<const std::string&, const std::optional<std::string>&, const std::optional<int>&,
                    const std::optional<std::string>&, const std::optional<std::string>&, bool,
                    const std::optional<std::string>&>(),
           py::arg("path"), py::arg("swath") = py::none(), py::arg("burst") = py::none(),
           py::arg("polarization") = py::none(), py::arg("radiometry") = py::none(),
           py::arg("noise_removal") = false, py::arg("frequency") = py::none())
      .def("info", &OpenedProduct::Info,
           "Shape, dtype, variable name, dims, coordinates (azimuth_time_ns, line, pixel, slant_range_m or "
           "ground_range_m) and attributes.")
      .def("read", &OpenedProduct::Read, py::arg("row"), py::arg("rows"), py::arg("col"), py::arg("cols"),
           "Rows x cols of the image from (row, col): complex64 DN or float32 (amplitude DN or calibrated power), NaN "
           "no-data.");
  m.def("write_png", &WritePngArray, py::arg("path"), py::arg("image"),
        "Write an (H, W) grey or (H, W, 3|4) RGB(A) uint8 array as PNG (all-or-nothing: temporary name + rename).");
}

}  // namespace gissar::python
