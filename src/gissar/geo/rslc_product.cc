#include "gissar/geo/rslc_product.h"

#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <sstream>

#include "gissar/geo/look_side.h"
#include "gissar/util/error.h"
#include "gissar/util/isolated_call.h"
#include "gissar/util/utc_time.h"
#include "gissar/util/memory_limit.h"

namespace gissar::geo {
namespace fs = std::filesystem;

namespace {

// RAII owner of an HDF5 identifier.
class H5Id {
 public:
  H5Id() = default;
  H5Id(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  H5Id(const H5Id&) = delete;
  H5Id& operator=(const H5Id&) = delete;
  H5Id(H5Id&& o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = -1; }
  H5Id& operator=(H5Id&& o) noexcept {
    if (this != &o) {
      Reset();
      id_ = o.id_;
      close_ = o.close_;
      o.id_ = -1;
    }
    return *this;
  }
  ~H5Id() { Reset(); }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

 private:
  void Reset() {
    if (id_ >= 0 && close_ != nullptr) close_(id_);
    id_ = -1;
  }
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

// Silences HDF5's automatic error stack printing for the reader's lifetime.
class QuietHdf5 {
 public:
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

class Reader {
 public:
  Reader(const fs::path& path, int64_t max_bytes = 0) : file_(path.string()), max_bytes_(max_bytes) {}

  // True when every component of the absolute `path` exists.
  bool Exists(hid_t file, const std::string& path) const {
    size_t pos = 1;
    while (true) {
      const size_t next = path.find('/', pos);
      const std::string prefix = path.substr(0, next);
      if (H5Lexists(file, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
      if (next == std::string::npos) return true;
      pos = next + 1;
    }
  }

  H5Id OpenDataset(hid_t file, const std::string& path) const {
    if (!Exists(file, path)) throw InputError("product has no dataset " + path, file_);
    H5Id ds(H5Dopen2(file, path.c_str(), H5P_DEFAULT), H5Dclose);
    if (!ds.valid()) throw InputError("cannot open dataset " + path, file_);
    return ds;
  }

  std::vector<hsize_t> Shape(hid_t ds) const {
    H5Id space(H5Dget_space(ds), H5Sclose);
    const int rank = H5Sget_simple_extent_ndims(space.get());
    std::vector<hsize_t> dims(std::max(rank, 0));
    if (rank > 0) H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
    return dims;
  }

  std::vector<double> Doubles(hid_t file, const std::string& path, size_t expected_columns = 0) const {
    H5Id ds = OpenDataset(file, path);
    const std::vector<hsize_t> dims = Shape(ds.get());
    double n_values = 1.0;
    for (hsize_t d : dims) n_values *= double(d);
    if (max_bytes_ > 0) {
      CheckMemoryBudget(8.0 * n_values, max_bytes_, "dataset " + path + " of " + std::to_string(int64_t(n_values)) +
                            " values (" + file_ + ")",
                        "use a smaller product");
    }
    size_t n = 1;
    for (hsize_t d : dims) n *= d;
    if (expected_columns > 0 && (dims.size() != 2 || dims[1] != expected_columns)) {
      throw InputError("dataset " + path + " must have " + std::to_string(expected_columns) + " columns", file_);
    }
    H5Id type(H5Dget_type(ds.get()), H5Tclose);
    const H5T_class_t cls = H5Tget_class(type.get());
    if (cls != H5T_FLOAT && cls != H5T_INTEGER) throw InputError("dataset " + path + " is not numeric", file_);
    // libhdf5 converts through a buffer of n stored values: a corrupt
    // element size (gigabytes) is refused first.
    if (H5Tget_size(type.get()) > 16) {
      throw InputError("dataset " + path + " has " + std::to_string(H5Tget_size(type.get())) + "-byte numbers", file_);
    }
    std::vector<double> values(n);
    if (n > 0 && H5Dread(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0) {
      throw InputError("cannot read dataset " + path, file_);
    }
    for (double v : values) {
      if (!std::isfinite(v)) throw InputError("dataset " + path + " holds non-finite values", file_);
    }
    return values;
  }

  double Scalar(hid_t file, const std::string& path) const {
    const std::vector<double> v = Doubles(file, path);
    if (v.size() != 1) throw InputError("dataset " + path + " must be a scalar", file_);
    return v[0];
  }

  // Strings of a string dataset or attribute (`attribute` non-empty).
  std::vector<std::string> Strings(hid_t object, const std::string& what, bool is_attribute) const {
    H5Id type(is_attribute ? H5Aget_type(object) : H5Dget_type(object), H5Tclose);
    if (H5Tget_class(type.get()) != H5T_STRING) throw InputError(what + " is not a string", file_);
    H5Id space(is_attribute ? H5Aget_space(object) : H5Dget_space(object), H5Sclose);
    const hssize_t n = std::max<hssize_t>(1, H5Sget_simple_extent_npoints(space.get()));
    // Metadata strings are short: a corrupt count or size (gigabytes from a
    // 15 KB file) is refused before the buffer is allocated.
    constexpr uint64_t kMaxStringBytes = uint64_t{64} << 20;
    const uint64_t fixed_size = H5Tis_variable_str(type.get()) > 0 ? sizeof(char*) : H5Tget_size(type.get());
    if (uint64_t(n) > kMaxStringBytes / std::max<uint64_t>(fixed_size, 1)) {
      throw InputError(what + " declares " + std::to_string(n) + " strings of " + std::to_string(fixed_size) +
                           " bytes (over 64 MiB): not a NISAR RSLC or a corrupt file",
                       file_);
    }
    std::vector<std::string> out;
    if (H5Tis_variable_str(type.get()) > 0) {
      H5Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(mem.get(), H5T_VARIABLE);
      H5Tset_cset(mem.get(), H5Tget_cset(type.get()));
      std::vector<char*> ptrs(n, nullptr);
      const herr_t status = is_attribute ? H5Aread(object, mem.get(), ptrs.data())
                                         : H5Dread(object, mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data());
      if (status < 0) throw InputError("cannot read " + what, file_);
      for (char* p : ptrs) out.emplace_back(p != nullptr ? p : "");
      H5Dvlen_reclaim(mem.get(), space.get(), H5P_DEFAULT, ptrs.data());
    } else {
      const size_t size = H5Tget_size(type.get());
      std::vector<char> buffer(size * n + 1, '\0');
      const herr_t status = is_attribute ? H5Aread(object, type.get(), buffer.data())
                                         : H5Dread(object, type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data());
      if (status < 0) throw InputError("cannot read " + what, file_);
      for (hssize_t i = 0; i < n; ++i) {
        std::string s(buffer.data() + i * size, size);
        s = s.substr(0, s.find('\0'));
        while (!s.empty() && s.back() == ' ') s.pop_back();
        out.push_back(s);
      }
    }
    return out;
  }

  std::string String(hid_t file, const std::string& path) const {
    H5Id ds = OpenDataset(file, path);
    const std::vector<std::string> v = Strings(ds.get(), "dataset " + path, false);
    if (v.empty()) throw InputError("dataset " + path + " is empty", file_);
    return v[0];
  }

  // The "units" attribute of a dataset ("" when absent).
  std::string Units(hid_t file, const std::string& path) const {
    H5Id ds = OpenDataset(file, path);
    if (H5Aexists(ds.get(), "units") <= 0) return "";
    H5Id attr(H5Aopen(ds.get(), "units", H5P_DEFAULT), H5Aclose);
    if (!attr.valid()) return "";
    const std::vector<std::string> v = Strings(attr.get(), "units of " + path, true);
    return v.empty() ? "" : v[0];
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
  int64_t max_bytes_ = 0;
};

// Seconds since the Unix epoch of the "seconds since YYYY-MM-DD[ T]hh:mm:ss[.f]"
// units of a time dataset, and the epoch text.
double EpochSeconds(const std::string& units, const std::string& where, std::string* epoch_text) {
  const std::string prefix = "seconds since ";
  if (units.rfind(prefix, 0) != 0) {
    throw InputError("time units must read 'seconds since <UTC date>', got '" + units + "'", where);
  }
  const std::string text = units.substr(prefix.size());
  double seconds = 0.0;
  try {
    seconds = ParseUtcSeconds(text, where);
  } catch (const InputError&) {
    throw InputError("cannot parse the epoch of time units '" + units + "'", where);
  }
  if (epoch_text != nullptr) {
    *epoch_text = text;
    if (epoch_text->size() > 10 && (*epoch_text)[10] == 'T') (*epoch_text)[10] = ' ';
  }
  return seconds;
}

void CheckUniformIncreasing(const std::vector<double>& v, const std::string& name, const std::string& where) {
  if (v.size() < 2) throw InputError(name + " needs at least 2 samples", where);
  const double step = (v.back() - v.front()) / double(v.size() - 1);
  if (!(step > 0.0)) throw InputError(name + " is not increasing", where);
  for (size_t i = 1; i < v.size(); ++i) {
    const double expected = v.front() + step * double(i);
    if (!(v[i] > v[i - 1]) || std::abs(v[i] - expected) > 1e-6 * std::abs(step) * double(v.size()) +
                                                             1e-9 * std::abs(expected)) {
      throw InputError(name + " is not uniformly spaced (sample " + std::to_string(i) + ")", where);
    }
  }
}

std::vector<Eigen::Vector3d> Rows3(const std::vector<double>& v) {
  std::vector<Eigen::Vector3d> out(v.size() / 3);
  for (size_t i = 0; i < out.size(); ++i) out[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
  return out;
}

}  // namespace

double RslcProduct::azimuth_spacing_s() const {
  return rows() > 1 ? (zero_doppler_time_s.back() - zero_doppler_time_s.front()) / (rows() - 1) : 0.0;
}

double RslcProduct::range_spacing_m() const {
  return cols() > 1 ? (slant_range_m.back() - slant_range_m.front()) / (cols() - 1) : 0.0;
}

namespace {

// How much of the SLC layer ReadInProcess reads.
enum class LayerRead {
  kAsAsked,    // what RslcReadOptions asks (amplitude and/or complex, or nothing)
  kEdgeLines,  // only its first and last lines (the probe: they walk the chunk index)
};

// The probe's limit: metadata and two lines take milliseconds, a hang
// (a corrupt B-tree cycling) takes forever.
constexpr double kProbeTimeoutS = 120.0;

// Held by every use of libhdf5 here: no other thread of ours is inside the
// library when the probe forks (the child would wait for its lock forever).
std::mutex& Hdf5Mutex() {
  static std::mutex mutex;
  return mutex;
}

// The open product file and the reader of its datasets.
struct RslcFile {
  const Reader& r;
  hid_t f;
  const std::string& where;
};

// The product's root group /science/<band>/{SLC|RSLC} (LSAR or SSAR, older
// or newer product name) and its band group /science/<band>.
std::pair<std::string, std::string> FindProductRoot(const RslcFile& file) {
  const auto& [r, f, where] = file;
  std::string band_root, root;
  for (const char* band : {"LSAR", "SSAR"}) {
    for (const char* group : {"SLC", "RSLC"}) {
      const std::string candidate = std::string("/science/") + band + "/" + group;
      if (root.empty() && r.Exists(f, candidate)) {
        band_root = std::string("/science/") + band;
        root = candidate;
      }
    }
  }
  if (root.empty()) throw InputError("not a NISAR RSLC product: no /science/LSAR/SLC (or RSLC) group", where);
  return {band_root, root};
}

// Mission, product version and look side.
void ReadIdentification(const RslcFile& file, const std::string& band_root, RslcProduct& p) {
  const auto& [r, f, where] = file;
  const std::string ident = band_root + "/identification";
  if (r.Exists(f, ident + "/missionId")) p.mission = r.String(f, ident + "/missionId");
  if (r.Exists(f, ident + "/productVersion")) p.product_version = r.String(f, ident + "/productVersion");
  std::string look = r.String(f, ident + "/lookDirection");
  std::transform(look.begin(), look.end(), look.begin(), [](unsigned char c) { return std::tolower(c); });
  const std::optional<LookSide> side = kLookSides.Find(look);
  if (!side) throw InputError("lookDirection must be " + kLookSides.Alternatives() + ", got '" + look + "'", where);
  p.look_left = *side == LookSide::kLeft;
}

// The radar grid of frequency group `freq`: zero-Doppler times, slant
// ranges (checked against the memory budget), centre frequency, processed
// bandwidths and listed polarisations. Returns the epoch of the grid's
// times (seconds since the Unix epoch), the times of everything else being
// taken to it.
double ReadRadarGrid(const RslcFile& file, const std::string& swaths, const std::string& freq,
                     const RslcReadOptions& options, RslcProduct& p) {
  const auto& [r, f, where] = file;
  const std::string time_path = swaths + "/zeroDopplerTime";
  p.zero_doppler_time_s = r.Doubles(f, time_path);
  const double epoch = EpochSeconds(r.Units(f, time_path), where + ":" + time_path, &p.epoch_utc);
  CheckUniformIncreasing(p.zero_doppler_time_s, "zeroDopplerTime", where);
  p.slant_range_m = r.Doubles(f, freq + "/slantRange");
  CheckUniformIncreasing(p.slant_range_m, "slantRange", where);
  if (!(p.slant_range_m.front() > 0.0)) throw InputError("slant ranges must be positive", where);
  if (options.max_bytes > 0) {
    CheckMemoryBudget(options.bytes_per_pixel * double(p.rows()) * double(p.cols()), options.max_bytes,
                      "product grid of " + std::to_string(p.rows()) + " x " + std::to_string(p.cols()) + " pixels (" +
                          where + ")",
                      "crop the product");
  }
  p.center_frequency_hz = r.Scalar(f, freq + "/processedCenterFrequency");
  if (!(p.center_frequency_hz > 1e6 && p.center_frequency_hz < 1e12)) {
    throw InputError("processedCenterFrequency out of range (1 MHz .. 1 THz)", where);
  }
  p.wavelength_m = kSpeedOfLightMps / p.center_frequency_hz;
  // Optional: the processed bandwidths (NaN when absent or not positive).
  auto stated_bandwidth = [&](const std::string& path) {
    if (!r.Exists(f, path)) return std::numeric_limits<double>::quiet_NaN();
    const double v = r.Scalar(f, path);
    return v > 0.0 ? v : std::numeric_limits<double>::quiet_NaN();
  };
  p.processed_range_bandwidth_hz = stated_bandwidth(freq + "/processedRangeBandwidth");
  p.processed_azimuth_bandwidth_hz = stated_bandwidth(freq + "/processedAzimuthBandwidth");
  if (r.Exists(f, freq + "/listOfPolarizations")) {
    H5Id ds = r.OpenDataset(f, freq + "/listOfPolarizations");
    p.polarizations = r.Strings(ds.get(), "listOfPolarizations", false);
  }
  return epoch;
}

// The orbit's state vectors, their times taken to `epoch`; they must cover
// the grid's times.
void ReadOrbit(const RslcFile& file, const std::string& root, double epoch, RslcProduct& p) {
  const auto& [r, f, where] = file;
  const std::string orbit = root + "/metadata/orbit";
  if (!r.Exists(f, orbit + "/time") || !r.Exists(f, orbit + "/position") || !r.Exists(f, orbit + "/velocity")) {
    throw InputError("product has no orbit (" + orbit + "/{time,position,velocity})", where);
  }
  p.orbit.time_s = r.Doubles(f, orbit + "/time");
  const double orbit_epoch = EpochSeconds(r.Units(f, orbit + "/time"), where + ":" + orbit + "/time", nullptr);
  for (double& t : p.orbit.time_s) t += orbit_epoch - epoch;
  p.orbit.position_m = Rows3(r.Doubles(f, orbit + "/position", 3));
  p.orbit.velocity_mps = Rows3(r.Doubles(f, orbit + "/velocity", 3));
  if (r.Exists(f, orbit + "/orbitType")) p.orbit.type = r.String(f, orbit + "/orbitType");
  const size_t n_sv = p.orbit.time_s.size();
  if (n_sv < 4) throw InputError("orbit needs at least 4 state vectors, has " + std::to_string(n_sv), where);
  if (p.orbit.position_m.size() != n_sv || p.orbit.velocity_mps.size() != n_sv) {
    throw InputError("orbit time, position and velocity differ in length", where);
  }
  for (size_t i = 1; i < n_sv; ++i) {
    if (!(p.orbit.time_s[i] > p.orbit.time_s[i - 1])) throw InputError("orbit times are not increasing", where);
  }
  if (p.orbit.time_s.front() > p.zero_doppler_time_s.front() || p.orbit.time_s.back() < p.zero_doppler_time_s.back()) {
    throw InputError("orbit does not cover the image's azimuth times", where);
  }
}

// The attitude quaternions and Euler angles, when the product has them.
void ReadAttitude(const RslcFile& file, const std::string& root, double epoch, RslcProduct& p) {
  const auto& [r, f, where] = file;
  const std::string att = root + "/metadata/attitude";
  if (r.Exists(f, att + "/time") && r.Exists(f, att + "/quaternions")) {
    p.attitude.time_s = r.Doubles(f, att + "/time");
    const double att_epoch = EpochSeconds(r.Units(f, att + "/time"), where + ":" + att + "/time", nullptr);
    for (double& t : p.attitude.time_s) t += att_epoch - epoch;
    const std::vector<double> q = r.Doubles(f, att + "/quaternions", 4);
    for (size_t i = 0; i + 3 < q.size(); i += 4) p.attitude.quaternion.emplace_back(q[i], q[i + 1], q[i + 2], q[i + 3]);
    if (r.Exists(f, att + "/eulerAngles")) p.attitude.euler_deg = Rows3(r.Doubles(f, att + "/eulerAngles", 3));
  }
}

// The beta0 calibration LUT, when the product has one: its axes (times
// taken to `epoch`) must match its shape and increase, its values be > 0.
std::optional<RslcCalibrationLut> ReadBeta0Lut(const RslcFile& file, const std::string& root, double epoch) {
  const auto& [r, f, where] = file;
  const std::string cal = root + "/metadata/calibrationInformation";
  const std::string values_path = cal + "/geometry/beta0";
  if (!r.Exists(f, values_path)) return std::nullopt;
  RslcCalibrationLut lut;
  lut.dataset = values_path;
  std::string axes = cal + "/geometry";
  if (!r.Exists(f, axes + "/zeroDopplerTime") || !r.Exists(f, axes + "/slantRange")) axes = cal;
  const std::string t_path = axes + "/zeroDopplerTime", r_path = axes + "/slantRange";
  if (!r.Exists(f, t_path) || !r.Exists(f, r_path)) {
    throw InputError("calibration LUT " + values_path + " has no zeroDopplerTime/slantRange axes", where);
  }
  lut.time_s = r.Doubles(f, t_path);
  const double lut_epoch = EpochSeconds(r.Units(f, t_path), where + ":" + t_path, nullptr);
  for (double& t : lut.time_s) t += lut_epoch - epoch;
  lut.slant_range_m = r.Doubles(f, r_path);
  H5Id lut_ds = r.OpenDataset(f, values_path);
  const std::vector<hsize_t> lut_dims = r.Shape(lut_ds.get());
  if (lut_dims.size() != 2 || lut_dims[0] != lut.time_s.size() || lut_dims[1] != lut.slant_range_m.size()) {
    throw InputError("calibration LUT " + values_path + " does not match its " + std::to_string(lut.time_s.size()) +
                         " x " + std::to_string(lut.slant_range_m.size()) + " axes",
                     where);
  }
  if (lut.time_s.empty() || lut.slant_range_m.empty()) {
    throw InputError("calibration LUT " + values_path + " is empty", where);
  }
  for (const std::vector<double>* axis : {&lut.time_s, &lut.slant_range_m}) {
    for (size_t i = 1; i < axis->size(); ++i) {
      if (!((*axis)[i] > (*axis)[i - 1])) {
        throw InputError("axes of the calibration LUT " + values_path + " are not increasing", where);
      }
    }
  }
  lut.values = r.Doubles(f, values_path);  // non-finite values are an InputError there
  for (double v : lut.values) {
    if (!(v > 0.0)) throw InputError("calibration LUT " + values_path + " holds a value <= 0", where);
  }
  return lut;
}

// The SLC layer `layer` (the asked polarisation), which must hold the grid's
// rows x cols.
H5Id OpenSlcLayer(const RslcFile& file, const std::string& layer, const RslcProduct& p) {
  const auto& [r, f, where] = file;
  if (!r.Exists(f, layer)) {
    std::string stored;
    for (const std::string& pol : p.stored_polarizations) stored += (stored.empty() ? "" : ", ") + pol;
    throw InputError("product has no dataset " + layer + " (polarisations stored: " +
                         (stored.empty() ? std::string("none") : stored) + ")",
                     where);
  }
  H5Id ds = r.OpenDataset(f, layer);
  const std::vector<hsize_t> dims = r.Shape(ds.get());
  if (dims.size() != 2 || dims[0] != hsize_t(p.rows()) || dims[1] != hsize_t(p.cols())) {
    throw InputError("SLC layer " + layer + " does not match the " + std::to_string(p.rows()) + " x " +
                         std::to_string(p.cols()) + " radar grid",
                     where);
  }
  return ds;
}

// The memory type of a complex sample: compound {float r, float i}.
H5Id ComplexFloatType() {
  H5Id mem(H5Tcreate(H5T_COMPOUND, 2 * sizeof(float)), H5Tclose);
  H5Tinsert(mem.get(), "r", 0, H5T_NATIVE_FLOAT);
  H5Tinsert(mem.get(), "i", sizeof(float), H5T_NATIVE_FLOAT);
  return mem;
}

// The probe's read: the layer's first and last lines (they walk the chunk
// index); nothing is kept, and a layer that is not complex is left to the
// real read.
void ReadEdgeLines(hid_t ds, const RslcProduct& p) {
  H5Id type(H5Dget_type(ds), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_COMPOUND || H5Tget_nmembers(type.get()) != 2) return;
  H5Id mem = ComplexFloatType();
  std::vector<std::complex<float>> line(size_t(p.cols()));
  for (const hsize_t row : {hsize_t{0}, hsize_t(p.rows() - 1)}) {
    H5Id file_space(H5Dget_space(ds), H5Sclose);
    const hsize_t start[2] = {row, 0}, count[2] = {1, hsize_t(p.cols())};
    H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr);
    H5Id mem_space(H5Screate_simple(2, count, nullptr), H5Sclose);
    H5Dread(ds, mem.get(), mem_space.get(), file_space.get(), H5P_DEFAULT, line.data());
  }
}

// The whole complex layer, kept as amplitude and/or complex samples as the
// options ask (non-finite amplitudes become 0).
void ReadSlcSamples(hid_t ds, const std::string& layer, const RslcReadOptions& options, const std::string& where,
                    RslcProduct& p) {
  H5Id type(H5Dget_type(ds), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_COMPOUND || H5Tget_nmembers(type.get()) != 2) {
    throw InputError("SLC layer " + layer + " is not complex (compound r, i)", where);
  }
  H5Id mem = ComplexFloatType();
  std::vector<std::complex<float>> slc(size_t(p.rows()) * p.cols());
  if (H5Dread(ds, mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, slc.data()) < 0) {
    throw InputError("cannot read SLC layer " + layer + " (members must be named r and i)", where);
  }
  if (options.read_amplitude) {
    p.amplitude.resize(slc.size());
    for (size_t k = 0; k < slc.size(); ++k) {
      const float a = std::abs(slc[k]);
      p.amplitude[k] = std::isfinite(a) ? a : 0.0f;
    }
  }
  if (options.read_complex) p.slc = std::move(slc);
}

RslcProduct ReadInProcess(const fs::path& path, const RslcReadOptions& options, LayerRead layer_read) {
  const std::string where = path.string();
  QuietHdf5 quiet;
  if (H5Fis_hdf5(where.c_str()) <= 0) throw InputError("not an HDF5 file (NISAR RSLC expected)", where);
  H5Id handle(H5Fopen(where.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!handle.valid()) throw InputError("cannot open HDF5 file", where);
  const Reader r(path, options.max_bytes);
  const RslcFile file{r, handle.get(), where};
  const auto [band_root, root] = FindProductRoot(file);

  RslcProduct p;
  p.path = where;
  p.frequency = options.frequency;
  p.polarization = options.polarization;
  ReadIdentification(file, band_root, p);
  const std::string swaths = root + "/swaths";
  const std::string freq = swaths + "/frequency" + options.frequency;
  if (!r.Exists(file.f, freq)) throw InputError("product has no frequency band " + options.frequency, where);
  const double epoch = ReadRadarGrid(file, swaths, freq, options, p);
  ReadOrbit(file, root, epoch, p);
  ReadAttitude(file, root, epoch, p);
  for (const char* pol : {"HH", "HV", "VH", "VV"}) {
    if (r.Exists(file.f, freq + "/" + pol)) p.stored_polarizations.push_back(pol);
  }
  if (options.read_calibration) p.beta0_lut = ReadBeta0Lut(file, root, epoch);

  const std::string layer = freq + "/" + options.polarization;
  H5Id ds = OpenSlcLayer(file, layer, p);
  if (layer_read == LayerRead::kEdgeLines) {
    ReadEdgeLines(ds.get(), p);
  } else if (options.read_amplitude || options.read_complex) {
    ReadSlcSamples(ds.get(), layer, options, where, p);
  }
  return p;
}

}  // namespace

RslcProduct ReadRslcProduct(const fs::path& path, const RslcReadOptions& options) {
  const std::string where = path.string();
  if (options.frequency != "A" && options.frequency != "B") {
    throw ConfigError("frequency band must be A or B, got '" + options.frequency + "'", "--frequency");
  }
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError("product file not found", where);
  // libhdf5 1.10 trusts a file's internal structure: a corrupt local heap or
  // chunk index can make it read through a null pointer (fuzz_nisar_hdf5
  // found such files: tests/data/hostile_hdf5). The metadata and the
  // layer's edge lines are read first in a child process; its death becomes
  // an InputError here, the caller left alive. A child that threw, or no
  // child (fork failed), leaves the verdict to the read below.
  const std::lock_guard<std::mutex> lock(Hdf5Mutex());
  const IsolatedOutcome probe =
      RunIsolated([&] { ReadInProcess(path, options, LayerRead::kEdgeLines); }, kProbeTimeoutS);
  if (probe.kind == IsolatedOutcome::Kind::kCrashed) {
    throw InputError("the HDF5 library crashed reading this file (" + probe.Describe(kProbeTimeoutS) +
                         " in a probe process): a corrupt HDF5 file, not a readable NISAR RSLC",
                     where);
  }
  if (probe.kind == IsolatedOutcome::Kind::kTimedOut) {
    throw InputError("the HDF5 library gave " + probe.Describe(kProbeTimeoutS) +
                         " reading this file's metadata (probe process): a corrupt HDF5 file",
                     where);
  }
  return ReadInProcess(path, options, LayerRead::kAsAsked);
}

double RslcCalibrationLut::At(double time, double range) const {
  // Index and weight of `x` on an increasing axis, clamped to its ends.
  auto locate = [](const std::vector<double>& axis, double x, size_t* i0, double* w) {
    if (axis.size() < 2 || !(x > axis.front())) {
      *i0 = 0;
      *w = 0.0;
      return;
    }
    if (!(x < axis.back())) {
      *i0 = axis.size() - 2;
      *w = 1.0;
      return;
    }
    const size_t hi = size_t(std::upper_bound(axis.begin(), axis.end(), x) - axis.begin());
    *i0 = hi - 1;
    *w = (x - axis[hi - 1]) / (axis[hi] - axis[hi - 1]);
  };
  size_t it = 0, ir = 0;
  double wt = 0.0, wr = 0.0;
  locate(time_s, time, &it, &wt);
  locate(slant_range_m, range, &ir, &wr);
  const size_t nr = slant_range_m.size();
  auto v = [&](size_t i, size_t j) {
    return values[std::min(i, time_s.size() - 1) * nr + std::min(j, nr - 1)];
  };
  return (1.0 - wt) * ((1.0 - wr) * v(it, ir) + wr * v(it, ir + 1)) +
         wt * ((1.0 - wr) * v(it + 1, ir) + wr * v(it + 1, ir + 1));
}

namespace {

void WriteDoubles(hid_t loc, const std::string& name, const std::vector<double>& v, std::vector<hsize_t> dims,
                  const std::string& units, const std::string& where) {
  H5Id space(dims.empty() ? H5Screate(H5S_SCALAR) : H5Screate_simple(int(dims.size()), dims.data(), nullptr),
             H5Sclose);
  H5Id ds(H5Dcreate2(loc, name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
          H5Dclose);
  if (!ds.valid() || H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0) {
    throw IoError("cannot write dataset " + name, where);
  }
  if (!units.empty()) {
    H5Id type(H5Tcopy(H5T_C_S1), H5Tclose);
    H5Tset_size(type.get(), units.size());
    H5Id aspace(H5Screate(H5S_SCALAR), H5Sclose);
    H5Id attr(H5Acreate2(ds.get(), "units", type.get(), aspace.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (!attr.valid() || H5Awrite(attr.get(), type.get(), units.data()) < 0) {
      throw IoError("cannot write units of " + name, where);
    }
  }
}

void WriteString(hid_t loc, const std::string& name, const std::string& text, const std::string& where) {
  H5Id type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type.get(), std::max<size_t>(1, text.size()));
  H5Tset_strpad(type.get(), H5T_STR_NULLPAD);
  H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
  H5Id ds(H5Dcreate2(loc, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
  std::string padded = text.empty() ? std::string(1, '\0') : text;
  if (!ds.valid() || H5Dwrite(ds.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, padded.data()) < 0) {
    throw IoError("cannot write dataset " + name, where);
  }
}

H5Id Group(hid_t loc, const std::string& name, const std::string& where) {
  H5Id g(H5Gcreate2(loc, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  if (!g.valid()) throw IoError("cannot create group " + name, where);
  return g;
}

}  // namespace

void WriteRslcProduct(const fs::path& path, const RslcProduct& product) {
  const std::string where = path.string();
  const std::lock_guard<std::mutex> lock(Hdf5Mutex());
  QuietHdf5 quiet;
  H5Id file(H5Fcreate(where.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (!file.valid()) throw IoError("cannot create HDF5 file", where);
  const std::string units = "seconds since " + (product.epoch_utc.empty() ? "2000-01-01 00:00:00" : product.epoch_utc);
  H5Id science = Group(file.get(), "science", where);
  H5Id lsar = Group(science.get(), "LSAR", where);
  H5Id ident = Group(lsar.get(), "identification", where);
  WriteString(ident.get(), "lookDirection", std::string(kLookSides.Name(LookSideOf(product.look_left))), where);
  WriteString(ident.get(), "productVersion", product.product_version, where);
  WriteString(ident.get(), "missionId", product.mission, where);
  H5Id slc = Group(lsar.get(), "SLC", where);
  H5Id swaths = Group(slc.get(), "swaths", where);
  WriteDoubles(swaths.get(), "zeroDopplerTime", product.zero_doppler_time_s, {hsize_t(product.rows())}, units, where);
  H5Id freq = Group(swaths.get(), "frequencyA", where);
  WriteDoubles(freq.get(), "slantRange", product.slant_range_m, {hsize_t(product.cols())}, "meters", where);
  WriteDoubles(freq.get(), "processedCenterFrequency", {product.center_frequency_hz}, {}, "Hz", where);
  if (!std::isnan(product.processed_range_bandwidth_hz)) {
    WriteDoubles(freq.get(), "processedRangeBandwidth", {product.processed_range_bandwidth_hz}, {}, "Hz", where);
  }
  if (!std::isnan(product.processed_azimuth_bandwidth_hz)) {
    WriteDoubles(freq.get(), "processedAzimuthBandwidth", {product.processed_azimuth_bandwidth_hz}, {}, "Hz", where);
  }
  H5Id meta = Group(slc.get(), "metadata", where);
  if (!product.orbit.time_s.empty()) {
    H5Id orbit = Group(meta.get(), "orbit", where);
    const hsize_t n = product.orbit.time_s.size();
    std::vector<double> pos, vel;
    for (size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        pos.push_back(product.orbit.position_m[i][k]);
        vel.push_back(product.orbit.velocity_mps[i][k]);
      }
    }
    WriteDoubles(orbit.get(), "time", product.orbit.time_s, {n}, units, where);
    WriteDoubles(orbit.get(), "position", pos, {n, 3}, "meters", where);
    WriteDoubles(orbit.get(), "velocity", vel, {n, 3}, "meters per second", where);
  }
  // Complex64 layer (compound r, i) with zero phase.
  const hsize_t dims[2] = {hsize_t(product.rows()), hsize_t(product.cols())};
  H5Id space(H5Screate_simple(2, dims, nullptr), H5Sclose);
  H5Id type(H5Tcreate(H5T_COMPOUND, 2 * sizeof(float)), H5Tclose);
  H5Tinsert(type.get(), "r", 0, H5T_NATIVE_FLOAT);
  H5Tinsert(type.get(), "i", sizeof(float), H5T_NATIVE_FLOAT);
  const std::string pol = product.polarization.empty() ? "HH" : product.polarization;
  H5Id ds(H5Dcreate2(freq.get(), pol.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
          H5Dclose);
  std::vector<std::complex<float>> data(size_t(product.rows()) * product.cols(), {0.0f, 0.0f});
  for (size_t k = 0; k < data.size() && k < product.amplitude.size(); ++k) data[k] = {product.amplitude[k], 0.0f};
  if (!ds.valid() || H5Dwrite(ds.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()) < 0) {
    throw IoError("cannot write SLC layer", where);
  }
  if (H5Fflush(file.get(), H5F_SCOPE_GLOBAL) < 0) throw IoError("cannot flush HDF5 file", where);
}

}  // namespace gissar::geo
