// mvkp synth: query views of a target with known homographies.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/synth/synth.h"
#include "output.h"

namespace mvkp::cli {
namespace {

struct SynthArgs {
  std::string image, outdir, background;
  int n = 20;
  std::uint64_t seed = 1;
  bool gray = false;
  SceneOptions opt;
};

int RunSynth(SynthArgs& a) {
  Require(a.n >= 1 && a.n <= 100000, ErrorCode::kInvalidArgument, "--n must be in 1..100000");
  a.opt.Check();
  const cv::Mat src = a.gray ? LoadImageGray(a.image) : LoadImageColor(a.image);
  const cv::Mat bg = a.background.empty() ? cv::Mat() : LoadImageColor(a.background);
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(a.outdir, ec);
  if (ec || !fs::is_directory(a.outdir)) throw Error(ErrorCode::kIo, a.outdir + ": cannot create output directory");
  const cv::Mat target = PrepareTarget(src, a.opt.target_max_side);
  SaveImage((fs::path(a.outdir) / "target.png").string(), target);
  std::ofstream manifest(fs::path(a.outdir) / "manifest.txt");
  if (!manifest) throw Error(ErrorCode::kIo, a.outdir + "/manifest.txt: cannot write");
  manifest << "# mvkp synth " << a.image << " --n " << a.n << " --seed " << a.seed
           << "; columns: img1 img2 H (H maps img1 pixels to img2 pixels)\n";
  for (int i = 0; i < a.n; ++i) {
    const SceneView v = MakeSceneView(target, a.opt, a.seed * 1000003ull + std::uint64_t(i), bg);
    char name[64], hname[64];
    std::snprintf(name, sizeof name, "view_%04d.png", i);
    std::snprintf(hname, sizeof hname, "H_%04d.txt", i);
    SaveImage((fs::path(a.outdir) / name).string(), v.image);
    std::ofstream h(fs::path(a.outdir) / hname);
    h.precision(17);
    for (int r = 0; r < 3; ++r) h << v.H(r, 0) << " " << v.H(r, 1) << " " << v.H(r, 2) << "\n";
    if (!h) throw Error(ErrorCode::kIo, std::string(hname) + ": cannot write");
    manifest << "target.png " << name << " " << hname << "\n";
    Progress("synth: view", i + 1, a.n);
  }
  std::printf("wrote %d views of %s (target %dx%d) to %s; manifest: %s/manifest.txt\n", a.n, a.image.c_str(),
              target.cols, target.rows, a.outdir.c_str(), a.outdir.c_str());
  return 0;
}

}  // namespace

void RegisterSynth(CLI::App& app, int* code) {
  auto a = std::make_shared<SynthArgs>();
  auto* c = app.add_subcommand("synth", "Write query views of a target with known homographies and a manifest");
  c->add_option("IMAGE", a->image, "target image")->required();
  c->add_option("-o,--output", a->outdir, "output directory")->required();
  c->add_option("--n", a->n, "number of views")->capture_default_str();
  c->add_option("--seed", a->seed, "random seed")->capture_default_str();
  c->add_option("--background", a->background, "photo to use behind the clutter");
  c->add_option("--width", a->opt.width, "frame width")->capture_default_str();
  c->add_option("--height", a->opt.height, "frame height")->capture_default_str();
  c->add_option("--target-size", a->opt.target_max_side, "resize the target to this longest side first (0: keep)")->capture_default_str();
  c->add_option("--min-scale", a->opt.min_scale, "smallest affine scale")->capture_default_str();
  c->add_option("--max-scale", a->opt.max_scale, "largest affine scale")->capture_default_str();
  c->add_option("--perspective", a->opt.perspective, "max relative depth change across the target")->capture_default_str();
  c->add_option("--blur", a->opt.max_blur, "max Gaussian blur sigma")->capture_default_str();
  c->add_option("--noise", a->opt.max_noise, "max noise sigma (grey levels)")->capture_default_str();
  c->add_flag("!--no-clutter", a->opt.clutter, "plain background");
  c->add_flag("!--no-lighting", a->opt.lighting, "no lighting change");
  c->add_flag("--gray", a->gray, "write grayscale views");
  c->callback([a, code] { *code = RunSynth(*a); });
}

}  // namespace mvkp::cli
