// specula rm: removes objects from a store in one transaction (their space is reclaimed by gc or a later commit).
#include <fmt/format.h>

#include "apps/commands.h"
#include "apps/common.h"
#include "specula/store/store.h"

namespace specula::app {
namespace {

struct RmOptions {
  std::string store;
  std::vector<std::string> objects;
};

void run_rm(const RmOptions& o) {
  std::vector<std::pair<std::string, std::string>> targets;
  {
    const store::Store s = store::Store::open(o.store);
    for (const auto& spec : o.objects) targets.push_back(store::resolve_object(s, spec));
  }
  store::StoreWriter writer(o.store, {.command_line = command_line()});
  for (const auto& [kind, name] : targets) writer.remove(kind, name);
  writer.commit();
  for (const auto& [kind, name] : targets) fmt::print("removed {}/{} from {}\n", kind, name, o.store);
  const auto& r = writer.reclaimed();
  if (r.files) fmt::print("reclaimed {} file(s), {:.1f} MB\n", r.files, double(r.bytes) / 1e6);
}

}  // namespace

void setup_rm(CLI::App& app) {
  auto o = std::make_shared<RmOptions>();
  auto* cmd = app.add_subcommand(
      "rm", "Remove objects from a store (one transaction; space is reclaimed when no reader needs it)");
  cmd->add_option("store", o->store, "Store file")->required();
  cmd->add_option("objects", o->objects, "Objects: KIND/NAME (e.g. images/scene, bases/pca) or a name used by one kind")
      ->required();
  cmd->callback([o] { run_rm(*o); });
}

}  // namespace specula::app
