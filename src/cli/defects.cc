// `ssiu defects build`: a static defect map (hot and dead pixels) from dark or median frames.
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/error.h"
#include "detect/detect.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::vector<std::string> frames;
  std::string out;
  double sigma = DefectMapOptions{}.sigma;
};

void Run(const Opts& o) {
  std::vector<Frame> frames;
  for (const auto& f : o.frames) {
    frames.push_back(ReadFrame(f));
    if (frames.back().image.width != frames[0].image.width || frames.back().image.height != frames[0].image.height) {
      throw InputError(f, "size differs from " + o.frames[0]);
    }
  }
  std::vector<ImageView> views;
  for (const auto& f : frames) views.push_back(f.image.view());
  DefectMapOptions opt;
  opt.sigma = o.sigma;
  opt.Check();
  const DefectMap m = BuildDefectMap(views, opt);
  size_t hot = 0, dead = 0;
  for (uint8_t v : m.mask) {
    hot += v == 1;
    dead += v == 2;
  }
  SaveDefectMap(o.out, m);
  std::cout << o.out << ": " << hot << " hot, " << dead << " dead pixels from " << frames.size() << " frame(s)\n";
}

}  // namespace
}  // namespace ssiu::cli

SSIU_REGISTER_COMMAND(defects, [](CLI::App& root) {
  using namespace ssiu::cli;
  CLI::App* grp = GetOrAddSubcommand(root, "defects", "Static defect maps");
  CLI::App* cmd = grp->add_subcommand("build", "Build a defect map from dark or median frames");
  auto o = std::make_shared<Opts>();
  cmd->add_option("frames", o->frames, "Dark or median frames")->required();
  cmd->add_option("--out", o->out, "Output PNG (0 good, 255 hot, 128 dead)")->required();
  cmd->add_option("--sigma", o->sigma, "Outlier threshold in local noise sigmas");
  cmd->callback([o] { Run(*o); });
});
