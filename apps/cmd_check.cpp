// specula check: verifies every object's data file against its recorded size and checksum, and the root's links.
#include <fmt/format.h>

#include "apps/commands.h"
#include "specula/core/error.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

void run_check(const std::string& path) {
  const auto problems = store::check(path);
  const auto s = store::Store::open(path);
  if (problems.empty()) {
    fmt::print("{}: {} object(s), generation {}: every data file matches its checksum\n", path,
               s.index().entries.size(), s.index().generation);
    return;
  }
  for (const auto& p : problems) fmt::print(stderr, "{}: {}\n", path, p.what);
  throw InputError(path + ": " + std::to_string(problems.size()) + " problem(s) found (listed above)");
}

}  // namespace

void setup_check(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto* cmd =
      app.add_subcommand("check", "Verify every object's data against its recorded checksum and the root's links");
  cmd->add_option("store", *path, "Store file")->required();
  cmd->callback([path] { run_check(*path); });
}

}  // namespace specula::app
