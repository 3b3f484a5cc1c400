// specula upgrade: converts a format-1 (single-file) store in place into the current layout, as one transaction.
#include <fmt/format.h>

#include "apps/commands.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

void run_upgrade(const std::string& path) {
  store::upgrade(path);
  const auto s = store::Store::open(path);
  fmt::print("{}: upgraded to store format version {} ({} objects; data kept in {})\n", path, s.format_version(),
             s.index().entries.size(), s.data_dir().string());
}

}  // namespace

void setup_upgrade(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto* cmd =
      app.add_subcommand("upgrade", "Convert a format-1 store in place to the current format (no copy of the data)");
  cmd->add_option("store", *path, "Store file")->required();
  cmd->callback([path] { run_upgrade(*path); });
}

}  // namespace specula::app
