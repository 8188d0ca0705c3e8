#include "gissar/scene/scene_io.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>

#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"

namespace gissar::scene {
namespace fs = std::filesystem;
namespace {

constexpr char kMagic[8] = {'G', 'I', 'S', 'S', 'A', 'R', 'S', 'C'};
constexpr char kEndMagic[8] = {'G', 'S', 'C', 'N', 'E', 'N', 'D', '1'};

// Closes `out` and throws util's WriteError("<what>", path) when a write or
// the close failed: on a full disk "<what>: no space left on the device
// holding DIR", naming the output rather than its temporary.
void CloseChecked(std::ofstream& out, const fs::path& path, const std::string& what) {
  out.close();
  if (out) return;
  throw WriteError(what, path, errno);
}

template <typename T>
void Put(std::ofstream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

class Reader {
 public:
  Reader(const fs::path& path) : path_(path), in_(path, std::ios::binary) {
    if (!in_) throw InputError("scene file does not exist or cannot be read", path.string());
    in_.seekg(0, std::ios::end);
    size_ = static_cast<uint64_t>(in_.tellg());
    in_.seekg(0);
  }
  void Bytes(void* dst, uint64_t n) {
    if (n > size_ - static_cast<uint64_t>(in_.tellg()) || !in_.read(static_cast<char*>(dst), n)) {
      throw InputError("scene file is truncated", path_.string());
    }
  }
  template <typename T>
  T Get() {
    T v;
    Bytes(&v, sizeof(T));
    return v;
  }
  uint64_t remaining() { return size_ - static_cast<uint64_t>(in_.tellg()); }

 private:
  fs::path path_;
  std::ifstream in_;
  uint64_t size_ = 0;
};

}  // namespace

void WriteScene(const fs::path& path, const SceneFile& scene) {
  if (scene.mesh.grid_width > 0) {  // the file stores every triangle
    SceneFile stored = scene;
    stored.mesh.MakeExplicit();
    WriteScene(path, stored);
    return;
  }
  errno = 0;  // no stale errno from before the write
  std::ofstream out(path, std::ios::binary);
  if (!out) throw IoError("cannot open scene file for writing", path.string());
  nlohmann::json header = {
      {"origin_lon_deg", scene.origin_lon_deg},
      {"origin_lat_deg", scene.origin_lat_deg},
      {"centre_enu", {scene.centre_enu.x(), scene.centre_enu.y(), scene.centre_enu.z()}},
      {"centre_lon_deg", scene.centre_lon_deg},
      {"centre_lat_deg", scene.centre_lat_deg},
      {"centre_height_m", scene.centre_height_m},
      {"class_names", scene.class_names},
      {"materials", scene.materials},
      {"provenance", scene.provenance}};
  if (!scene.reflectors.empty()) {
    nlohmann::json list = nlohmann::json::array();
    for (const StoredReflector& r : scene.reflectors) {
      list.push_back({{"type", r.type},
                      {"lon_deg", r.lon_deg},
                      {"lat_deg", r.lat_deg},
                      {"apex_height_m", r.apex_height_m},
                      {"size_m", r.size_m},
                      {"boresight_azimuth_deg", r.boresight_azimuth_deg},
                      {"boresight_elevation_deg", r.boresight_elevation_deg},
                      {"roll_deg", r.roll_deg},
                      {"apex_enu", {r.apex_enu.x(), r.apex_enu.y(), r.apex_enu.z()}},
                      {"source", r.source},
                      {"row", r.row}});
    }
    header["reflectors"] = list;
  }
  if (scene.grid.cells > 0) {
    header["terrain_grid"] = {{"width", scene.grid.width}, {"height", scene.grid.height}, {"cells", scene.grid.cells}};
  }
  const std::string text = header.dump();
  out.write(kMagic, sizeof(kMagic));
  Put(out, kSceneFileVersion);
  Put(out, static_cast<uint64_t>(text.size()));
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  const TriangleMesh& mesh = scene.mesh;
  Put(out, static_cast<uint64_t>(mesh.vertices.size()));
  Put(out, static_cast<uint64_t>(mesh.triangles.size()));
  out.write(reinterpret_cast<const char*>(mesh.vertices.data()),
            static_cast<std::streamsize>(mesh.vertices.size() * sizeof(Eigen::Vector3f)));
  out.write(reinterpret_cast<const char*>(mesh.triangles.data()),
            static_cast<std::streamsize>(mesh.triangles.size() * sizeof(Eigen::Vector3i)));
  out.write(reinterpret_cast<const char*>(mesh.classes.data()),
            static_cast<std::streamsize>(mesh.classes.size()));
  const bool normals = !mesh.shading_normals.empty();
  if (normals && mesh.shading_normals.size() != mesh.vertices.size()) {
    throw IoError("scene has " + std::to_string(mesh.shading_normals.size()) + " shading normals for " +
                      std::to_string(mesh.vertices.size()) + " vertices",
                  path.string());
  }
  Put(out, static_cast<uint8_t>(normals ? 1 : 0));
  if (normals) {
    out.write(reinterpret_cast<const char*>(mesh.shading_normals.data()),
              static_cast<std::streamsize>(mesh.shading_normals.size() * sizeof(Eigen::Vector3f)));
  }
  out.write(kEndMagic, sizeof(kEndMagic));
  CloseChecked(out, path, "failed writing scene file");
}

SceneFile ReadScene(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError("scene path is a directory", path.string());
  Reader in(path);
  char magic[8] = {};
  if (in.remaining() < sizeof(magic)) throw InputError("not a gissar scene file (too short)", path.string());
  in.Bytes(magic, sizeof(magic));
  if (std::memcmp(magic, kMagic, sizeof(kMagic)) != 0) {
    throw InputError("not a gissar scene file", path.string());
  }
  const uint32_t version = in.Get<uint32_t>();
  if (version != kSceneFileVersion) {
    throw InputError("scene file version " + std::to_string(version) + " is not supported (this gissar reads " +
                         std::to_string(kSceneFileVersion) + "); rebuild the scene",
                     path.string());
  }
  const uint64_t json_bytes = in.Get<uint64_t>();
  if (json_bytes > in.remaining()) throw InputError("scene file is truncated", path.string());
  std::string text(json_bytes, '\0');
  in.Bytes(text.data(), json_bytes);
  SceneFile scene;
  try {
    const nlohmann::json header = nlohmann::json::parse(text);
    scene.origin_lon_deg = header.at("origin_lon_deg");
    scene.origin_lat_deg = header.at("origin_lat_deg");
    const auto& c = header.at("centre_enu");
    scene.centre_enu = Eigen::Vector3d(c.at(0), c.at(1), c.at(2));
    scene.centre_lon_deg = header.at("centre_lon_deg");
    scene.centre_lat_deg = header.at("centre_lat_deg");
    scene.centre_height_m = header.at("centre_height_m");
    scene.class_names = header.at("class_names").get<std::vector<std::string>>();
    scene.materials = header.at("materials");
    scene.provenance = header.at("provenance");
    if (header.contains("reflectors")) {
      for (const nlohmann::json& item : header.at("reflectors")) {
        StoredReflector r;
        r.type = item.at("type").get<std::string>();
        r.lon_deg = item.at("lon_deg");
        r.lat_deg = item.at("lat_deg");
        r.apex_height_m = item.at("apex_height_m");
        r.size_m = item.at("size_m");
        r.boresight_azimuth_deg = item.at("boresight_azimuth_deg");
        r.boresight_elevation_deg = item.at("boresight_elevation_deg");
        r.roll_deg = item.value("roll_deg", 0.0);
        const auto& a = item.at("apex_enu");
        r.apex_enu = Eigen::Vector3d(a.at(0), a.at(1), a.at(2));
        r.source = item.at("source").get<std::string>();
        r.row = item.at("row");
        const bool finite = std::isfinite(r.lon_deg) && std::isfinite(r.lat_deg) && std::isfinite(r.apex_height_m) &&
                            std::isfinite(r.boresight_azimuth_deg) && std::isfinite(r.boresight_elevation_deg) &&
                            std::isfinite(r.roll_deg) && r.apex_enu.allFinite();
        if (r.type.empty() || !finite || !(r.size_m > 0.0) || !std::isfinite(r.size_m)) {
          throw InputError("scene header is corrupt: reflector " + std::to_string(scene.reflectors.size() + 1) +
                               " has no type, a non-finite field or size <= 0",
                           path.string());
        }
        scene.reflectors.push_back(r);
      }
    }
    if (header.contains("terrain_grid")) {
      const nlohmann::json& g = header.at("terrain_grid");
      scene.grid.width = g.at("width").get<int>();
      scene.grid.height = g.at("height").get<int>();
      scene.grid.cells = g.at("cells").get<int64_t>();
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("scene header is corrupt: ") + e.what(), path.string());
  }
  if (!std::isfinite(scene.origin_lon_deg) || !std::isfinite(scene.origin_lat_deg) ||
      std::abs(scene.origin_lat_deg) > 90.0 || !scene.centre_enu.allFinite() ||
      !std::isfinite(scene.centre_lon_deg) || !std::isfinite(scene.centre_lat_deg) ||
      !std::isfinite(scene.centre_height_m)) {
    throw InputError("scene header is corrupt: frame origin or centre is not a valid position",
                     path.string());
  }
  if (scene.class_names.empty() || scene.class_names.size() > 256) {
    throw InputError("scene header is corrupt: it needs 1 to 256 class names", path.string());
  }
  const uint64_t n = in.Get<uint64_t>(), m = in.Get<uint64_t>();
  const uint64_t needed = n * sizeof(Eigen::Vector3f) + m * (sizeof(Eigen::Vector3i) + 1) + 1 + sizeof(kEndMagic);
  if (n > (uint64_t{1} << 34) || m > (uint64_t{1} << 34) || needed > in.remaining()) {
    throw InputError("scene file is truncated", path.string());
  }
  scene.mesh.vertices.resize(n);
  scene.mesh.triangles.resize(m);
  scene.mesh.classes.resize(m);
  in.Bytes(scene.mesh.vertices.data(), n * sizeof(Eigen::Vector3f));
  in.Bytes(scene.mesh.triangles.data(), m * sizeof(Eigen::Vector3i));
  in.Bytes(scene.mesh.classes.data(), m);
  const uint8_t normals = in.Get<uint8_t>();
  if (normals > 1) throw InputError("scene file is corrupt (shading-normal flag)", path.string());
  if (normals == 1) {
    if (n * sizeof(Eigen::Vector3f) + sizeof(kEndMagic) > in.remaining()) {
      throw InputError("scene file is truncated", path.string());
    }
    scene.mesh.shading_normals.resize(n);
    in.Bytes(scene.mesh.shading_normals.data(), n * sizeof(Eigen::Vector3f));
    for (const Eigen::Vector3f& v : scene.mesh.shading_normals) {
      if (!v.allFinite() || (!v.isZero() && std::abs(v.norm() - 1.0f) > 1e-3f)) {
        throw InputError("scene file is corrupt (shading normal neither unit nor zero)", path.string());
      }
    }
  }
  char end[8] = {};
  in.Bytes(end, sizeof(end));
  if (std::memcmp(end, kEndMagic, sizeof(kEndMagic)) != 0) {
    throw InputError("scene file is corrupt (bad end marker)", path.string());
  }
  for (const Eigen::Vector3i& t : scene.mesh.triangles) {
    if ((t.array() < 0).any() || (t.array() >= static_cast<int>(n)).any()) {
      throw InputError("scene file is corrupt (vertex index out of range)", path.string());
    }
  }
  for (const Eigen::Vector3f& v : scene.mesh.vertices) {
    if (!v.allFinite()) throw InputError("scene file is corrupt (non-finite vertex)", path.string());
  }
  for (const ClassId c : scene.mesh.classes) {
    if (c >= scene.class_names.size()) {
      throw InputError("scene file is corrupt (class id " + std::to_string(c) + " has no name)",
                       path.string());
    }
  }
  if (scene.grid.cells != 0 && !GridPrefixCells(scene.mesh, scene.grid)) {
    throw InputError("scene file is corrupt (its terrain grid is not the mesh's first triangles)", path.string());
  }
  return scene;
}

void WritePly(const fs::path& path, const TriangleMesh& mesh, const std::vector<std::string>& class_names,
              const std::vector<std::string>& header_comments) {
  errno = 0;
  std::ofstream out(path, std::ios::binary);
  if (!out) throw IoError("cannot open PLY for writing", path.string());
  out << "ply\nformat binary_little_endian 1.0\ncomment gissar scene, ENU metres\n";
  for (size_t i = 0; i < class_names.size(); ++i) {
    out << "comment class " << i << " " << class_names[i] << "\n";
  }
  for (const std::string& line : header_comments) out << "comment " << line << "\n";
  out << "element vertex " << mesh.vertices.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "element face " << mesh.triangle_count()
      << "\nproperty list uchar int vertex_indices\nproperty uchar class\nend_header\n";
  out.write(reinterpret_cast<const char*>(mesh.vertices.data()),
            static_cast<std::streamsize>(mesh.vertices.size() * sizeof(Eigen::Vector3f)));
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    Put(out, static_cast<uint8_t>(3));
    const Eigen::Vector3i face = mesh.Triangle(t);
    out.write(reinterpret_cast<const char*>(face.data()), 3 * sizeof(int));
    Put(out, mesh.classes[t]);
  }
  CloseChecked(out, path, "failed writing PLY");
}

void WriteObj(const fs::path& path, const TriangleMesh& mesh, const std::vector<std::string>& class_names,
              const std::vector<std::array<uint8_t, 3>>& class_colours) {
  fs::path mtl_path = path;
  mtl_path.replace_extension(".mtl");
  WriteObj(path, mtl_path, mtl_path.filename().string(), mesh, class_names, class_colours);
}

void WriteObj(const fs::path& path, const fs::path& mtl_path, const std::string& mtllib_name,
              const TriangleMesh& mesh, const std::vector<std::string>& class_names,
              const std::vector<std::array<uint8_t, 3>>& class_colours,
              const std::vector<std::string>& header_comments) {
  {
    errno = 0;
    std::ofstream mtl(mtl_path);
    if (!mtl) throw IoError("cannot open MTL for writing", mtl_path.string());
    for (size_t c = 0; c < class_names.size(); ++c) {
      const auto rgb = c < class_colours.size() ? class_colours[c] : std::array<uint8_t, 3>{200, 200, 200};
      mtl << "newmtl " << class_names[c] << "\nKd " << rgb[0] / 255.0 << " " << rgb[1] / 255.0 << " "
          << rgb[2] / 255.0 << "\n";
    }
    CloseChecked(mtl, mtl_path, "failed writing MTL");  // a short file fails only when flushed
  }
  errno = 0;
  std::ofstream out(path);
  if (!out) throw IoError("cannot open OBJ for writing", path.string());
  out << "# gissar scene, ENU metres (x east, y north, z up)\n";
  for (const std::string& line : header_comments) out << "# " << line << "\n";
  out << "mtllib " << mtllib_name << "\n";
  out.precision(9);
  for (const Eigen::Vector3f& v : mesh.vertices) out << "v " << v.x() << " " << v.y() << " " << v.z() << "\n";
  // Faces grouped by class.
  for (size_t c = 0; c < class_names.size(); ++c) {
    bool any = false;
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      if (mesh.classes[t] != c) continue;
      if (!any) {
        out << "usemtl " << class_names[c] << "\n";
        any = true;
      }
      const Eigen::Vector3i f = mesh.Triangle(t);
      out << "f " << f[0] + 1 << " " << f[1] + 1 << " " << f[2] + 1 << "\n";
    }
  }
  CloseChecked(out, path, "failed writing OBJ");
}

}  // namespace gissar::scene
