// Flags of `gissar fmatrix`, `resect`, `register` and `epipolar`.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/cli/command_line.h"
#include "gissar/mvg/registration.h"
#include "gissar/pipeline/mvg_commands.h"
#include "gissar/pipeline/mvg_fields.h"
#include "gissar/util/error.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

namespace {

// The JSON output of fmatrix and resect: --out PREFIX (PREFIX.json), or the
// deprecated --json FILE, which named the file itself and keeps doing so for
// one release (so that the outputs' collision checks see the file it writes).
std::string JsonOutput(const std::string& out_prefix, const std::string& json_file, Reporter& reporter) {
  if (json_file.empty()) return out_prefix.empty() ? "" : PrefixedOutput(out_prefix, ".json");
  reporter.Warn(DeprecationWarning("--json", "--out"));
  if (!out_prefix.empty()) throw ConfigError("give the output once, as --out", "--json/--out");
  return json_file;
}

}  // namespace

void AddMvgCommands(CLI::App& root, CommandRegistry& registry) {
  {
    auto o = std::make_shared<FmatrixRequest>();
    auto res1 = std::make_shared<std::string>(), res2 = std::make_shared<std::string>();  // deprecated
    CLI::App* cmd = root.add_subcommand(
        "fmatrix", "Affine fundamental matrix (RANSAC + Gold Standard), KvD decomposition and heading change.");
    // Every field of the request's table is a flag (pipeline/mvg_fields.cc), in the table's order.
    auto flags = std::make_shared<RequestFlags<FmatrixRequest>>(cmd, FmatrixFields(), o.get());
    flags->AddAll({"matches"});
    // Until the next release: --res1 R1,A1 --res2 R2,A2 (one image each), not
    // listed in --help. Not a plain rename (ReplaceDeprecatedFlags): the
    // values regroup across the two new flags.
    cmd->add_option("--res1", *res1)->group("");
    cmd->add_option("--res2", *res2)->group("");
    // --out is required, unless the deprecated --json FILE (hidden) names the file.
    auto json_file = std::make_shared<std::string>();
    cmd->add_option("--json", *json_file)->group("");
    registry.Add(cmd, [=](const CommandContext& context) {
      FmatrixRequest r = *o;
      flags->Apply(r);
      r.json_out = JsonOutput(o->json_out, *json_file, context.reporter);
      if (!res1->empty() || !res2->empty()) {
        const std::string replacement = "--range-spacing R1,R2 --azimuth-spacing A1,A2";
        if (!res1->empty()) context.reporter.Warn(DeprecationWarning("--res1", replacement));
        if (!res2->empty()) context.reporter.Warn(DeprecationWarning("--res2", replacement));
        if (res1->empty() || res2->empty()) throw ConfigError("give both --res1 and --res2", "--res1/--res2");
        if (r.range_spacing_m || r.azimuth_spacing_m) {
          throw ConfigError("give the spacings once, as --range-spacing/--azimuth-spacing", "--res1/--res2");
        }
        const Eigen::Vector2d a = ParseNumberPair(*res1, "--res1"), b = ParseNumberPair(*res2, "--res2");
        r.range_spacing_m = Eigen::Vector2d(a.x(), b.x());
        r.azimuth_spacing_m = Eigen::Vector2d(a.y(), b.y());
      }
      nlohmann::json out;
      try {
        out = RunFmatrix(r, context.command_line, context.reporter);
      } catch (const ConfigError& e) {
        // The JSON named by the old --json: the error names the flag given.
        auto renamed = [](const std::string& text) {
          return text.rfind("--out", 0) == 0 ? "--json" + text.substr(5) : text;
        };
        if (json_file->empty()) throw;
        throw ConfigError(renamed(e.message()), renamed(e.where()));
      }
      context.out << r.json_out << "\n";
      if (out.contains("pictures")) {
        for (const auto& p : out["pictures"]) context.out << p.get<std::string>() << "\n";
      }
      // A consensus no better than chance: the JSON says why (exit 3).
      if (!out.value("converged", true)) {
        context.no_result = out.at("reason").get<std::string>();
        return;
      }
      context.out << FmatrixHeadline(out) << "\n";
    });
  }
  {
    auto o = std::make_shared<ResectRequest>();
    CLI::App* cmd = root.add_subcommand(
        "resect", "Affine SAR camera (heading, depression, spacings) from >= 4 known 3-D points.");
    auto flags = std::make_shared<RequestFlags<ResectRequest>>(cmd, ResectFields(), o.get());
    flags->AddAll({"points"});
    auto json_file = std::make_shared<std::string>();  // deprecated --json FILE, as in fmatrix
    cmd->add_option("--json", *json_file)->group("");
    registry.Add(cmd, [=](const CommandContext& context) {
      ResectRequest r = *o;
      flags->Apply(r);
      r.json_out = JsonOutput(o->json_out, *json_file, context.reporter);
      const auto out = RunResect(r, context.command_line, context.reporter);
      context.out << r.json_out << "\n" << ResectHeadline(out) << "\n";
    });
  }
  {
    auto o = std::make_shared<RegisterRequest>();
    CLI::App* cmd = root.add_subcommand(
        "register", "Register a moving image to a fixed one from control points (cpselect/fitgeotrans).");
    auto flags = std::make_shared<RequestFlags<RegisterRequest>>(cmd, RegisterFields(), o.get());
    flags->AddAll({"fixed", "moving", "points", "out_prefix"});
    registry.Add(cmd, [=](const CommandContext& context) {
      RegisterRequest r = *o;
      RunRegister(r, context.command_line, context.reporter);
      context.out << r.out_prefix << ".tif\n" << r.out_prefix << "_composite.png\n" << r.out_prefix << ".json\n";
    });
  }
  {
    auto o = std::make_shared<EpipolarRequest>();
    CLI::App* cmd = root.add_subcommand("epipolar", "Draw matches and epipolar lines over an image pair.");
    auto flags = std::make_shared<RequestFlags<EpipolarRequest>>(cmd, EpipolarFields(), o.get());
    flags->AddAll({"matches", "image1", "image2", "out"});
    registry.Add(cmd, [=](const CommandContext& context) {
      EpipolarRequest resolved = *o;
      resolved.out_png = PrefixedOutput(o->out_png, ".png");
      RunEpipolar(resolved);
      context.out << resolved.out_png << "\n";
    });
  }
  {
    auto o = std::make_shared<CompositeRequest>();
    CLI::App* cmd = root.add_subcommand(
        "composite", "Green/magenta composite of two co-registered images (grey where they agree).");
    auto flags = std::make_shared<RequestFlags<CompositeRequest>>(cmd, CompositeFields(), o.get());
    flags->AddAll({"green", "magenta", "out"});
    registry.Add(cmd, [=](const CommandContext& context) {
      CompositeRequest resolved = *o;
      resolved.out_png = PrefixedOutput(o->out_png, ".png");
      RunComposite(resolved);
      context.out << resolved.out_png << "\n";
    });
  }
}

}  // namespace gissar::cli
