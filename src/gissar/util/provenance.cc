#include "gissar/util/provenance.h"

#include <openssl/evp.h>

#include <array>
#include <cerrno>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <memory>
#include <sstream>

#include "gissar/util/atomic_output.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/git_describe.h"
#include "gissar/util/version.h"

namespace gissar {
namespace fs = std::filesystem;

std::string VersionString() {
  return std::string("gissar ") + kGissarVersion + " (" + kGissarGitDescribe + ")";
}

std::string Sha256OfFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot read file for checksum", path.string());
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1) {
    throw IoError("cannot initialise SHA-256", path.string());
  }
  std::array<char, 1 << 16> buffer;
  while (in) {
    in.read(buffer.data(), buffer.size());
    const std::streamsize n = in.gcount();
    if (n > 0) EVP_DigestUpdate(ctx.get(), buffer.data(), static_cast<size_t>(n));
  }
  if (in.bad()) throw IoError("read error while computing checksum", path.string());
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(ctx.get(), digest, &length);
  std::ostringstream hex;
  for (unsigned int i = 0; i < length; ++i) {
    hex << std::hex << std::setw(2) << std::setfill('0') << static_cast<int>(digest[i]);
  }
  return hex.str();
}

nlohmann::json InputFileRecord(const fs::path& path) {
  if (path.string().rfind("/vsimem/", 0) == 0) return {{"path", path.string()}, {"in_memory", true}};
  std::error_code ec;
  const auto bytes = fs::file_size(path, ec);
  if (ec) throw IoError("cannot stat input file", path.string());
  return {{"path", fs::absolute(path).lexically_normal().string()},
          {"bytes", bytes},
          {"sha256", Sha256OfFile(path)}};
}

PendingInputRecord::PendingInputRecord(const fs::path& path)
    : record_(std::async(std::launch::async, [path] { return InputFileRecord(path); }).share()) {}

nlohmann::json PendingInputRecord::Get() const {
  GISSAR_CHECK(record_.valid());
  return record_.get();
}

void WriteJsonFile(const nlohmann::json& value, const fs::path& path) {
  errno = 0;
  std::ofstream out(path);
  if (!out) throw WriteError("cannot open JSON output for writing", path, errno);
  out << value.dump(2) << "\n";
  out.close();
  if (!out) throw WriteError("failed writing JSON output", path, errno);
}

std::string UtcTimestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm tm_utc{};
  gmtime_r(&now, &tm_utc);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", &tm_utc);
  return buffer;
}

nlohmann::json ProvenanceHeader(const std::string& command, const std::string& command_line,
                                const nlohmann::json& options) {
  return {{"command", command},
          {"command_line", command_line},
          {"version", VersionString()},
          {"created_utc", UtcTimestamp()},
          {"options", options}};
}

}  // namespace gissar
