// `ssiu demo`: the main job on the built-in default: simulate a frame from the catalog, detect its
// stars and report against the truth.
#include "sim/demo.h"

#include <cstdio>
#include <memory>

#include "cli/command.h"
#include "core/attitude.h"
#include "core/catalog.h"

SSIU_REGISTER_COMMAND(demo, [](CLI::App& root) {
  CLI::App* cmd = root.add_subcommand("demo", "Simulate a frame from the catalog, detect and report the errors");
  auto seed = std::make_shared<uint64_t>(1);
  auto json = std::make_shared<std::string>();
  cmd->add_option("--seed", *seed, "Random attitude and noise seed");
  cmd->add_option("--json", *json, "Also write the report as JSON (- for stdout)");
  cmd->callback([seed, json] {
    const ssiu::DemoReport r = ssiu::RunDemo(ssiu::StarCatalog(ssiu::LoadXplanetBsc(ssiu::DefaultBscPath())), *seed);
    std::fputs(r.text.c_str(), stdout);
    if (!json->empty()) ssiu::WriteJsonFile(*json, r.json);
  });
});
