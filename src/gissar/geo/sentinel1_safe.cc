#include "gissar/geo/sentinel1_safe.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <sstream>

#include <cpl_string.h>
#include <cpl_vsi.h>
#include <libxml/parser.h>
#include <libxml/tree.h>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"
#include "gissar/util/utc_time.h"

namespace gissar::geo {
namespace fs = std::filesystem;

namespace {

// Largest XML file read (an IW SLC annotation is ~1-2 MB; a calibration file
// a few MB): a bound against runaway inputs.
constexpr vsi_l_offset kMaxXmlBytes = 256ull << 20;

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

// Reads a whole file through GDAL's VSI layer (plain paths and /vsizip/).
std::string ReadVsiFile(const std::string& path, const std::string& where) {
  EnsureGdal();
  VSIStatBufL st;
  if (VSIStatL(path.c_str(), &st) != 0) throw InputError("file not found", where);
  if (VSI_ISDIR(st.st_mode)) throw InputError("is a directory, expected a file", where);
  GByte* bytes = nullptr;
  vsi_l_offset size = 0;
  if (!VSIIngestFile(nullptr, path.c_str(), &bytes, &size, static_cast<GIntBig>(kMaxXmlBytes))) {
    throw InputError("cannot read the file (unreadable or over " + std::to_string(kMaxXmlBytes >> 20) + " MB)",
                     where);
  }
  std::string text(reinterpret_cast<const char*>(bytes), static_cast<size_t>(size));
  VSIFree(bytes);
  return text;
}

struct DocDeleter {
  void operator()(xmlDoc* doc) const { xmlFreeDoc(doc); }
};
struct CtxtDeleter {
  void operator()(xmlParserCtxt* ctxt) const { xmlFreeParserCtxt(ctxt); }
};
using XmlDoc = std::unique_ptr<xmlDoc, DocDeleter>;

// Parses XML without network access, DTD loading or entity substitution.
XmlDoc ParseXml(const std::string& text, const std::string& file) {
  if (text.size() > static_cast<size_t>(kMaxXmlBytes)) throw InputError("XML document too large", file);
  std::unique_ptr<xmlParserCtxt, CtxtDeleter> ctxt(xmlNewParserCtxt());
  if (!ctxt) throw IoError("cannot create an XML parser", file);
  XmlDoc doc(xmlCtxtReadMemory(ctxt.get(), text.data(), static_cast<int>(text.size()), nullptr, nullptr,
                               XML_PARSE_NONET | XML_PARSE_NOERROR | XML_PARSE_NOWARNING));
  const xmlError* error = xmlCtxtGetLastError(ctxt.get());
  if (!doc || (error != nullptr && error->level >= XML_ERR_ERROR)) {
    std::string what = "malformed or truncated XML";
    if (error != nullptr && error->message != nullptr) {
      what += ": " + Trim(error->message) + " (line " + std::to_string(error->line) + ")";
    }
    throw InputError(what, file);
  }
  if (xmlDocGetRootElement(doc.get()) == nullptr) throw InputError("XML document has no root element", file);
  return doc;
}

bool IsElement(const xmlNode* n, const char* name) {
  return n != nullptr && n->type == XML_ELEMENT_NODE && xmlStrcmp(n->name, BAD_CAST name) == 0;
}

std::vector<const xmlNode*> Children(const xmlNode* parent, const char* name) {
  std::vector<const xmlNode*> out;
  if (parent == nullptr) return out;
  for (const xmlNode* c = parent->children; c != nullptr; c = c->next) {
    if (IsElement(c, name)) out.push_back(c);
  }
  return out;
}

const xmlNode* Child(const xmlNode* parent, const char* name) {
  if (parent == nullptr) return nullptr;
  for (const xmlNode* c = parent->children; c != nullptr; c = c->next) {
    if (IsElement(c, name)) return c;
  }
  return nullptr;
}

// First element named `name` anywhere below `n` (depth first).
const xmlNode* FindDeep(const xmlNode* n, const char* name) {
  for (const xmlNode* c = n == nullptr ? nullptr : n->children; c != nullptr; c = c->next) {
    if (c->type != XML_ELEMENT_NODE) continue;
    if (IsElement(c, name)) return c;
    if (const xmlNode* f = FindDeep(c, name)) return f;
  }
  return nullptr;
}

void CollectDeep(const xmlNode* n, const char* name, std::vector<const xmlNode*>& out) {
  for (const xmlNode* c = n == nullptr ? nullptr : n->children; c != nullptr; c = c->next) {
    if (c->type != XML_ELEMENT_NODE) continue;
    if (IsElement(c, name)) out.push_back(c);
    CollectDeep(c, name, out);
  }
}

std::string Content(const xmlNode* n) {
  xmlChar* c = xmlNodeGetContent(n);
  std::string s = c == nullptr ? "" : reinterpret_cast<const char*>(c);
  xmlFree(c);
  return Trim(s);
}

std::string Attribute(const xmlNode* n, const char* name) {
  xmlChar* c = xmlGetProp(n, BAD_CAST name);
  if (c == nullptr) return "";
  std::string s = reinterpret_cast<const char*>(c);
  xmlFree(c);
  return s;
}

double ParseNumber(const std::string& text, const std::string& where) {
  const std::string t = Trim(text);
  if (t.empty()) throw InputError("empty value, expected a number", where);
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (end != t.c_str() + t.size() || errno == ERANGE || !std::isfinite(v)) {
    throw InputError("not a finite number: '" + t.substr(0, 40) + "'", where);
  }
  return v;
}

int ParseInt(const std::string& text, const std::string& where) {
  const double v = ParseNumber(text, where);
  if (v != std::floor(v) || std::abs(v) > 2e9) throw InputError("not an integer: '" + Trim(text) + "'", where);
  return static_cast<int>(v);
}

// Element navigation with errors naming the file and the element path.
class Reader {
 public:
  Reader(std::string file, double epoch_unix_s) : file_(std::move(file)), epoch_unix_s_(epoch_unix_s) {}

  const std::string& file() const { return file_; }
  std::string Where(const std::string& path) const { return file_ + ": " + path; }

  // The element at `path` ("a/b/c") below `n`; InputError when absent.
  const xmlNode* Node(const xmlNode* n, const std::string& path, const std::string& base) const {
    const xmlNode* cur = n;
    std::stringstream ss(path);
    std::string part;
    while (std::getline(ss, part, '/')) {
      cur = Child(cur, part.c_str());
      if (cur == nullptr) throw InputError("missing element <" + part + ">", Where(Join(base, path)));
    }
    return cur;
  }
  std::string Text(const xmlNode* n, const std::string& path, const std::string& base) const {
    return Content(Node(n, path, base));
  }
  double Number(const xmlNode* n, const std::string& path, const std::string& base) const {
    return ParseNumber(Text(n, path, base), Where(Join(base, path)));
  }
  int Int(const xmlNode* n, const std::string& path, const std::string& base) const {
    return ParseInt(Text(n, path, base), Where(Join(base, path)));
  }
  // Seconds since the epoch of a UTC time element, keeping the fraction's
  // full precision (whole seconds and fraction are parsed apart).
  double Time(const xmlNode* n, const std::string& path, const std::string& base) const {
    return TimeOf(Text(n, path, base), Where(Join(base, path)));
  }
  double TimeOf(const std::string& text, const std::string& where) const {
    std::string t = text;
    if (!t.empty() && (t.back() == 'Z' || t.back() == 'z')) t.pop_back();
    ParseUtcSeconds(t, where);  // validates the whole text
    const size_t dot = t.find('.');
    const double whole = ParseUtcSeconds(t.substr(0, dot), where);
    double fraction = 0.0;
    if (dot != std::string::npos) fraction = ParseNumber("0" + t.substr(dot), where);
    return (whole - epoch_unix_s_) + fraction;
  }
  // A space-separated list; checks the "count" attribute when present.
  std::vector<double> Numbers(const xmlNode* n, const std::string& path, const std::string& base) const {
    const xmlNode* node = Node(n, path, base);
    const std::string where = Where(Join(base, path));
    std::vector<double> out;
    std::stringstream ss(Content(node));
    std::string item;
    while (ss >> item) out.push_back(ParseNumber(item, where));
    const std::string count = Attribute(node, "count");
    if (!count.empty() && ParseInt(count, where + "@count") != static_cast<int>(out.size())) {
      throw InputError("count=\"" + count + "\" but " + std::to_string(out.size()) + " values", where);
    }
    return out;
  }
  std::vector<int> Ints(const xmlNode* n, const std::string& path, const std::string& base) const {
    const std::vector<double> v = Numbers(n, path, base);
    std::vector<int> out;
    out.reserve(v.size());
    for (double x : v) {
      if (x != std::floor(x) || std::abs(x) > 2e9) throw InputError("not an integer list", Where(Join(base, path)));
      out.push_back(static_cast<int>(x));
    }
    return out;
  }

  static std::string Join(const std::string& a, const std::string& b) { return a.empty() ? b : a + "/" + b; }
  static std::string Item(const std::string& base, const char* name, size_t index) {
    return base + "/" + name + "[" + std::to_string(index + 1) + "]";
  }

 private:
  std::string file_;
  double epoch_unix_s_;
};

// Midnight UTC (POSIX seconds) of the day of a timestamp.
double MidnightOf(const std::string& text, const std::string& where) {
  const double s = ParseUtcSeconds(text, where);
  return std::floor(s / 86400.0) * 86400.0;
}

Sentinel1LineVectors ReadLineVectors(const Reader& r, const xmlNode* list, const std::string& list_path,
                                     const char* item_name, const char* value_name) {
  Sentinel1LineVectors v;
  const std::vector<const xmlNode*> items = Children(list, item_name);
  if (items.empty()) throw InputError(std::string("no <") + item_name + ">", r.Where(list_path));
  for (size_t i = 0; i < items.size(); ++i) {
    const std::string base = Reader::Item(list_path, item_name, i);
    v.azimuth_time_s.push_back(r.Time(items[i], "azimuthTime", base));
    v.line.push_back(r.Int(items[i], "line", base));
    std::vector<int> pixel = r.Ints(items[i], "pixel", base);
    std::vector<double> values = r.Numbers(items[i], value_name, base);
    if (pixel.empty() || pixel.size() != values.size()) {
      throw InputError(std::to_string(pixel.size()) + " pixels but " + std::to_string(values.size()) + " values",
                       r.Where(base + "/" + value_name));
    }
    for (size_t k = 1; k < pixel.size(); ++k) {
      if (pixel[k] <= pixel[k - 1]) throw InputError("pixels not strictly increasing", r.Where(base + "/pixel"));
    }
    if (i > 0 && v.line[i] < v.line[i - 1]) throw InputError("lines decreasing", r.Where(base + "/line"));
    v.pixel.push_back(std::move(pixel));
    v.values.push_back(std::move(values));
  }
  return v;
}

double InterpolateIn(const std::vector<int>& x, const std::vector<double>& y, double at) {
  if (at <= x.front()) return y.front();
  if (at >= x.back()) return y.back();
  const size_t k = static_cast<size_t>(std::upper_bound(x.begin(), x.end(), at) - x.begin());  // x[k-1] <= at < x[k]
  const double w = (at - x[k - 1]) / double(x[k] - x[k - 1]);
  return (1.0 - w) * y[k - 1] + w * y[k];
}

double Polynomial(const std::vector<double>& c, double x) {
  double v = 0.0;
  for (size_t k = c.size(); k-- > 0;) v = v * x + c[k];
  return v;
}

// (swath, polarisation) of an annotation/calibration/noise/measurement file
// name: [calibration-|noise-]<mission>-<swath>-<type>-<pol>-<start>-...
std::pair<std::string, std::string> SwathPolOf(const std::string& href) {
  std::string name = fs::path(href).filename().string();
  for (const char* prefix : {"calibration-", "noise-", "rfi-"}) {
    if (name.rfind(prefix, 0) == 0) name = name.substr(std::string(prefix).size());
  }
  std::vector<std::string> parts;
  std::stringstream ss(name);
  std::string p;
  while (std::getline(ss, p, '-')) parts.push_back(p);
  if (parts.size() < 4) return {"", ""};
  return {Upper(parts[1]), Upper(parts[3])};
}

std::string NormaliseHref(std::string href) {
  if (href.rfind("./", 0) == 0) href = href.substr(2);
  return href;
}

bool VsiExists(const std::string& path, bool* is_dir = nullptr) {
  VSIStatBufL st;
  if (VSIStatL(path.c_str(), &st) != 0) return false;
  if (is_dir != nullptr) *is_dir = VSI_ISDIR(st.st_mode);
  return true;
}

}  // namespace

double Sentinel1LineVectors::At(double at_line, double at_pixel) const {
  if (line.empty()) throw InputError("empty look-up table", "Sentinel1LineVectors");
  const size_t n = line.size();
  if (n == 1 || at_line <= line.front()) return InterpolateIn(pixel.front(), values.front(), at_pixel);
  if (at_line >= line.back()) return InterpolateIn(pixel.back(), values.back(), at_pixel);
  const size_t k = static_cast<size_t>(std::upper_bound(line.begin(), line.end(), at_line) - line.begin());
  const double a = InterpolateIn(pixel[k - 1], values[k - 1], at_pixel);
  const double b = InterpolateIn(pixel[k], values[k], at_pixel);
  const double span = double(line[k] - line[k - 1]);
  const double w = span > 0.0 ? (at_line - line[k - 1]) / span : 1.0;
  return (1.0 - w) * a + w * b;
}

double Sentinel1Noise::At(double at_line, double at_pixel) const {
  const double r = range.line.empty() ? 1.0 : range.At(at_line, at_pixel);
  for (const Sentinel1NoiseAzimuthBlock& b : azimuth) {
    if (at_pixel < b.first_range_sample || at_pixel > b.last_range_sample || at_line < b.first_azimuth_line ||
        at_line > b.last_azimuth_line || b.line.empty()) {
      continue;
    }
    return r * InterpolateIn(b.line, b.values, at_line);
  }
  return r;
}

double Sentinel1Annotation::slant_range_spacing_m() const {
  return 0.5 * kSpeedOfLightMps / range_sampling_rate_hz;
}

namespace {

template <typename Eval>
double ByAzimuth(const std::vector<Sentinel1RangeConversion>& records, double t, const std::string& file,
                 Eval eval) {
  if (records.empty()) {
    throw InputError("no slant/ground range conversion (not a GRD product?)",
                     file + ": coordinateConversion/coordinateConversionList");
  }
  // The record nearest in time (the earlier one at a tie).
  size_t best = 0;
  for (size_t k = 1; k < records.size(); ++k) {
    if (std::abs(records[k].azimuth_time_s - t) < std::abs(records[best].azimuth_time_s - t)) best = k;
  }
  return eval(records[best]);
}

}  // namespace

double Sentinel1Annotation::GroundRangeOfSlantRange(double range_m, double azimuth_time_s) const {
  return ByAzimuth(range_conversion, azimuth_time_s, file, [&](const Sentinel1RangeConversion& c) {
    return Polynomial(c.srgr, range_m - c.sr0_m);
  });
}

double Sentinel1Annotation::SlantRangeOfGroundRange(double ground_range_m, double azimuth_time_s) const {
  return ByAzimuth(range_conversion, azimuth_time_s, file, [&](const Sentinel1RangeConversion& c) {
    return Polynomial(c.grsr, ground_range_m - c.gr0_m);
  });
}

const Sentinel1Burst& Sentinel1Annotation::Burst(int number) const {
  if (is_grd()) throw InputError("a GRD product has no bursts", "--burst (" + file + ")");
  if (bursts.empty()) throw InputError("a " + mode + " " + product_type + " product has no bursts", "--burst (" + file + ")");
  if (number < 1 || number > static_cast<int>(bursts.size())) {
    throw InputError("burst " + std::to_string(number) + " does not exist; swath " + swath + " has bursts 1-" +
                         std::to_string(bursts.size()),
                     "--burst (" + file + ": swathTiming/burstList)");
  }
  return bursts[static_cast<size_t>(number - 1)];
}

int Sentinel1Annotation::BurstOfTime(double t) const {
  int found = bursts.empty() ? 0 : 1;
  for (const Sentinel1Burst& b : bursts) {
    if (b.azimuth_time_s <= t) found = b.number;
  }
  return found;
}

const Sentinel1Entry& Sentinel1Product::Entry(const std::string& swath, const std::string& polarization) const {
  const std::string s = Upper(swath), p = Upper(polarization);
  std::string have;
  for (const Sentinel1Entry& e : entries) {
    have += (have.empty() ? "" : ", ") + e.swath + "/" + e.polarization;
  }
  bool swath_known = s.empty(), pol_known = p.empty();
  const Sentinel1Entry* first_listed = nullptr;
  for (const Sentinel1Entry& e : entries) {
    swath_known = swath_known || e.swath == s;
    pol_known = pol_known || e.polarization == p;
    if ((s.empty() || e.swath == s) && (p.empty() || e.polarization == p)) {
      if (e.annotation_present) return e;
      if (first_listed == nullptr) first_listed = &e;
    }
  }
  if (!swath_known) throw InputError("swath " + s + " does not exist in " + name + " (it has " + have + ")", "--swath");
  if (!pol_known) {
    throw InputError("polarisation " + p + " does not exist in " + name + " (it has " + have + ")", "--polarization");
  }
  if (first_listed != nullptr) return *first_listed;  // its reader reports the missing file
  throw InputError("no swath/polarisation " + s + "/" + p + " in " + name + " (it has " + have + ")",
                   "--swath/--polarization");
}

bool IsSentinel1Path(const fs::path& path) {
  const std::string name = path.filename().string();
  if (name == "manifest.safe") return true;
  const std::string ext = Lower(path.extension().string());
  if (ext == ".zip" || ext == ".safe") return true;  // NISAR products are HDF5, never zipped
  std::error_code ec;
  return fs::is_directory(path, ec) && fs::exists(path / "manifest.safe", ec);
}

Sentinel1Product OpenSentinel1(const fs::path& path) {
  EnsureGdal();
  Sentinel1Product product;
  product.path = path.string();
  const std::string given = path.string();
  if (given.empty()) throw InputError("no product path given", "--product");
  std::string root;
  if (Lower(path.extension().string()) == ".zip") {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw InputError("file not found", given);
    const std::string zip = "/vsizip/" + fs::absolute(path).string();
    char** list = VSIReadDir(zip.c_str());
    std::vector<std::string> safes;
    bool manifest_at_top = false;
    for (char** p = list; p != nullptr && *p != nullptr; ++p) {
      const std::string e = *p;
      if (Lower(fs::path(e).extension().string()) == ".safe" && e != "manifest.safe") safes.push_back(e);
      if (e == "manifest.safe") manifest_at_top = true;
    }
    const bool listed = list != nullptr;
    CSLDestroy(list);
    if (!listed && !VsiExists(zip)) throw InputError("not a readable .zip archive", given);
    if (safes.size() == 1) {
      root = zip + "/" + safes.front();
    } else if (manifest_at_top) {
      root = zip;
    } else {
      throw InputError(safes.empty() ? "the .zip holds no NAME.SAFE directory"
                                     : "the .zip holds " + std::to_string(safes.size()) + " .SAFE directories",
                       given);
    }
    product.name = safes.empty() ? path.stem().string() : safes.front();
  } else {
    bool is_dir = false;
    if (!VsiExists(given, &is_dir)) throw InputError("not found", given);
    root = is_dir ? given : path.parent_path().string();
    if (!is_dir && path.filename() != "manifest.safe") {
      throw InputError("not a SAFE directory, its manifest.safe or a .zip", given);
    }
    product.name = fs::path(root).filename().string();
    if (product.name.empty()) product.name = fs::path(root).parent_path().filename().string();
  }
  product.root = root;
  const std::string manifest_file = product.name + "/manifest.safe";
  const std::string text = ReadVsiFile(root + "/manifest.safe", manifest_file);
  const XmlDoc doc = ParseXml(text, manifest_file);
  const xmlNode* top = xmlDocGetRootElement(doc.get());
  if (!IsElement(top, "XFDU")) throw InputError("root element is not <XFDU>", manifest_file);

  const xmlNode* family = FindDeep(top, "familyName");
  const xmlNode* number = FindDeep(top, "number");
  if (family == nullptr || Content(family) != "SENTINEL-1") {
    throw InputError("not a Sentinel-1 product (platform familyName is '" +
                         (family == nullptr ? std::string() : Content(family)) + "')",
                     manifest_file + ": metadataSection/platform/familyName");
  }
  product.mission = "S1" + (number == nullptr ? std::string() : Content(number));
  if (const xmlNode* m = FindDeep(top, "mode")) product.mode = Content(m);
  if (const xmlNode* t = FindDeep(top, "productType")) product.product_type = Content(t);
  const xmlNode* start = FindDeep(top, "startTime");
  if (start == nullptr) throw InputError("missing element <startTime>", manifest_file + ": acquisitionPeriod/startTime");
  product.epoch_unix_s = MidnightOf(Content(start), manifest_file + ": acquisitionPeriod/startTime");
  product.epoch_utc = FormatUtc(product.epoch_unix_s);

  std::map<std::pair<std::string, std::string>, Sentinel1Entry> entries;
  std::vector<const xmlNode*> objects;
  CollectDeep(top, "dataObject", objects);
  for (const xmlNode* o : objects) {
    const std::string rep = Attribute(o, "repID");
    const xmlNode* loc = Child(Child(o, "byteStream"), "fileLocation");
    if (loc == nullptr) continue;
    const std::string href = NormaliseHref(Attribute(loc, "href"));
    const auto key = SwathPolOf(href);
    if (key.first.empty()) continue;
    Sentinel1Entry& e = entries[key];
    e.swath = key.first;
    e.polarization = key.second;
    if (rep == "s1Level1ProductSchema") e.annotation_file = href;
    if (rep == "s1Level1CalibrationSchema") e.calibration_file = href;
    if (rep == "s1Level1NoiseSchema") e.noise_file = href;
    if (rep == "s1Level1MeasurementSchema") e.measurement_file = href;
  }
  for (auto& [key, e] : entries) {
    if (e.annotation_file.empty()) continue;
    e.annotation_present = VsiExists(root + "/" + e.annotation_file);
    product.entries.push_back(e);
  }
  if (product.entries.empty()) {
    throw InputError("the manifest lists no product annotation (s1Level1ProductSchema)",
                     manifest_file + ": dataObjectSection");
  }
  return product;
}

namespace {

// The epoch of an annotation's times when the caller gives none: midnight
// UTC of the product's first line.
double AnnotationEpoch(const xmlNode* top, const std::string& file) {
  const Reader probe(file, 0.0);
  const std::string where = probe.Where("imageAnnotation/imageInformation/productFirstLineUtcTime");
  return MidnightOf(probe.Text(top, "imageAnnotation/imageInformation/productFirstLineUtcTime", ""), where);
}

// adsHeader and generalAnnotation/productInformation: mission, type, mode,
// swath, polarisation, pass, radar frequency and range sampling rate.
void ParseProductInformation(const Reader& r, const xmlNode* top, Sentinel1Annotation& a) {
  a.mission = r.Text(top, "adsHeader/missionId", "");
  a.product_type = r.Text(top, "adsHeader/productType", "");
  a.mode = r.Text(top, "adsHeader/mode", "");
  a.swath = r.Text(top, "adsHeader/swath", "");
  a.polarization = r.Text(top, "adsHeader/polarisation", "");
  const xmlNode* info = r.Node(top, "generalAnnotation/productInformation", "");
  const std::string info_path = "generalAnnotation/productInformation";
  a.pass = r.Text(info, "pass", info_path);
  a.radar_frequency_hz = r.Number(info, "radarFrequency", info_path);
  a.range_sampling_rate_hz = r.Number(info, "rangeSamplingRate", info_path);
  if (!(a.radar_frequency_hz > 0.0)) throw InputError("must be > 0", r.Where(info_path + "/radarFrequency"));
  if (!(a.range_sampling_rate_hz > 0.0)) throw InputError("must be > 0", r.Where(info_path + "/rangeSamplingRate"));
  a.wavelength_m = kSpeedOfLightMps / a.radar_frequency_hz;
}

// imageAnnotation/imageInformation: first and last line times, the grid's
// spacings and size.
void ParseImageInformation(const Reader& r, const xmlNode* top, Sentinel1Annotation& a) {
  const std::string ii_path = "imageAnnotation/imageInformation";
  const xmlNode* ii = r.Node(top, ii_path, "");
  a.first_line_time_s = r.Time(ii, "productFirstLineUtcTime", ii_path);
  a.last_line_time_s = r.Time(ii, "productLastLineUtcTime", ii_path);
  a.slant_range_time_s = r.Number(ii, "slantRangeTime", ii_path);
  a.range_pixel_spacing_m = r.Number(ii, "rangePixelSpacing", ii_path);
  a.azimuth_pixel_spacing_m = r.Number(ii, "azimuthPixelSpacing", ii_path);
  a.azimuth_time_interval_s = r.Number(ii, "azimuthTimeInterval", ii_path);
  a.number_of_samples = r.Int(ii, "numberOfSamples", ii_path);
  a.number_of_lines = r.Int(ii, "numberOfLines", ii_path);
  for (const auto& [value, name] : {std::pair{a.slant_range_time_s, "slantRangeTime"},
                                    {a.range_pixel_spacing_m, "rangePixelSpacing"},
                                    {a.azimuth_time_interval_s, "azimuthTimeInterval"},
                                    {double(a.number_of_samples), "numberOfSamples"},
                                    {double(a.number_of_lines), "numberOfLines"}}) {
    if (!(value > 0.0)) throw InputError("must be > 0", r.Where(ii_path + "/" + name));
  }
  if (!(a.last_line_time_s >= a.first_line_time_s)) {
    throw InputError("productLastLineUtcTime before productFirstLineUtcTime", r.Where(ii_path));
  }
}

// generalAnnotation/orbitList: at least kMinStateVectors state vectors,
// increasing in time, covering the first to the last line.
void ParseOrbitList(const Reader& r, const xmlNode* top, Sentinel1Annotation& a) {
  const std::string orbit_path = "generalAnnotation/orbitList";
  const std::vector<const xmlNode*> orbits = Children(r.Node(top, orbit_path, ""), "orbit");
  a.orbit.type = "annotation";
  for (size_t i = 0; i < orbits.size(); ++i) {
    const std::string base = Reader::Item(orbit_path, "orbit", i);
    const double t = r.Time(orbits[i], "time", base);
    const Eigen::Vector3d p(r.Number(orbits[i], "position/x", base), r.Number(orbits[i], "position/y", base),
                            r.Number(orbits[i], "position/z", base));
    const Eigen::Vector3d v(r.Number(orbits[i], "velocity/x", base), r.Number(orbits[i], "velocity/y", base),
                            r.Number(orbits[i], "velocity/z", base));
    if (!a.orbit.time_s.empty() && !(t > a.orbit.time_s.back())) {
      throw InputError("orbit times not strictly increasing", r.Where(base + "/time"));
    }
    a.orbit.time_s.push_back(t);
    a.orbit.position_m.push_back(p);
    a.orbit.velocity_mps.push_back(v);
  }
  if (static_cast<int>(orbits.size()) < kMinStateVectors) {
    throw InputError(std::to_string(orbits.size()) + " orbit state vectors, at least " +
                         std::to_string(kMinStateVectors) + " needed",
                     r.Where(orbit_path));
  }
  if (a.orbit.time_s.front() > a.first_line_time_s || a.orbit.time_s.back() < a.last_line_time_s) {
    throw InputError("the orbit state vectors do not cover the product's first to last line", r.Where(orbit_path));
  }
}

// swathTiming (TOPS SLC): lines and samples per burst, and each burst's
// times, valid samples per line, first line and valid lines.
void ParseSwathTiming(const Reader& r, const xmlNode* top, Sentinel1Annotation& a) {
  const xmlNode* timing = Child(top, "swathTiming");
  if (timing == nullptr) return;
  const std::vector<const xmlNode*> bursts = Children(Child(timing, "burstList"), "burst");
  if (!bursts.empty()) {
    a.lines_per_burst = r.Int(timing, "linesPerBurst", "swathTiming");
    a.samples_per_burst = r.Int(timing, "samplesPerBurst", "swathTiming");
    if (a.lines_per_burst <= 0) throw InputError("must be > 0", r.Where("swathTiming/linesPerBurst"));
  }
  for (size_t i = 0; i < bursts.size(); ++i) {
    const std::string base = Reader::Item("swathTiming/burstList", "burst", i);
    Sentinel1Burst b;
    b.number = static_cast<int>(i) + 1;
    b.azimuth_time_s = r.Time(bursts[i], "azimuthTime", base);
    b.sensing_time_s = r.Time(bursts[i], "sensingTime", base);
    b.first_valid_sample = r.Ints(bursts[i], "firstValidSample", base);
    b.last_valid_sample = r.Ints(bursts[i], "lastValidSample", base);
    for (const auto& [list, name] : {std::pair{&b.first_valid_sample, "firstValidSample"},
                                     {&b.last_valid_sample, "lastValidSample"}}) {
      if (static_cast<int>(list->size()) != a.lines_per_burst) {
        throw InputError(std::to_string(list->size()) + " values, linesPerBurst is " +
                             std::to_string(a.lines_per_burst),
                         r.Where(base + "/" + name));
      }
    }
    // The lists hold lines_per_burst values each, so this stays far below 2^31.
    b.first_line = static_cast<int>(static_cast<int64_t>(i) * a.lines_per_burst);
    for (int k = 0; k < a.lines_per_burst; ++k) {
      if (b.first_valid_sample[size_t(k)] >= 0) {
        if (b.first_valid_line < 0) b.first_valid_line = k;
        b.last_valid_line = k;
      }
    }
    if (!a.bursts.empty() && !(b.azimuth_time_s > a.bursts.back().azimuth_time_s)) {
      throw InputError("burst azimuth times not increasing", r.Where(base + "/azimuthTime"));
    }
    a.bursts.push_back(std::move(b));
  }
}

// geolocationGrid/geolocationGridPointList: at least one point, each with
// its image position, ground point and angles.
void ParseGeolocationGrid(const Reader& r, const xmlNode* top, Sentinel1Annotation& a) {
  const std::string grid_path = "geolocationGrid/geolocationGridPointList";
  const std::vector<const xmlNode*> points = Children(r.Node(top, grid_path, ""), "geolocationGridPoint");
  if (points.empty()) throw InputError("no <geolocationGridPoint>", r.Where(grid_path));
  for (size_t i = 0; i < points.size(); ++i) {
    const std::string base = Reader::Item(grid_path, "geolocationGridPoint", i);
    Sentinel1GridPoint g;
    g.azimuth_time_s = r.Time(points[i], "azimuthTime", base);
    g.slant_range_time_s = r.Number(points[i], "slantRangeTime", base);
    g.line = r.Int(points[i], "line", base);
    g.pixel = r.Int(points[i], "pixel", base);
    g.latitude_deg = r.Number(points[i], "latitude", base);
    g.longitude_deg = r.Number(points[i], "longitude", base);
    g.height_m = r.Number(points[i], "height", base);
    g.incidence_angle_deg = r.Number(points[i], "incidenceAngle", base);
    g.elevation_angle_deg = r.Number(points[i], "elevationAngle", base);
    if (std::abs(g.latitude_deg) > 90.0 || std::abs(g.longitude_deg) > 360.0 || !(g.slant_range_time_s > 0.0)) {
      throw InputError("latitude, longitude or slantRangeTime out of range", r.Where(base));
    }
    a.geolocation_grid.push_back(g);
  }
}

// coordinateConversion/coordinateConversionList (GRD): the slant <-> ground
// range polynomials, increasing in time.
void ParseRangeConversion(const Reader& r, const xmlNode* top, Sentinel1Annotation& a) {
  const xmlNode* cc = Child(Child(top, "coordinateConversion"), "coordinateConversionList");
  if (cc == nullptr) return;
  const std::vector<const xmlNode*> records = Children(cc, "coordinateConversion");
  for (size_t i = 0; i < records.size(); ++i) {
    const std::string base = Reader::Item("coordinateConversion/coordinateConversionList", "coordinateConversion", i);
    Sentinel1RangeConversion c;
    c.azimuth_time_s = r.Time(records[i], "azimuthTime", base);
    c.slant_range_time_s = r.Number(records[i], "slantRangeTime", base);
    c.sr0_m = r.Number(records[i], "sr0", base);
    c.gr0_m = r.Number(records[i], "gr0", base);
    c.srgr = r.Numbers(records[i], "srgrCoefficients", base);
    c.grsr = r.Numbers(records[i], "grsrCoefficients", base);
    if (c.srgr.empty() || c.grsr.empty()) throw InputError("empty polynomial", r.Where(base));
    if (!a.range_conversion.empty() && !(c.azimuth_time_s > a.range_conversion.back().azimuth_time_s)) {
      throw InputError("azimuth times not increasing", r.Where(base + "/azimuthTime"));
    }
    a.range_conversion.push_back(std::move(c));
  }
}

// imageAnnotation/processingInformation/swathProcParamsList: the processed
// bands and windows (optional: older or hand-made annotations may lack them).
void ParseSwathProcessing(const Reader& r, const xmlNode* top, Sentinel1Annotation& a) {
  const std::string proc_path = "imageAnnotation/processingInformation/swathProcParamsList";
  const xmlNode* list = Child(Child(Child(top, "imageAnnotation"), "processingInformation"), "swathProcParamsList");
  if (list == nullptr) return;
  const std::vector<const xmlNode*> params = Children(list, "swathProcParams");
  for (size_t i = 0; i < params.size(); ++i) {
    const std::string base = Reader::Item(proc_path, "swathProcParams", i);
    Sentinel1SwathProcessing p;
    p.swath = r.Text(params[i], "swath", base);
    p.range_processing_bandwidth_hz = r.Number(params[i], "rangeProcessing/processingBandwidth", base);
    p.range_look_bandwidth_hz = r.Number(params[i], "rangeProcessing/lookBandwidth", base);
    p.range_looks = r.Int(params[i], "rangeProcessing/numberOfLooks", base);
    p.range_window = r.Text(params[i], "rangeProcessing/windowType", base);
    p.range_window_coefficient = r.Number(params[i], "rangeProcessing/windowCoefficient", base);
    p.azimuth_processing_bandwidth_hz = r.Number(params[i], "azimuthProcessing/processingBandwidth", base);
    p.azimuth_look_bandwidth_hz = r.Number(params[i], "azimuthProcessing/lookBandwidth", base);
    p.azimuth_looks = r.Int(params[i], "azimuthProcessing/numberOfLooks", base);
    p.azimuth_window = r.Text(params[i], "azimuthProcessing/windowType", base);
    p.azimuth_window_coefficient = r.Number(params[i], "azimuthProcessing/windowCoefficient", base);
    for (const auto& [value, name] :
         {std::pair{p.range_processing_bandwidth_hz, "rangeProcessing/processingBandwidth"},
          {p.range_look_bandwidth_hz, "rangeProcessing/lookBandwidth"},
          {p.azimuth_processing_bandwidth_hz, "azimuthProcessing/processingBandwidth"},
          {p.azimuth_look_bandwidth_hz, "azimuthProcessing/lookBandwidth"}}) {
      if (!(value > 0.0)) throw InputError("must be > 0", r.Where(base + "/" + name));
    }
    a.processing.push_back(std::move(p));
  }
}

}  // namespace

Sentinel1Annotation ParseSentinel1Annotation(const std::string& xml, const std::string& file, double epoch_unix_s) {
  const XmlDoc doc = ParseXml(xml, file);
  const xmlNode* top = xmlDocGetRootElement(doc.get());
  if (!IsElement(top, "product")) {
    throw InputError("root element is <" + std::string(reinterpret_cast<const char*>(top->name)) +
                         ">, expected <product>",
                     file);
  }
  if (epoch_unix_s == 0.0) epoch_unix_s = AnnotationEpoch(top, file);
  const Reader r(file, epoch_unix_s);
  Sentinel1Annotation a;
  a.file = file;
  ParseProductInformation(r, top, a);
  ParseImageInformation(r, top, a);
  ParseOrbitList(r, top, a);
  ParseSwathTiming(r, top, a);
  ParseGeolocationGrid(r, top, a);
  ParseRangeConversion(r, top, a);
  ParseSwathProcessing(r, top, a);
  if (a.is_grd() && a.range_conversion.empty()) {
    throw InputError("a GRD annotation without slant/ground range polynomials",
                     r.Where("coordinateConversion/coordinateConversionList"));
  }
  return a;
}

namespace {

std::string RequireFile(const Sentinel1Product& product, const Sentinel1Entry& entry, const std::string& file,
                        const char* what) {
  if (file.empty()) {
    throw InputError(std::string("the manifest lists no ") + what + " for " + entry.swath + "/" + entry.polarization,
                     product.name + "/manifest.safe: dataObjectSection");
  }
  return ReadVsiFile(product.root + "/" + file, product.name + "/" + file);
}

}  // namespace

Sentinel1Annotation ReadSentinel1Annotation(const Sentinel1Product& product, const Sentinel1Entry& entry) {
  const std::string text = RequireFile(product, entry, entry.annotation_file, "annotation");
  return ParseSentinel1Annotation(text, product.name + "/" + entry.annotation_file, product.epoch_unix_s);
}

Sentinel1Calibration ParseSentinel1Calibration(const std::string& text, const std::string& file, double epoch_unix_s) {
  const XmlDoc doc = ParseXml(text, file);
  const xmlNode* top = xmlDocGetRootElement(doc.get());
  if (!IsElement(top, "calibration")) throw InputError("root element is not <calibration>", file);
  const Reader r(file, epoch_unix_s);
  Sentinel1Calibration c;
  c.file = file;
  c.absolute_calibration_constant = r.Number(top, "calibrationInformation/absoluteCalibrationConstant", "");
  const std::string list_path = "calibrationVectorList";
  const xmlNode* list = r.Node(top, list_path, "");
  c.sigma0 = ReadLineVectors(r, list, list_path, "calibrationVector", "sigmaNought");
  c.beta0 = ReadLineVectors(r, list, list_path, "calibrationVector", "betaNought");
  c.gamma0 = ReadLineVectors(r, list, list_path, "calibrationVector", "gamma");
  c.dn = ReadLineVectors(r, list, list_path, "calibrationVector", "dn");
  for (const Sentinel1LineVectors* v : {&c.sigma0, &c.beta0, &c.gamma0, &c.dn}) {
    for (size_t i = 0; i < v->values.size(); ++i) {
      for (double x : v->values[i]) {
        if (!(x > 0.0)) {
          throw InputError("calibration values must be > 0",
                           r.Where(Reader::Item(list_path, "calibrationVector", i)));
        }
      }
    }
  }
  return c;
}

Sentinel1Calibration ReadSentinel1Calibration(const Sentinel1Product& product, const Sentinel1Entry& entry) {
  const std::string text = RequireFile(product, entry, entry.calibration_file, "calibration annotation");
  return ParseSentinel1Calibration(text, product.name + "/" + entry.calibration_file, product.epoch_unix_s);
}

Sentinel1Noise ParseSentinel1Noise(const std::string& text, const std::string& file, double epoch_unix_s) {
  const XmlDoc doc = ParseXml(text, file);
  const xmlNode* top = xmlDocGetRootElement(doc.get());
  if (!IsElement(top, "noise")) throw InputError("root element is not <noise>", file);
  const Reader r(file, epoch_unix_s);
  Sentinel1Noise n;
  n.file = file;
  if (const xmlNode* range = Child(top, "noiseRangeVectorList")) {
    n.range = ReadLineVectors(r, range, "noiseRangeVectorList", "noiseRangeVector", "noiseRangeLut");
  } else if (const xmlNode* old = Child(top, "noiseVectorList")) {
    n.range = ReadLineVectors(r, old, "noiseVectorList", "noiseVector", "noiseLut");
  } else {
    throw InputError("missing element <noiseRangeVectorList>", r.Where("noiseRangeVectorList"));
  }
  if (const xmlNode* az = Child(top, "noiseAzimuthVectorList")) {
    const std::vector<const xmlNode*> blocks = Children(az, "noiseAzimuthVector");
    for (size_t i = 0; i < blocks.size(); ++i) {
      const std::string base = Reader::Item("noiseAzimuthVectorList", "noiseAzimuthVector", i);
      Sentinel1NoiseAzimuthBlock b;
      if (const xmlNode* s = Child(blocks[i], "swath")) b.swath = Content(s);
      b.first_azimuth_line = r.Int(blocks[i], "firstAzimuthLine", base);
      b.last_azimuth_line = r.Int(blocks[i], "lastAzimuthLine", base);
      b.first_range_sample = r.Int(blocks[i], "firstRangeSample", base);
      b.last_range_sample = r.Int(blocks[i], "lastRangeSample", base);
      b.line = r.Ints(blocks[i], "line", base);
      b.values = r.Numbers(blocks[i], "noiseAzimuthLut", base);
      if (b.line.empty() || b.line.size() != b.values.size()) {
        throw InputError(std::to_string(b.line.size()) + " lines but " + std::to_string(b.values.size()) + " values",
                         r.Where(base + "/noiseAzimuthLut"));
      }
      for (size_t k = 1; k < b.line.size(); ++k) {
        if (b.line[k] <= b.line[k - 1]) throw InputError("lines not strictly increasing", r.Where(base + "/line"));
      }
      n.azimuth.push_back(std::move(b));
    }
  }
  return n;
}

Sentinel1Noise ReadSentinel1Noise(const Sentinel1Product& product, const Sentinel1Entry& entry) {
  const std::string text = RequireFile(product, entry, entry.noise_file, "noise annotation");
  return ParseSentinel1Noise(text, product.name + "/" + entry.noise_file, product.epoch_unix_s);
}

void ReplaceSentinel1Orbit(Sentinel1Annotation& annotation, const Sentinel1Product& product,
                           const StateVectors& vectors, const std::string& source) {
  constexpr double kMarginS = 60.0;
  RslcOrbit orbit;
  orbit.type = vectors.format;
  for (size_t i = 0; i < vectors.utc_s.size(); ++i) {
    const double t = vectors.utc_s[i] - product.epoch_unix_s;
    if (t < annotation.first_line_time_s - kMarginS || t > annotation.last_line_time_s + kMarginS) continue;
    orbit.time_s.push_back(t);
    orbit.position_m.push_back(vectors.position_m[i]);
    orbit.velocity_mps.push_back(vectors.velocity_mps[i]);
  }
  if (orbit.time_s.size() < 2 || orbit.time_s.front() > annotation.first_line_time_s ||
      orbit.time_s.back() < annotation.last_line_time_s) {
    throw InputError("the orbit does not cover the product's time " +
                         FormatUtc(product.epoch_unix_s + annotation.first_line_time_s) + " to " +
                         FormatUtc(product.epoch_unix_s + annotation.last_line_time_s) +
                         (vectors.utc_s.empty() ? std::string()
                                                : " (it spans " + FormatUtc(vectors.utc_s.front()) + " to " +
                                                      FormatUtc(vectors.utc_s.back()) + ")"),
                     source);
  }
  annotation.orbit = std::move(orbit);
}

}  // namespace gissar::geo
