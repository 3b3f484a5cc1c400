// specula gc: reclaims the space of removed and replaced objects and of abandoned transactions.
#include <fmt/format.h>

#include "apps/commands.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

void run_gc(const std::string& path) {
  const auto r = store::collect_garbage(path);
  fmt::print("{}: reclaimed {} file(s), {:.1f} MB", path, r.files, double(r.bytes) / 1e6);
  if (r.in_use) fmt::print("; {} still open by readers (reclaimed once they close)", r.in_use);
  if (r.in_flight) fmt::print("; {} transaction(s) in progress left alone", r.in_flight);
  fmt::print("\n");
}

}  // namespace

void setup_gc(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto* cmd =
      app.add_subcommand("gc", "Reclaim the space of removed or replaced objects and of abandoned transactions");
  cmd->add_option("store", *path, "Store file")->required();
  cmd->callback([path] { run_gc(*path); });
}

}  // namespace specula::app
