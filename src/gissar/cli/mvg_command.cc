// Flags of `gissar fmatrix`, `resect`, `register` and `epipolar`.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/cli/command_line.h"
#include "gissar/mvg/registration.h"
#include "gissar/pipeline/mvg_commands.h"
#include "gissar/pipeline/simulate.h"
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
    auto range_spacing = std::make_shared<std::string>(), azimuth_spacing = std::make_shared<std::string>();
    auto res1 = std::make_shared<std::string>(), res2 = std::make_shared<std::string>();  // deprecated
    auto depressions = std::make_shared<std::string>();
    auto ransac = std::make_shared<bool>(true);
    CLI::App* cmd = root.add_subcommand(
        "fmatrix", "Affine fundamental matrix (RANSAC + Gold Standard), KvD decomposition and heading change.");
    cmd->add_option("--matches", o->matches, "CSV with a header and columns x1,y1,x2,y2 (others ignored)")->required();
    cmd->add_option("--range-spacing", *range_spacing,
                    "Slant-range pixel spacing R1,R2 of images 1 and 2, metres (calibrated F, with --azimuth-spacing)");
    cmd->add_option("--azimuth-spacing", *azimuth_spacing, "Along-track pixel spacing A1,A2 of images 1 and 2, metres");
    // Until the next release: --res1 R1,A1 --res2 R2,A2 (one image each), not
    // listed in --help. Not a plain rename (ReplaceDeprecatedFlags): the
    // values regroup across the two new flags.
    cmd->add_option("--res1", *res1)->group("");
    cmd->add_option("--res2", *res2)->group("");
    cmd->add_option("--depressions", *depressions, "Depressions D1,D2 in degrees: gives the heading change");
    cmd->add_option("--threshold", o->threshold_px, "RANSAC inlier threshold, pixels")->capture_default_str();
    AddSwitch(cmd, "ransac", *ransac, "RANSAC before the Gold Standard fit, or (--no-ransac) one fit to all matches");
    cmd->add_option("--seed", o->seed, "RANSAC seed")->capture_default_str();
    // Required, unless the deprecated --json FILE (hidden) names the file.
    auto json_file = std::make_shared<std::string>();
    cmd->add_option("--out", o->json_out, "Output prefix: PREFIX.json (the fit)");
    cmd->add_option("--json", *json_file)->group("");
    cmd->add_option("--plot", o->plot_prefix, "Pictures: PREFIX_kvd.png (KvD diagram) and, with the images, "
                                              "PREFIX_epipolar.png (matches and epipolar lines)");
    cmd->add_option("--image1", o->image1, "Image 1 (any GDAL raster) for --plot");
    cmd->add_option("--image2", o->image2, "Image 2 for --plot");
    registry.Add(cmd, [=](const CommandContext& context) {
      FmatrixRequest r = *o;
      r.json_out = JsonOutput(o->json_out, *json_file, context.reporter);
      r.robust = *ransac;
      if (!range_spacing->empty()) r.range_spacing_m = ParseNumberPair(*range_spacing, "--range-spacing");
      if (!azimuth_spacing->empty()) r.azimuth_spacing_m = ParseNumberPair(*azimuth_spacing, "--azimuth-spacing");
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
      if (!depressions->empty()) r.depressions = ParseNumberPair(*depressions, "--depressions");
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
    auto center = std::make_shared<std::vector<double>>();
    auto range = std::make_shared<double>(0.0);
    CLI::App* cmd = root.add_subcommand(
        "resect", "Affine SAR camera (heading, depression, spacings) from >= 4 known 3-D points.");
    cmd->add_option("--points", o->points, "CSV with a header and columns X,Y,Z,x,y (ENU m, pixels)")->required();
    cmd->add_option("--center-enu", *center, "Scene centre Xc X,Y,Z (ENU m; default 0,0,0)")->delimiter(',')->expected(3);
    cmd->add_option("--slant-range", *range, "Measured slant range to Xc, metres: also gives the sensor position");
    auto json_file = std::make_shared<std::string>();  // deprecated --json FILE, as in fmatrix
    cmd->add_option("--out", o->json_out, "Output prefix: PREFIX.json (the camera)");
    cmd->add_option("--json", *json_file)->group("");
    registry.Add(cmd, [=](const CommandContext& context) {
      ResectRequest r = *o;
      r.json_out = JsonOutput(o->json_out, *json_file, context.reporter);
      if (!center->empty()) r.center_enu_m = Eigen::Vector3d((*center)[0], (*center)[1], (*center)[2]);
      if (*range != 0.0) r.slant_range_m = *range;
      const auto out = RunResect(r, context.command_line, context.reporter);
      context.out << r.json_out << "\n" << ResectHeadline(out) << "\n";
    });
  }
  {
    auto o = std::make_shared<RegisterRequest>();
    auto ransac = std::make_shared<bool>(true);
    CLI::App* cmd = root.add_subcommand(
        "register", "Register a moving image to a fixed one from control points (cpselect/fitgeotrans).");
    cmd->add_option("--fixed", o->fixed, "Fixed image (any GDAL raster)")->required();
    cmd->add_option("--moving", o->moving, "Moving image")->required();
    cmd->add_option("--points", o->points, "CSV x1,y1 (fixed), x2,y2 (moving)")->required();
    cmd->add_option("--transform", o->transform, mvg::kTransformTypes.Alternatives())
        ->capture_default_str();
    cmd->add_option("--threshold", o->threshold_px, "Robust fit inlier threshold, pixels")->capture_default_str();
    AddSwitch(cmd, "ransac", *ransac, "Robust fit, or (--no-ransac) least squares on all pairs");
    cmd->add_option("--out", o->out_prefix, "Output prefix: PREFIX.tif, PREFIX_composite.png, PREFIX.json")
        ->required();
    registry.Add(cmd, [=](const CommandContext& context) {
      RegisterRequest r = *o;
      r.robust = *ransac;
      RunRegister(r, context.command_line, context.reporter);
      context.out << r.out_prefix << ".tif\n" << r.out_prefix << "_composite.png\n" << r.out_prefix << ".json\n";
    });
  }
  {
    auto o = std::make_shared<EpipolarRequest>();
    CLI::App* cmd = root.add_subcommand("epipolar", "Draw matches and epipolar lines over an image pair.");
    cmd->add_option("--matches", o->matches, "CSV x1,y1,x2,y2")->required();
    cmd->add_option("--image1", o->image1, "Image 1")->required();
    cmd->add_option("--image2", o->image2, "Image 2")->required();
    cmd->add_option("--threshold", o->threshold_px, "RANSAC threshold, pixels")->capture_default_str();
    cmd->add_option("--out", o->out_png, "Output prefix: PREFIX.png")->required();
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
    cmd->add_option("--green", o->green, "First image (e.g. the real one), band 1 linear intensity")->required();
    cmd->add_option("--magenta", o->magenta, "Second image (e.g. the simulation), same size")->required();
    cmd->add_option("--out", o->out_png, "Output prefix: PREFIX.png")->required();
    registry.Add(cmd, [=](const CommandContext& context) {
      CompositeRequest resolved = *o;
      resolved.out_png = PrefixedOutput(o->out_png, ".png");
      RunComposite(resolved);
      context.out << resolved.out_png << "\n";
    });
  }
}

}  // namespace gissar::cli
